"""The sans-I/O session: lifecycle, feedback, composition, frames."""

from __future__ import annotations

import re

import pytest
from lxml import etree

from realizer.bml_parser import BML_NS, BMLA_NS
from realizer.session import (
    TRANSITIONS,
    BlockEvent,
    BlockLifecycle,
    BlockState,
    LifecycleError,
    Session,
    SessionLimits,
)
from tests.conftest import EXAMPLES


def bml(block_id: str, body: str, attrs: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" id="{block_id}" {attrs}>{body}</bml>'


NOD = '<head id="nod1" lexeme="NOD" start="0" end="1"/>'


def kinds(session: Session) -> list[str]:
    return [f.kind for f in session.take_feedback()]


def parse(xml: str) -> etree._Element:
    return etree.fromstring(xml.encode())


# -- the lifecycle table -----------------------------------------------------


def test_lifecycle_allows_exactly_the_table() -> None:
    for state in BlockState:
        for event in BlockEvent:
            life = BlockLifecycle("b", state)
            if (state, event) in TRANSITIONS:
                assert life.handle(event) is TRANSITIONS[(state, event)]
            else:
                with pytest.raises(LifecycleError, match=f"{event.value!r}.*{state.value!r}"):
                    life.handle(event)


def test_finished_states_are_final() -> None:
    finals = {BlockState.DONE, BlockState.INTERRUPTED, BlockState.FAILED}
    assert not [key for key in TRANSITIONS if key[0] in finals]


# -- feedback ------------------------------------------------------------------


def test_a_block_gets_prediction_then_progress_in_time_order_each_once() -> None:
    session = Session("Alice")
    plan = session.receive_bml(bml("b1", NOD), now=10.0)
    assert plan is not None and plan.start == 10.0
    first = session.take_feedback()
    assert [f.kind for f in first][:1] == ["prediction"]
    prediction = parse(first[0].xml)
    assert prediction.tag == f"{{{BML_NS}}}predictionFeedback"
    assert prediction.get("characterId") == "Alice"
    block = prediction.find(f"{{{BML_NS}}}bml")
    assert block is not None and float(block.get("globalEnd", "")) == pytest.approx(11.0)
    collected = first[1:]
    for now in (10.2, 10.5, 10.9, 11.5, 12.0, 13.0):
        session.tick(now)
        collected += session.take_feedback()
    times = [f.time for f in collected]
    assert times == sorted(times)
    ids = [parse(f.xml).get("id") for f in collected]
    assert ids[0] == "b1:start" and ids[-1] == "b1:end"
    syncs = [i for i in ids if i and i.startswith("b1:nod1:")]
    assert syncs == [f"b1:nod1:{s}" for s in plan.behaviours[0].times]  # canonical order
    assert len(ids) == len(set(ids))  # exactly once
    assert session.state("b1") is BlockState.DONE


def test_sync_point_progress_carries_block_relative_and_global_time() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=5.0)
    session.tick(7.0)
    progress = [parse(f.xml) for f in session.take_feedback() if f.kind == "syncPointProgress"]
    end = next(p for p in progress if p.get("id") == "b1:nod1:end")
    assert float(end.get("time", "")) == pytest.approx(1.0)
    assert float(end.get("globalTime", "")) == pytest.approx(6.0)


def test_progress_is_not_reported_before_its_time() -> None:
    session = Session()
    session.receive_bml(bml("b1", '<head id="n" lexeme="NOD" start="2" end="3"/>'), now=0.0)
    assert kinds(session) == ["prediction", "blockProgress"]  # the block starts at once
    session.tick(1.0)
    assert kinds(session) == []  # the nod starts at 2
    session.tick(2.5)
    assert kinds(session).count("syncPointProgress") >= 2


def test_parse_errors_answer_with_a_warning_and_keep_the_session() -> None:
    session = Session()
    assert session.receive_bml("<bml", now=0.0) is None
    (feedback,) = session.take_feedback()
    element = parse(feedback.xml)
    assert element.get("type") == "PARSING_FAILURE"
    assert re.match(r"\d+:\d+: ", element.text or "")
    assert session.receive_bml(bml("b2", NOD), now=0.0) is not None


