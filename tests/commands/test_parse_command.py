"""``realizer parse``: text, JSON and round-trip modes and their exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import realizer.bml_parser
from realizer.cli import main
from tests.conftest import EXAMPLES, conformance_files

SPEECH = EXAMPLES / "05_speech_sync.xml"


def test_parse_prints_behaviours_and_sync_references(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["parse", str(SPEECH)]) == 0
    out = capsys.readouterr().out
    assert "block speech" in out
    assert "head nod1 lexeme=NOD" in out
    assert "stroke = say1:s2" in out
    assert "syncs: start s1 s2 end" in out


def test_parse_json_gives_the_tree(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["parse", "--json", str(SPEECH)]) == 0
    (document,) = json.loads(capsys.readouterr().out)
    block = document["block"]
    assert block["id"] == "speech"
    speech, nod, brows = block["behaviours"]
    assert speech["text"][1] == {"sync": "s1"}
    assert nod["syncRefs"]["stroke"]["behaviour"] == "say1"
    assert nod["syncRefs"]["stroke"]["sync"] == "s2"
    assert brows["type"] == "faceLexeme"


def test_roundtrip_reports_ok_for_every_example_and_corpus_file(
    capsys: pytest.CaptureFixture[str],
) -> None:
    valid = [p for p in conformance_files() if "invalid" not in p.name
             and p.name != "testnod_unknownattributes.xml"]  # fmt: skip
    paths = sorted(EXAMPLES.glob("*.xml")) + valid
    assert main(["parse", "--roundtrip", *map(str, paths)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == [f"OK {path}" for path in paths]


def test_roundtrip_reports_diff_and_exits_1(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = realizer.bml_parser.serialise
    monkeypatch.setattr(
        realizer.bml_parser,
        "serialise",
        lambda block, **kw: real(block, **kw).replace("NOD", "SHAKE"),
    )
    assert main(["parse", "--roundtrip", str(SPEECH)]) == 1
    out = capsys.readouterr().out
    assert out.startswith(f"DIFF {SPEECH}: at character")
    assert "NOD" in out and "SHAKE" in out


def test_invalid_input_exits_2_with_path_line_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text(
        '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="b">\n'
        '  <head id="n" lexeme="NOD" start="x:"/>\n</bml>\n'
    )
    assert main(["parse", str(bad), str(SPEECH)]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(f"{bad}:2:29: error: sync reference 'x:' ends with a colon")
    assert "block speech" in captured.out  # the good file is still reported


def test_missing_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["parse", str(tmp_path / "nope.xml")]) == 2
    assert "nope.xml: error: no such file" in capsys.readouterr().err


def test_the_installed_command_runs() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "parse", "--roundtrip", str(SPEECH)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"OK {SPEECH}"
