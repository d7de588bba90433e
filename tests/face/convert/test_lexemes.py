"""BML 1.0 faceLexeme and FACS behaviours -> FAPs."""

from __future__ import annotations

import pytest

from realizer.face.convert.errors import ConversionError
from realizer.face.convert.facs import facs_to_faps
from realizer.face.convert.lexemes import (
    facs_behaviour_faps,
    format_lexemes,
    lexeme_faps,
    load_default_lexemes,
    parse_lexemes,
)

#: The faceLexeme lexemes of the BML 1.0 standard.
BML_LEXEMES = (
    "OBLIQUE_BROWS", "RAISE_BROWS", "RAISE_LEFT_BROW", "RAISE_RIGHT_BROW", "LOWER_BROWS",
    "LOWER_LEFT_BROW", "LOWER_RIGHT_BROW", "LOWER_MOUTH_CORNERS", "LOWER_LEFT_MOUTH_CORNER",
    "LOWER_RIGHT_MOUTH_CORNER", "RAISE_MOUTH_CORNERS", "RAISE_RIGHT_MOUTH_CORNER",
    "RAISE_LEFT_MOUTH_CORNER", "OPEN_MOUTH", "OPEN_LIPS", "WIDEN_EYES", "CLOSE_EYES",
)  # fmt: skip

LEFT_FAPS = {19, 21, 31, 33, 35, 37, 53, 59, 12, 6}
RIGHT_FAPS = {20, 22, 32, 34, 36, 38, 54, 60, 13, 7}


def test_the_table_holds_exactly_the_standard_lexemes() -> None:
    assert set(load_default_lexemes().names()) == set(BML_LEXEMES)


@pytest.mark.parametrize("lexeme", BML_LEXEMES)
def test_every_standard_lexeme_moves_the_face(lexeme: str) -> None:
    faps = lexeme_faps(lexeme, 1.0).as_dict()
    assert faps and any(value != 0 for value in faps.values())


@pytest.mark.parametrize("lexeme", [x for x in BML_LEXEMES if "_LEFT_" in x])
def test_left_lexemes_move_only_left_faps(lexeme: str) -> None:
    faps = set(lexeme_faps(lexeme, 1.0).as_dict())
    assert faps & LEFT_FAPS and not faps & RIGHT_FAPS


@pytest.mark.parametrize("lexeme", [x for x in BML_LEXEMES if "_RIGHT_" in x])
def test_right_lexemes_move_only_right_faps(lexeme: str) -> None:
    faps = set(lexeme_faps(lexeme, 1.0).as_dict())
    assert faps & RIGHT_FAPS and not faps & LEFT_FAPS


def test_lexemes_go_through_their_action_units() -> None:
    assert lexeme_faps("RAISE_BROWS", 1.0) == facs_to_faps(["1", "2"])
    assert lexeme_faps("LOWER_LEFT_MOUTH_CORNER", 1.0) == facs_to_faps(["15L"])
    assert lexeme_faps("CLOSE_EYES", 1.0) == facs_to_faps(["43"])


def test_directions_follow_the_lexeme_names() -> None:
    assert lexeme_faps("RAISE_BROWS", 1.0).as_dict()[31] > 0
    assert lexeme_faps("LOWER_BROWS", 1.0).as_dict()[31] < 0
    assert lexeme_faps("RAISE_MOUTH_CORNERS", 1.0).as_dict()[59] > 0
    assert lexeme_faps("LOWER_MOUTH_CORNERS", 1.0).as_dict()[59] < 0
    assert lexeme_faps("WIDEN_EYES", 1.0).as_dict()[19] < 0
    assert lexeme_faps("CLOSE_EYES", 1.0).as_dict()[19] > 0
    assert lexeme_faps("OPEN_MOUTH", 1.0).as_dict()[3] > 0


def test_amount_scales_the_movement() -> None:
    full = lexeme_faps("RAISE_BROWS", 1.0).as_dict()
    half = lexeme_faps("RAISE_BROWS", 0.5).as_dict()
    assert half == pytest.approx({fap: value / 2 for fap, value in full.items()})
    assert lexeme_faps("RAISE_BROWS") == lexeme_faps("RAISE_BROWS", 0.5)  # BML default


def test_lexeme_names_are_case_insensitive_and_unknown_ones_refused() -> None:
    assert lexeme_faps("raise_brows", 1.0) == lexeme_faps("RAISE_BROWS", 1.0)
    with pytest.raises(ConversionError, match="SMIRK"):
        lexeme_faps("SMIRK")
    with pytest.raises(ConversionError):
        lexeme_faps("RAISE_BROWS", 1.5)


def test_face_facs_behaviours_use_the_same_path_with_sides() -> None:
    assert facs_behaviour_faps(12, "LEFT", 0.8) == facs_to_faps(["12L:0.8"])
    assert facs_behaviour_faps(12, "RIGHT", 0.8) == facs_to_faps(["12R:0.8"])
    assert facs_behaviour_faps(12, "BOTH", 0.8) == facs_to_faps(["12:0.8"])
    assert facs_behaviour_faps(12, None, 0.8) == facs_to_faps(["12:0.8"])
    with pytest.raises(ConversionError):
        facs_behaviour_faps(12, "UP", 0.8)


def test_the_lexeme_file_round_trips() -> None:
    table = load_default_lexemes()
    assert parse_lexemes(format_lexemes(table)) == table