def test_warnings_come_before_the_prediction() -> None:
    session = Session()
    session.receive_bml(bml("b1", '<head id="n" lexeme="NOD" start="ghost:end"/>'), now=0.0)
    feedback = session.take_feedback()
    assert [f.kind for f in feedback][:2] == ["warning", "prediction"]
    assert parse(feedback[0].xml).get("type") == "NO_SUCH_TARGET"


def test_a_required_part_that_cannot_be_met_fails_the_block() -> None:
    session = Session()
    body = (
        '<required><head id="a" lexeme="NOD" start="2" end="3"/>'
        '<head id="b" lexeme="NOD" start="a:end" end="a:start"/></required>'
    )
    assert session.receive_bml(bml("b1", body), now=0.0) is None
    feedback = [parse(f.xml) for f in session.take_feedback()]
    assert feedback[-1].get("type") == "IMPOSSIBLE_TO_SCHEDULE"
    assert session.state("b1") is BlockState.FAILED


def test_an_optional_constraint_is_dropped_with_a_warning_naming_it() -> None:
    session = Session()
    body = (
        '<head id="a" lexeme="NOD" start="0" end="1"/>'
        '<faceLexeme id="b" lexeme="RAISE_MOUTH_CORNERS" start="0" end="1"/>'  # no channel conflict
        '<constraint id="impossible">'
        '<before ref="a:start"><sync ref="b:end"/></before></constraint>'
    )
    plan = session.receive_bml(bml("b1", body), now=0.0)
    assert plan is not None and {b.id for b in plan.behaviours} == {"a", "b"}
    warnings = [parse(f.xml) for f in session.take_feedback() if f.kind == "warning"]
    assert len(warnings) == 1 and "impossible" in (warnings[0].text or "")


# -- composition and interruption ----------------------------------------------


def test_merge_starts_now_beside_running_blocks() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=0.0)
    plan = session.receive_bml(bml("b2", NOD), now=0.5)
    assert plan is not None and plan.start == 0.5
    session.tick(0.6)
    assert session.state("b1") is BlockState.IN_EXECUTION
    assert session.state("b2") is BlockState.IN_EXECUTION


def test_append_starts_after_every_earlier_block_ends() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=0.0)
    session.receive_bml(bml("b2", '<head id="n" lexeme="NOD" start="0" end="2"/>'), now=0.2)
    plan = session.receive_bml(bml("b3", NOD, 'composition="APPEND"'), now=0.5)
    assert plan is not None and plan.start == pytest.approx(2.2)
    session.tick(1.0)
    assert session.state("b3") is BlockState.PENDING
    session.tick(2.3)
    assert session.state("b3") is BlockState.IN_EXECUTION


def test_replace_interrupts_running_and_pending_blocks_first() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=0.0)
    session.receive_bml(bml("b2", NOD, 'composition="APPEND"'), now=0.1)
    session.take_feedback()
    plan = session.receive_bml(bml("b3", NOD, 'composition="REPLACE"'), now=0.5)
    assert plan is not None and plan.start == 0.5
    assert session.state("b1") is BlockState.INTERRUPTED
    assert session.state("b2") is BlockState.INTERRUPTED
    ends = [parse(f.xml) for f in session.take_feedback() if f.kind == "blockProgress"]
    # BMLA's block status: b1 was running (INTERRUPTED), b2 had not begun (REVOKED)
    status = f"{{{BMLA_NS}}}status"
    assert {(e.get("id"), e.get(status)) for e in ends} >= {
        ("b1:end", "INTERRUPTED"),
        ("b2:end", "REVOKED"),
    }
    assert all(e.get("status") is None for e in ends)  # BML 1.0 has no plain status


def test_interrupt_by_id_stops_progress_feedback() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=0.0)
    session.tick(0.3)
    session.take_feedback()
    assert session.interrupt("b1", now=0.3)
    session.tick(5.0)
    assert kinds(session) == ["blockProgress"]  # only the interrupted end
    assert not session.interrupt("b1", now=5.0)  # nothing left to interrupt
    assert parse(session.take_feedback()[0].xml).get("type") == "NO_SUCH_TARGET"


