"""FACS -> FAP conversion (seed 000 chapter 5, figure 5.2)."""

from __future__ import annotations

import pytest

from realizer.face.convert.errors import ConversionError, DataFileError
from realizer.face.convert.facs import (
    AuActivation,
    AuKey,
    facs_to_faps,
    format_mapping,
    load_default_mapping,
    parse_mapping,
)

FIGURE_5_2 = """\
23\tL
53\t0.0\t1.0\t0\t-300
23\tR
54\t0.0\t1.0\t0\t-300
24
16\t0.0\t1.0\t0\t1000
17\t0.0\t1.0\t0\t500
25
3\t0.0\t1.0\t0\t900
4\t0.5\t1.0\t0\t-100
5\t0.0\t1.0\t0\t-1000
10\t0.2\t1.0\t0\t-1000
11\t0.2\t1.0\t0\t-1000
"""

#: Every AU of seed 000 Appendix A, Table A.1.
APPENDIX_A = (
    1, 2, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 20, 22, 23, 24, 25, 26, 27, 28,
    41, 42, 43, 44, 45, 46, 51, 52, 53, 54, 55, 56, 57, 58, 61, 62, 63, 64,
)  # fmt: skip


def test_the_seed_example_au23_at_half_gives_fap53_minus_150() -> None:
    mapping = parse_mapping(FIGURE_5_2)
    assert facs_to_faps(["23L:0.5"], mapping).as_dict() == {53: -150.0}


def test_a_fap_line_with_a_late_au_start_stays_off_below_it() -> None:
    mapping = parse_mapping(FIGURE_5_2)
    low = facs_to_faps(["25:0.4"], mapping).as_dict()
    high = facs_to_faps(["25:0.75"], mapping).as_dict()
    assert low[4] == 0.0 and low[3] == pytest.approx(360.0)
    assert high[4] == pytest.approx(-50.0)
    assert low[10] == pytest.approx(-250.0)  # (0.4 - 0.2) / 0.8 of -1000


def test_figure_5_2_parses_with_comments_and_blank_lines() -> None:
    text = "# a comment\n\n" + FIGURE_5_2.replace("24\n", "24   # lip pressor\n")
    mapping = parse_mapping(text)
    assert [str(key) for key, _ in mapping.entries] == ["23L", "23R", "24", "25"]
    assert mapping.description(AuKey(24)) == "lip pressor"


def test_left_and_right_aus_move_only_their_side() -> None:
    left = facs_to_faps(["12L"]).as_dict()
    right = facs_to_faps(["12R"]).as_dict()
    both = facs_to_faps(["12"]).as_dict()
    assert 59 in left and 60 not in left
    assert 60 in right and 59 not in right
    assert both == {**left, **right}


def test_a_one_sided_request_still_moves_the_midline_faps() -> None:
    # AU 27 has unsided jaw lines and sided corner lines
    left = facs_to_faps(["27L"]).as_dict()
    assert left[3] == 1000.0 and 6 in left and 7 not in left


def test_intensity_scales_linearly_and_aus_on_one_fap_add_up() -> None:
    assert facs_to_faps(["1:0.5"]).as_dict()[31] == pytest.approx(150.0)
    combined = facs_to_faps(["1", "2"]).as_dict()
    assert combined[33] == pytest.approx(100.0 + 120.0)  # FAP 33 from AU 1 and AU 2


def test_au1_includes_fap33_as_seed_000_added_it() -> None:
    assert 33 in facs_to_faps(["1L"]).as_dict()


@pytest.mark.parametrize("au", APPENDIX_A)
def test_every_appendix_a_au_maps_to_some_fap(au: int) -> None:
    assert facs_to_faps([str(au)]).as_dict()


def test_head_and_eye_aus_drive_the_head_and_eyeball_faps() -> None:
    assert facs_to_faps(["51"]).as_dict() == {49: 60000.0}
    assert facs_to_faps(["52"]).as_dict()[49] < 0
    assert set(facs_to_faps(["55"]).as_dict()) == {50}
    assert set(facs_to_faps(["61"]).as_dict()) == {23, 24}
    assert facs_to_faps(["63"]).as_dict()[25] < 0 < facs_to_faps(["64"]).as_dict()[25]


def test_the_default_mapping_round_trips_through_its_file_format() -> None:
    mapping = load_default_mapping()
    again = parse_mapping(format_mapping(mapping))
    assert again == mapping
    assert format_mapping(again) == format_mapping(mapping)


def test_a_mapping_with_odd_bounds_round_trips_exactly() -> None:
    mapping = parse_mapping("7 R\n21 0.25 0.9 -12.5 250\n")
    assert parse_mapping(format_mapping(mapping)) == mapping


def test_au_activations_parse_with_side_and_intensity() -> None:
    assert AuActivation.parse("12L:0.8") == AuActivation(12, "L", 0.8)
    assert AuActivation.parse("AU4") == AuActivation(4, None, 1.0)
    assert AuActivation.parse("6r") == AuActivation(6, "R", 1.0)


@pytest.mark.parametrize("bad", ["12X", "L12", "12L:2", "12:-0.1", "", "12:abc"])
def test_bad_au_activations_are_refused(bad: str) -> None:
    with pytest.raises(ConversionError):
        AuActivation.parse(bad)


def test_an_au_that_is_not_mapped_is_an_error() -> None:
    with pytest.raises(ConversionError, match="AU 99"):
        facs_to_faps(["99"])


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("53 0.0 1.0 0 -300\n", 1),  # FAP line before any AU
        ("23 L\n53 0.0 1.0 0\n", 2),  # four fields
        ("23 X\n", 1),  # bad side
        ("23\n99 0.0 1.0 0 1\n", 2),  # not a FAP
        ("23\n3 1.0 0.5 0 1\n", 2),  # empty AU range
    ],
)
def test_malformed_mapping_files_report_the_line(text: str, line: int) -> None:
    with pytest.raises(DataFileError) as caught:
        parse_mapping(text, source="m.map")
    assert caught.value.line == line and "m.map" in str(caught.value)
