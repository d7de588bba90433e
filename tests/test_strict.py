"""Strict mode for planners' CI: every warning is an error.

``realizer parse --strict`` and ``realizer schedule --strict`` exit 2 on any
warning (an unknown reference included), and a submitter connection opened
as ``/bml?strict=true`` has every block with a warning refused, while a
plain connection to the same server still runs it.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path

from websockets.asyncio.client import connect

from realizer.bml_parser import BML_NS
from realizer.session import BlockState, Session
from tests.conftest import ROOT
from tests.service.harness import running_service
from tests.service.test_end_to_end import read_json, real_assets, real_sessions, until_block_final

UNKNOWN_REF = (
    f'<bml xmlns="{BML_NS}" id="b1"><head id="nod1" lexeme="NOD" start="nobody:end"/></bml>'
)
CLEAN = f'<bml xmlns="{BML_NS}" id="b2"><head id="nod1" lexeme="NOD" start="0"/></bml>'


def realizer(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "realizer", *map(str, args)],
        capture_output=True, text=True, cwd=ROOT, timeout=120, check=False,
    )  # fmt: skip


def test_parse_strict_turns_an_unknown_reference_into_an_error(tmp_path: Path) -> None:
    bad, good = tmp_path / "bad.xml", tmp_path / "good.xml"
    bad.write_text(UNKNOWN_REF)
    good.write_text(CLEAN)
    assert realizer("parse", bad).returncode == 0  # only a warning without --strict
    done = realizer("parse", "--strict", bad)
    assert done.returncode == 2
    assert "error: NO_SUCH_TARGET" in done.stderr and "'nobody'" in done.stderr
    assert realizer("parse", "--strict", good).returncode == 0


def test_parse_strict_turns_a_parser_warning_into_an_error(tmp_path: Path) -> None:
    path = tmp_path / "custom.xml"
    path.write_text(f'<bml xmlns="{BML_NS}" id="b1"><head id="h" lexeme="NOD" colour="red"/></bml>')
    done = realizer("parse", "--strict", path)
    assert done.returncode == 2 and "error: CUSTOM_ATTRIBUTE_NOT_SUPPORTED" in done.stderr


def test_schedule_strict_refuses_the_block_and_exits_2(tmp_path: Path) -> None:
    bad, good = tmp_path / "bad.xml", tmp_path / "good.xml"
    bad.write_text(UNKNOWN_REF)
    good.write_text(CLEAN)
    plain = realizer("schedule", bad)
    assert plain.returncode == 0 and "warning NO_SUCH_TARGET" in plain.stderr
    strict = realizer("schedule", "--strict", bad, good)
    assert strict.returncode == 2
    assert "error NO_SUCH_TARGET" in strict.stderr
    assert "bad.xml: not scheduled" in strict.stdout and "block b2" in strict.stdout
    assert realizer("schedule", "--strict", good).returncode == 0


def test_a_strict_session_runs_nothing_of_a_block_with_a_warning() -> None:
    session = Session()
    running = CLEAN.replace('id="b2"', 'id="b0"').replace('start="0"', 'start="0" end="5"')
    session.receive_bml(running, now=0.0)
    replace = UNKNOWN_REF.replace('id="b1"', 'id="b1" composition="REPLACE"')
    assert session.receive_bml(replace, now=0.1, strict=True) is None
    assert session.state("b1") is BlockState.FAILED
    assert session.state("b0") is BlockState.IN_EXECUTION  # a refused REPLACE interrupts nothing
    messages = [f for f in session.take_feedback() if f.block_id == "b1"]
    assert [f.kind for f in messages] == ["warning", "warning"]
    assert "strict mode" in messages[-1].xml


def test_a_strict_connection_has_blocks_with_warnings_refused() -> None:
    async def scenario() -> tuple[list[str], list[str]]:
        async with running_service(real_sessions(), real_assets()) as service:
            url = f"ws://127.0.0.1:{service.port}/bml?format=json"
            async with connect(url + "&strict=true") as strict, connect(url) as plain:
                await read_json(strict), await read_json(plain)
                await strict.send(UNKNOWN_REF)
                refused = await until_block_final(strict, "b1")
                await plain.send(UNKNOWN_REF.replace('id="b1"', 'id="b3"'))
                accepted = await until_block_final(plain, "b3")
        return (
            [m["state"] for m in refused if m["type"] == "block" and m["block"] == "b1"],
            [m["state"] for m in accepted if m["type"] == "block" and m["block"] == "b3"],
        )

    refused, accepted = asyncio.run(scenario())
    assert refused == ["rejected"]
    assert accepted == ["accepted", "done"]
