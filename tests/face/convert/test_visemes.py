"""FAP 1 visemes and FAP 2 expressions (seed 002 Tables 3 and 4)."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.convert.errors import ConversionError, DataFileError
from realizer.face.convert.visemes import (
    expression_faps,
    format_shapes,
    load_default_expressions,
    load_default_visemes,
    parse_shapes,
    viseme_faps,
)


def test_there_are_the_15_viseme_numbers_and_6_expressions_of_mpeg4() -> None:
    assert load_default_visemes().numbers() == tuple(range(15))
    names = [shape.label[0] for shape in load_default_expressions().shapes]
    assert names == ["joy", "sadness", "anger", "fear", "disgust", "surprise"]


def test_visemes_carry_their_phonemes() -> None:
    assert load_default_visemes().shape(1).label[0] == "p,b,m"
    assert load_default_visemes().shape(10).label[0] == "A:"


def test_viseme_zero_is_the_neutral_mouth_and_sets_every_mouth_fap() -> None:
    neutral = viseme_faps(0)
    assert neutral.mask.sum() == len(load_default_visemes().faps())
    assert not neutral.values.any()


def test_a_viseme_frame_blends_two_visemes_by_blend_over_63() -> None:
    a, b = viseme_faps(10), viseme_faps(1)
    half = viseme_faps(10, 1, 31.5)
    assert np.allclose(half.values, (a.values + b.values) / 2)
    assert viseme_faps(10, 1, 63) == a and viseme_faps(10, 1, 0) == b


def test_open_vowels_open_the_jaw_more_than_bilabials() -> None:
    assert viseme_faps(10).as_dict()[3] > viseme_faps(1).as_dict()[3]


def test_an_expression_frame_adds_two_expressions_by_intensity() -> None:
    joy = expression_faps(1, 63)
    surprise = expression_faps(6, 63)
    mixed = expression_faps(1, 42, 6, 21)
    assert np.allclose(mixed.values, joy.values * 42 / 63 + surprise.values * 21 / 63)
    assert np.array_equal(mixed.mask, joy.mask | surprise.mask)


def test_expressions_follow_their_textual_descriptions() -> None:
    assert expression_faps(1, 63).as_dict()[59] > 0  # joy: corners pulled back and up
    assert expression_faps(2, 63).as_dict()[31] > 0  # sadness: inner brows bent up
    assert expression_faps(3, 63).as_dict()[31] < 0  # anger: inner brows down
    assert expression_faps(6, 63).as_dict()[3] > 0  # surprise: jaw opened


@pytest.mark.parametrize("level", [-1, 64])
def test_intensities_and_blends_outside_0_63_are_refused(level: float) -> None:
    with pytest.raises(ConversionError):
        expression_faps(1, level)
    with pytest.raises(ConversionError):
        viseme_faps(1, 2, level)
    with pytest.raises(ConversionError):
        viseme_faps(15)


def test_both_shape_files_round_trip() -> None:
    for table in (load_default_visemes(), load_default_expressions()):
        assert parse_shapes(format_shapes(table), table.kind) == table


def test_a_malformed_shape_file_reports_its_line() -> None:
    with pytest.raises(DataFileError) as caught:
        parse_shapes("Viseme 1 pbm\nF3 40, F4\n", "Viseme")
    assert caught.value.line == 2
