"""Errors read the same across commands: a file that is not BML is reported
as ``path:line:col: error: message`` and fails the command, whichever
command reads it (``faps`` and ``plot-faps`` once wrote an empty recording
and exited 0; ``render`` said only that the block was refused)."""

from __future__ import annotations

from pathlib import Path

import pytest

from realizer.cli import main

BROKEN = '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="b">\n<face id="f" \n</bml>\n'


@pytest.mark.parametrize(
    ("command", "output", "status"),
    [
        ("parse", None, 2),
        ("faps", "out.fap", 2),
        ("plot-faps", "out.png", 2),
        ("render", "out.mp4", 1),
    ],
)
def test_a_file_that_is_not_bml_reads_as_a_parse_error_and_fails(
    command: str,
    output: str | None,
    status: int,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    if command == "plot-faps":
        pytest.importorskip("matplotlib", reason="realizer plot-faps needs the plots extra")
    if command == "render":
        pytest.importorskip("OpenGL", reason="realizer render needs the render extra")
    source = tmp_path / "broken.xml"
    source.write_text(BROKEN, encoding="utf-8")
    args = [command, str(source)] + (["-o", str(tmp_path / output)] if output else [])
    assert main(args) == status
    err = capsys.readouterr().err
    assert f"{source}:3:1: error: " in err, err
    if output:
        assert not (tmp_path / output).exists()  # nothing written from a broken file


@pytest.mark.parametrize("value", ["abc", "nan", "inf"])
def test_a_fap_value_that_is_not_a_finite_number_is_named(
    value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("OpenGL", reason="realizer face needs the render extra")
    assert main(["face", "--faps", f"3={value}", "-o", str(tmp_path / "f.png")]) != 0
    assert f"FAP 3: '{value}' is not a finite number" in capsys.readouterr().err
    assert not (tmp_path / "f.png").exists()
