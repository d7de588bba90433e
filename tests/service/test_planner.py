"""Planner processes (realizer.service.planner): the same answers as planning
in the caller's thread, a time budget per message, and children replaced
when they are killed or over budget.

Real processes (forked by multiprocessing's fork server), the real parser,
sessions and engines, no network.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from typing import Any

import pytest

from realizer.bml_parser import BML_NS
from realizer.service.assets import session_factory
from realizer.service.planner import PlannerPool, PlanningRecipe
from realizer.service.stage import BlockEvent, Stage, WireFeedback
from tests.service.test_cadence import big_block


@pytest.fixture(scope="module")
def pool() -> Iterator[PlannerPool]:
    made = PlannerPool(1, PlanningRecipe(), 5000)
    try:
        yield made
    finally:
        made.close()


def bml(block_id: str, body: str, extra: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" id="{block_id}"{extra}>{body}</bml>'


#: (time, kind, document): a session's life, with what a process must carry
#: over: cross-block references, compositions, BMLA, interrupts, warnings,
#: refusals, a gaze at a scene target, strict mode's refusal.
SCRIPT: list[tuple[float, str, str]] = [
    (0.0, "bml", bml("b1", '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="1"/>'
                           '<head id="h" lexeme="NOD" start="f:end" repetition="2"/>')),
    (0.1, "bml", bml("b2", '<faceLexeme id="g" lexeme="RAISE_MOUTH_CORNERS" '
                           'start="b1:h:stroke:2" end="b1:h:end+0.5"/>')),
    (0.2, "bml", bml("b3", '<head id="n" lexeme="SHAKE" start="0"/>', ' composition="APPEND"')),
    (0.3, "bml", bml("b4", '<gaze id="z" target="camera" start="0" end="1"/>'
                           '<gaze id="y" target="nowhere" start="0" end="1"/>'
                           '<faceLexeme id="u" lexeme="RAISE_BROWS" start="0" end="1" zzz="1"/>')),
    (0.4, "interrupt", "b3"),
    (0.5, "bml", bml("b5", '<faceLexeme id="x" lexeme="RAISE_BROWS" start="b9:a:end"/>')),
    (0.6, "bml", bml("b6", '<faceFacs id="a" au="12" start="0" end="2"/>',
                     ' composition="REPLACE"')),
    (0.7, "bml", bml("b6", '<faceFacs id="a" au="12" start="0" end="2"/>')),  # a duplicate
    (0.8, "bml", "<bml>not BML"),
    (0.9, "bml", bml("b7", '<faceLexeme id="p" lexeme="RAISE_BROWS" start="0" end="1"/>',
                     ' xmlns:bmla="http://www.asap-project.org/bmla" bmla:preplan="true"')),
    (1.0, "bml", bml("b8", '<faceLexeme id="q" lexeme="RAISE_BROWS" start="0" end="0.2"/>',
                     ' xmlns:bmla="http://www.asap-project.org/bmla" bmla:onStart="b7"')),
    (1.1, "strict", bml("b9", '<faceLexeme id="r" lexeme="RAISE_BROWS" start="0" end="1" '
                              'zz="2"/>')),
    (1.2, "bml", big_block()),
]  # fmt: skip


def run_script(stage: Stage) -> list[tuple[str, ...]]:
    """Every message the stage returns over the script and ticks after it."""
    seen: list[tuple[str, ...]] = []

    def note(messages: Any) -> None:
        for message in messages:
            if isinstance(message, WireFeedback):
                seen.append((message.character, message.kind, message.block_id, message.xml))
            else:
                assert isinstance(message, BlockEvent)
                seen.append((message.character, message.state, message.block_id))

    for now, kind, text in SCRIPT:
        if kind == "interrupt":
            note(stage.interrupt("default", text, now))
        else:
            note(stage.submit_bml(text, now, strict=kind == "strict").messages)
        for character_tick in stage.tick(now + 0.05):
            note(character_tick.messages)
    for step in range(40):
        for character_tick in stage.tick(1.3 + step * 0.25):
            note(character_tick.messages)
    return seen


def test_a_planner_process_answers_exactly_as_planning_in_the_thread(pool: PlannerPool) -> None:
    threads = Stage(session_factory(None))
    processes = Stage(session_factory(None), planner=pool)
    for stage in (threads, processes):
        stage.place_target("camera", (0.0, 0.2, 1.5), 0.0)
    in_threads = run_script(threads)
    in_processes = run_script(processes)
    assert in_processes == in_threads
    states = [m for m in in_processes if m[1] in ("accepted", "rejected", "done", "interrupted")]
    assert ("default", "accepted", "big") in states
    assert ("default", "interrupted", "b1") in states  # by b6, a REPLACE block
    assert ("default", "done", "b7") in states  # preplanned, activated by b8's start
    assert ("default", "interrupted", "b3") in states
    assert ("default", "rejected", "b9") in states  # strict mode
    # the cross-block reference was resolved in the child: b2 was predicted
    assert any(m[1] == "prediction" and m[2] == "b2" for m in in_processes)


def test_a_message_over_the_planning_budget_is_refused_and_its_process_replaced() -> None:
    tight = PlannerPool(1, PlanningRecipe(), 1)  # 1 ms: no 256-behaviour block fits
    try:
        stage = Stage(session_factory(None), planner=tight)
        before = tight.pids()
        result = stage.submit_bml(big_block(), 0.0)
        assert not result.accepted
        warning = next(m for m in result.messages if isinstance(m, WireFeedback))
        assert "planning_milliseconds" in warning.xml and "1 ms" in warning.xml
        assert [m.state for m in result.messages if isinstance(m, BlockEvent)] == ["rejected"]
        after = tight.pids()
        assert len(after) == 1 and after != before and tight.replaced == 1
        # the fresh process plans the next message within a real budget
        tight.budget_ms = 5000
        small = bml("s", '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="0.5"/>')
        assert stage.submit_bml(small, 1.0).accepted
    finally:
        tight.close()
    assert not tight.pids()


def test_a_killed_planner_process_is_replaced_and_the_next_block_accepted(
    pool: PlannerPool,
) -> None:
    stage = Stage(session_factory(None), planner=pool)
    (pid,) = pool.pids()
    os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 10
    while pid in pool.pids() and time.monotonic() < deadline:
        time.sleep(0.01)
    small = bml("k", '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="0.5"/>')
    assert stage.submit_bml(small, 0.0).accepted
    assert pool.pids() and pid not in pool.pids()


def test_a_closed_pool_refuses_blocks_with_a_warning() -> None:
    closing = PlannerPool(1, PlanningRecipe(), 5000)
    closing.close()
    stage = Stage(session_factory(None), planner=closing)
    result = stage.submit_bml(bml("c", '<faceLexeme id="f" lexeme="RAISE_BROWS"/>'), 0.0)
    assert not result.accepted
    assert [m.state for m in result.messages if isinstance(m, BlockEvent)] == ["rejected"]
