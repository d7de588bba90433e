"""Property: every block the stage announces as accepted ends, exactly once.

Hypothesis drives a stage of real sessions (real parser, scheduler and
face engine) with random blocks: compositions, references to other blocks,
duplicate ids, interrupts, hostile values and garbage, with ticks between.
After every step it checks that

* each ``accepted`` is followed, later or in the same answer, by exactly
  one of ``done``, ``interrupted`` or ``failed``, and nothing ends that was
  not accepted;
* the stage's open blocks are exactly those, within ``queued_blocks``;
* every feedback message is well-formed XML;

and, once the clock has passed every block's end, that nothing is open.

The same property holds with blocks parsed and planned in a planner process
(realizer.service.planner, ``--planner-processes N``), on a third as many
examples. CI runs a bounded number of examples (a few seconds); for a long run by
hand set ``REALIZER_PROPERTY_EXAMPLES``, e.g. to 2000.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from realizer.service.assets import session_factory
from realizer.service.limits import ServiceLimits
from realizer.service.planner import PlannerPool, PlanningRecipe
from realizer.service.stage import BlockEvent, Stage, WireFeedback
from realizer.session import Session

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
EXAMPLES = int(os.environ.get("REALIZER_PROPERTY_EXAMPLES", "30"))
CHARACTERS = ("alice", "bob")
BLOCK_IDS = ("b0", "b1", "b2", "b3")
QUEUED = 4

times = st.sampled_from(
    [
        "0",
        "0.2",
        "1",
        "2.5",
        "bml:start",
        "bml:start+0.3",
        "f0:end",
        "f1:start+0.5",
        "b0:f0:end",
        "b1:f1:start-0.2",
        "h0:stroke:2",
        "1e308",
        "-1",
        "nan",
        "a:",
        "9" * 400,
        "x:" + " " * 300 + "y",
    ]
)


@st.composite
def behaviours(draw: Any, index: int) -> str:
    attributes = {
        name: draw(times) for name in draw(st.sets(st.sampled_from(["start", "end", "ready"])))
    }
    written = "".join(f' {name}="{value}"' for name, value in attributes.items())
    if draw(st.booleans()):
        repetition = draw(st.sampled_from(["1", "2", "3", "33", "1e308", "x"]))
        return f'<head id="h{index}" lexeme="NOD" repetition="{repetition}"{written}/>'
    lexeme = draw(st.sampled_from(["RAISE_BROWS", "RAISE_MOUTH_CORNERS", "NO_SUCH"]))
    odd = ' odd="1"' if draw(st.booleans()) else ""
    return f'<faceLexeme id="f{index}" lexeme="{lexeme}"{odd}{written}/>'


@st.composite
def submissions(draw: Any) -> tuple[str, Any, str]:
    character = draw(st.sampled_from(CHARACTERS))
    if draw(st.integers(0, 9)) == 0:
        garbage = draw(
            st.sampled_from(["", "<bml/>", "not xml", f'<bml xmlns="{BML_NS}"/>', "\x00"])
        )
        return ("submit", character, garbage)
    block_id = draw(st.sampled_from(BLOCK_IDS))
    composition = draw(st.sampled_from(["MERGE", "APPEND", "REPLACE"]))
    count = draw(st.integers(0, 3))
    body = "".join(draw(behaviours(n)) for n in range(count))
    text = f'<bml xmlns="{BML_NS}" id="{block_id}" composition="{composition}">{body}</bml>'
    return ("submit", character, text)


operations = st.one_of(
    submissions(),
    st.tuples(
        st.just("interrupt"),
        st.sampled_from((*CHARACTERS, "nobody")),
        st.sampled_from((*BLOCK_IDS, "\x00", "\udc80")),
    ),
    st.tuples(st.just("tick"), st.sampled_from([0.0, 0.02, 0.3, 1.0, 3.0]), st.just("")),
)


class Model:
    """What the announced block events say is open."""

    def __init__(self) -> None:
        self.open: set[tuple[str, str]] = set()

    def check(self, messages: Any) -> None:
        for message in messages:
            if isinstance(message, WireFeedback):
                etree.fromstring(message.xml.encode("utf-8"))  # well-formed
                continue
            assert isinstance(message, BlockEvent)
            key = (message.character, message.block_id)
            if message.state == "accepted":
                assert key not in self.open, f"{key} accepted twice"
                self.open.add(key)
            elif message.state in ("done", "interrupted", "failed"):
                assert key in self.open, f"{key} ended ({message.state}) but was not open"
                self.open.remove(key)


def check_stage(stage: Stage, model: Model) -> None:
    for character in stage.characters.values():
        assert len(character.open_blocks) <= QUEUED
        opened = {(character.id, block_id) for block_id in character.open_blocks}
        assert opened == {key for key in model.open if key[0] == character.id}


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(st.lists(operations, max_size=14))
def test_every_accepted_block_ends_exactly_once(steps: list[tuple[str, Any, Any]]) -> None:
    run_steps(Stage(lambda c: Session(c), ServiceLimits(queued_blocks=QUEUED)), steps)


@pytest.fixture(scope="module")
def planner_pool() -> Iterator[PlannerPool]:
    pool = PlannerPool(1, PlanningRecipe(), ServiceLimits().planning_milliseconds)
    try:
        yield pool
    finally:
        pool.close()


@settings(
    max_examples=max(1, EXAMPLES // 3),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(st.lists(operations, max_size=14))
def test_every_accepted_block_ends_exactly_once_with_a_planner_process(
    planner_pool: PlannerPool, steps: list[tuple[str, Any, Any]]
) -> None:
    stage = Stage(session_factory(None), ServiceLimits(queued_blocks=QUEUED), planner=planner_pool)
    run_steps(stage, steps)


def run_steps(stage: Stage, steps: list[tuple[str, Any, Any]]) -> None:
    """Drive ``stage`` through ``steps``, checking the invariant after each."""
    model = Model()
    now = 0.0
    for kind, first, second in steps:
        if kind == "submit":
            result = stage.submit_bml(second, now, character=first)
            model.check(result.messages)
            announced = [
                m.state
                for m in result.messages
                if isinstance(m, BlockEvent) and m.block_id == result.block_id
            ]
            assert result.accepted == ("accepted" in announced)
            assert result.accepted != ("rejected" in announced)
        elif kind == "interrupt":
            model.check(stage.interrupt(first, second, now))
        else:
            now += first
            for character_tick in stage.tick(now):
                model.check(character_tick.messages)
        check_stage(stage, model)
    # Valid times are a few seconds, APPEND chains at most QUEUED long: after
    # a minute every accepted block has ended.
    for character_tick in stage.tick(now + 60.0):
        model.check(character_tick.messages)
    check_stage(stage, model)
    assert model.open == set()
