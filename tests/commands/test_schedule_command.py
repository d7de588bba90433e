"""``realizer schedule``: the table, the JSON layout, composition across files, exit codes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from realizer.bml_parser import parse_bml
from realizer.cli import main
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import schedule_block
from tests.conftest import EXAMPLES

BML = 'xmlns="http://www.bml-initiative.org/bml/bml-1.0"'
CONSTRAINTS = EXAMPLES / "08_constraints.xml"
SMILE = EXAMPLES / "01_smile.xml"
APPEND = EXAMPLES / "10_append.xml"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def schedule_json(
    capsys: pytest.CaptureFixture[str], *paths: Path
) -> tuple[int, dict[str, Any], str]:
    status = main(["schedule", "--json", *map(str, paths)])
    captured = capsys.readouterr()
    return status, json.loads(captured.out), captured.err


def test_json_has_exactly_the_documented_keys(capsys: pytest.CaptureFixture[str]) -> None:
    status, document, _ = schedule_json(capsys, CONSTRAINTS)
    assert status == 0
    assert set(document) == {"blocks", "warnings"}
    (block,) = document["blocks"]
    assert set(block) == {"id", "start", "end", "behaviours"}
    assert block["id"] == "constraints"
    for behaviour in block["behaviours"]:
        assert set(behaviour) == {"id", "type", "syncs"}
        assert all(isinstance(t, float) for t in behaviour["syncs"].values())
    assert [b["id"] for b in block["behaviours"]] == ["beat1", "nod1", "smile1", "brows1"]
    assert block["behaviours"][0]["type"] == "gesture"


def test_json_times_match_schedule_block(capsys: pytest.CaptureFixture[str]) -> None:
    expected = schedule_block(
        parse_bml(CONSTRAINTS.read_bytes()).block, registry=EngineRegistry.standard(), start=0.0
    )
    _, document, _ = schedule_json(capsys, CONSTRAINTS)
    (block,) = document["blocks"]
    assert block["start"] == pytest.approx(expected.start)
    assert block["end"] == pytest.approx(expected.end)
    for scheduled, listed in zip(expected.behaviours, block["behaviours"], strict=True):
        assert listed["id"] == scheduled.id
        assert list(listed["syncs"]) == list(scheduled.times)
        for name, time in scheduled.times.items():
            assert listed["syncs"][name] == pytest.approx(time, abs=1e-8)
    # The constraints the document states hold in what is printed.
    syncs = {b["id"]: b["syncs"] for b in block["behaviours"]}
    assert syncs["beat1"]["start"] == pytest.approx(0.5)
    assert syncs["beat1"]["stroke"] == pytest.approx(syncs["nod1"]["stroke"])
    assert syncs["smile1"]["start"] >= syncs["nod1"]["end"] - 1e-9
    assert syncs["brows1"]["attackPeak"] <= syncs["beat1"]["stroke"] + 1e-9


def test_an_append_block_in_a_later_file_follows_the_earlier_block(
    capsys: pytest.CaptureFixture[str],
) -> None:
    status, document, _ = schedule_json(capsys, SMILE, APPEND)
    assert status == 0
    smile, append = document["blocks"]
    assert append["start"] == pytest.approx(smile["end"])
    (frown,) = append["behaviours"]
    # start="0" is relative to the appended block's own start.
    assert frown["syncs"]["start"] == pytest.approx(smile["end"])
    assert frown["syncs"]["end"] == pytest.approx(smile["end"] + 1.5)


def test_a_later_file_may_refer_to_an_earlier_block(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    later = write(
        tmp_path,
        "later.xml",
        f'<bml {BML} id="later"><head id="nod2" lexeme="NOD" start="smile:smile1:relax"/></bml>',
    )
    status, document, _ = schedule_json(capsys, SMILE, later)
    assert status == 0
    smile, nod = document["blocks"]
    relax = smile["behaviours"][0]["syncs"]["relax"]
    assert nod["behaviours"][0]["syncs"]["start"] == pytest.approx(relax)


def test_text_output_is_a_table_per_block(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schedule", str(SMILE), str(CONSTRAINTS)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{SMILE}: block smile  0.000 s to 2.500 s"
    assert lines[1].split() == ["behaviour", "type", "start", "attackPeak", "relax", "end"]
    assert lines[2].split() == ["smile1", "faceLexeme", "0.000", "0.400", "2.000", "2.500"]
    header = next(line for line in lines if line.startswith("  behaviour") and "stroke" in line)
    beat = next(line for line in lines if line.split()[0] == "beat1")
    # A gesture has no attackPeak: its cell is a dash under that column.
    column = header.index("attackPeak") + len("attackPeak") - 1
    assert beat[column] == "-"


def test_warnings_go_to_stderr_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(
        tmp_path,
        "ghost.xml",
        f'<bml {BML} id="warned">'
        '<faceLexeme id="a" lexeme="RAISE_BROWS" start="1" end="ghost:end"/></bml>',
    )
    status, document, err = schedule_json(capsys, path)
    assert status == 0
    (note,) = document["warnings"]
    assert set(note) == {"type", "id", "message"}
    assert note["type"] == "NO_SUCH_TARGET"
    assert note["id"] == "warned:a"
    assert f"{path}: warning NO_SUCH_TARGET warned:a: " in err
    # The behaviour still runs, without the broken tie.
    assert document["blocks"][0]["behaviours"][0]["syncs"]["start"] == pytest.approx(1.0)


def test_a_block_that_cannot_be_scheduled_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(
        tmp_path,
        "impossible.xml",
        f'<bml {BML} id="impossible"><required>'
        '<faceLexeme id="a" lexeme="RAISE_BROWS" start="0" end="2"/>'
        '<faceLexeme id="b" lexeme="WIDEN_EYES" start="a:end" end="a:start"/>'
        "</required></bml>",
    )
    status, document, err = schedule_json(capsys, SMILE, path)
    assert status == 1
    assert [b["id"] for b in document["blocks"]] == ["smile"]
    assert [w["type"] for w in document["warnings"]] == ["IMPOSSIBLE_TO_SCHEDULE"]
    assert "IMPOSSIBLE_TO_SCHEDULE impossible" in err


def test_a_document_that_cannot_be_parsed_exits_2_with_its_position(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "broken.xml", f'<bml {BML} id="b">\n  <head id="h" lexeme="NOD"\n</bml>')
    status = main(["schedule", str(SMILE), str(path)])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith(f"{path}:3:")
    assert ": error: " in err


def test_a_missing_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schedule", str(tmp_path / "nowhere.xml")]) == 2
    assert "nowhere.xml: error: no such file" in capsys.readouterr().err


def test_help_says_how_times_are_counted(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["schedule", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "global seconds" in text
    assert "APPEND" in text


def test_a_block_id_already_running_is_refused_and_exits_1(
    capsys: pytest.CaptureFixture[str],
) -> None:
    status, document, err = schedule_json(capsys, SMILE, SMILE)
    assert "PARSING_FAILURE smile" in err
    assert status == 1
    assert [b["id"] for b in document["blocks"]] == ["smile"]
    (note,) = document["warnings"]
    assert note["type"] == "PARSING_FAILURE"
    assert "already running" in note["message"]


def test_a_replace_block_interrupts_earlier_files_and_append_follows_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    paths = [SMILE, EXAMPLES / "11_replace.xml", APPEND]
    assert main(["schedule", *map(str, paths)]) == 0
    out = capsys.readouterr().out
    assert f"{SMILE}: block smile  0.000 s to 2.500 s  (interrupted" in out
    status, document, _ = schedule_json(capsys, *paths)
    assert status == 0
    smile, replace, append = document["blocks"]
    # APPEND waits only for blocks still pending or running: not the smile.
    assert append["start"] == pytest.approx(replace["end"])
    assert append["start"] < smile["end"]


def test_every_parsable_corpus_document_schedules(
    conformance_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    unparsable = {"testinvalidxml.xml", "testinvalidxml2.xml", "testnod_unknownattributes.xml"}
    for path in sorted(conformance_dir.glob("*.xml")):
        status = main(["schedule", "--json", str(path)])
        captured = capsys.readouterr()
        if path.name in unparsable:
            assert status == 2, path.name
            assert captured.err.startswith(f"{path}:"), path.name
            continue
        assert status == 0, (path.name, captured.err)
        (block,) = json.loads(captured.out)["blocks"]
        for behaviour in block["behaviours"]:
            times = list(behaviour["syncs"].values())
            # Sync points in canonical order never run backwards.
            assert times == sorted(times), (path.name, behaviour["id"])