def test_a_block_may_refer_to_a_running_block() -> None:
    session = Session()
    first = session.receive_bml(bml("b1", NOD), now=0.0)
    assert first is not None
    plan = session.receive_bml(bml("b2", '<head id="n2" lexeme="NOD" start="b1:nod1:end"/>'), 0.2)
    assert plan is not None
    assert plan.time_of("n2", "start") == pytest.approx(first.time_of("nod1", "end"))


def test_a_running_block_id_cannot_be_reused() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD), now=0.0)
    assert session.receive_bml(bml("b1", NOD), now=0.1) is None
    assert parse(session.take_feedback()[-1].xml).get("type") == "PARSING_FAILURE"


# -- frames --------------------------------------------------------------------


def test_frames_follow_a_smile_through_its_envelope() -> None:
    session = Session()
    session.receive_bml((EXAMPLES / "01_smile.xml").read_text(), now=0.0)
    before = session.frame(-0.1)
    peak = session.frame(1.0)
    after = session.frame(3.0)
    assert not before.mask.any() and not after.mask.any()
    # raise_l_cornerlip_o / raise_r_cornerlip_o (FAPs 59, 60) lift at the peak
    assert peak.values[58] > 0 and peak.values[59] > 0
    assert session.frame(0.2).values[58] < peak.values[58]


def test_an_interrupted_smile_eases_out() -> None:
    session = Session()
    session.receive_bml((EXAMPLES / "01_smile.xml").read_text(), now=0.0)
    session.tick(1.0)
    session.interrupt("smile", now=1.0)
    assert session.frame(1.05).values[58] > 0
    assert not session.frame(1.5).mask.any()


def test_a_long_running_session_forgets_old_finished_blocks() -> None:
    session = Session(limits=SessionLimits(finished_kept=8))
    now = 0.0
    for index in range(40):
        session.receive_bml(bml(f"b{index}", NOD), now=now)
        now += 1.5
        session.tick(now)
    session.take_feedback()
    remembered = [f"b{i}" for i in range(40) if session.state(f"b{i}") is not None]
    assert len(remembered) <= 9
    assert session.state("b39") is BlockState.DONE and session.state("b0") is None
    # the recent ones can still be referred to
    plan = session.receive_bml(bml("late", '<head id="n" lexeme="NOD" start="b39:nod1:end+100"/>'),
                               now=now)  # fmt: skip
    assert plan is not None and not plan.warnings
    assert not session.frame(now + 50).mask.any()  # ended animations no longer mix


def test_a_tick_looks_only_at_live_blocks_not_at_the_finished_ones_kept() -> None:
    # The per-frame cost must not grow with the finished blocks kept for
    # queries: they leave the set a tick walks once their animations end.
    session = Session(limits=SessionLimits(finished_kept=64))
    now = 0.0
    for index in range(64):
        session.receive_bml(bml(f"b{index}", NOD), now=now)
        now += 1.5
        session.tick(now)
    assert all(session.state(f"b{i}") is BlockState.DONE for i in range(64))
    session.receive_bml(bml("playing", NOD), now=now)
    assert [r.lifecycle.block_id for r in session._live] == ["playing"]
    session.tick(now + 0.3)
    assert session.frame(now + 0.3).mask.any()


def test_forgetting_an_old_block_keeps_a_newer_block_of_the_same_id() -> None:
    session = Session(limits=SessionLimits(finished_kept=1))
    session.receive_bml(bml("again", NOD), now=0.0)
    session.tick(1.5)
    assert session.state("again") is BlockState.DONE
    long = '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="10"/>'
    session.receive_bml(bml("again", long), now=1.5)  # the id is used once more
    session.receive_bml(bml("short", NOD), now=1.5)
    session.tick(3.0)  # "short" finished: the first "again" is one too many
    assert session.state("short") is BlockState.DONE
    assert session.state("again") is BlockState.IN_EXECUTION
    assert session.frame(3.0).mask.any()
