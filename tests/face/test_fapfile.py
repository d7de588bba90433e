"""Reading and writing .fap files (Xface / Greta text format)."""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.convert.errors import DataFileError
from realizer.face.fapfile import (
    FapFile,
    fap_file_from_frames,
    format_fap_file,
    parse_fap_file,
    read_fap_file,
    write_fap_file,
)


def stream() -> FapFile:
    values = np.zeros((3, 68))
    mask = np.zeros((3, 68), dtype=bool)
    values[:, 2] = [0, 400, 800]
    mask[:, 2] = True
    values[1:, 47] = [-1500, 3000]
    mask[1:, 47] = True
    return FapFile("my face", 25, values, mask)


def test_a_fap_file_has_the_header_then_mask_and_values_lines() -> None:
    text = format_fap_file(stream())
    lines = text.splitlines()
    assert lines[0] == "2.1 my face 25 3"
    assert len(lines[1].split()) == 68 and lines[1].split()[2] == "1"
    assert lines[2] == "0 0"
    assert lines[4] == "1 400 -1500"


def test_a_fap_file_round_trips(tmp_path: object) -> None:
    original = stream()
    path = tmp_path / "out.fap"  # type: ignore[operator]
    write_fap_file(path, original)
    again = read_fap_file(path)
    assert again.name == "my face" and again.fps == 25 and again.frames == 3
    assert np.array_equal(again.mask, original.mask)
    assert np.array_equal(again.values, original.values)
    assert format_fap_file(again) == format_fap_file(original)


def test_69_mask_columns_are_read_as_fap_0_then_faps_1_to_68() -> None:
    mask = ["0"] * 69
    mask[3] = "1"  # FAP 3 when column 0 is FAP 0
    text = "2.1 greta 25 1\n" + " ".join(mask) + "\n0 321\n"
    fap = parse_fap_file(text)
    assert fap.mask[0].tolist().index(True) == 2 and fap.values[0, 2] == 321


def test_a_truncated_file_keeps_the_frames_it_has() -> None:
    text = format_fap_file(stream())
    cut = "\n".join(text.splitlines()[:6])  # header, two frames, the third frame's mask
    assert parse_fap_file(cut).frames == 2


def test_values_are_written_as_integers() -> None:
    fap = fap_file_from_frames("x", 30, [(np.full(68, 12.6), np.ones(68, dtype=bool))])
    line = format_fap_file(fap).splitlines()[2].split()
    assert line[1] == "13" and len(line) == 67  # frame number + FAPs 3..68


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("2.1 x 25\n", 1),
        ("2.1 x 25 1\n" + "0 " * 67 + "\n0\n", 2),
        ("2.1 x 25 1\n" + "1 " + "0 " * 67 + "\n0\n", 3),
        ("2.1 x 25 1\n" + "1 " + "0 " * 67 + "\n0 abc\n", 3),
    ],
)
def test_malformed_fap_files_report_the_line(text: str, line: int) -> None:
    with pytest.raises(DataFileError) as caught:
        parse_fap_file(text)
    assert caught.value.line == line


def test_fap_files_convert_to_and_from_fap_frames() -> None:
    original = stream()
    frames = original.fap_frames()
    assert [f.time for f in frames] == [0.0, 0.04, 0.08] and frames[2].number == 2
    again = FapFile.from_fap_frames("my face", 25, frames)
    assert np.array_equal(again.values, original.values)
    assert np.array_equal(again.mask, original.mask)
