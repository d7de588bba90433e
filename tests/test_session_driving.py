"""The sans-I/O session: lifecycle, composition, cross-block references, feedback, frames.

Every test drives the session with explicit times, faster than real time;
feedback is parsed as XML and checked against BML 1.0 (namespace, ids,
block-relative ``time`` and ``globalTime``), and each message must come
exactly once and in time order.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from lxml import etree

from realizer.bml_parser import BML_NS, BMLA_NS
from realizer.face.frame import FapFrame
from realizer.feedback import Feedback
from realizer.session import (
    TRANSITIONS,
    BlockEvent,
    BlockLifecycle,
    BlockState,
    LifecycleError,
    Session,
)

NS = {"b": BML_NS}


def bml(block_id: str, body: str, composition: str = "") -> str:
    extra = f' composition="{composition}"' if composition else ""
    return f'<bml xmlns="{BML_NS}" id="{block_id}"{extra}>{body}</bml>'


NOD = '<head id="nod1" lexeme="NOD" start="{start}" end="{end}"/>'


def xml(feedback: Feedback) -> etree._Element:
    element = etree.fromstring(feedback.xml.encode())
    assert etree.QName(element).namespace == BML_NS
    return element


def drain(session: Session, until: float, step: float = 0.05) -> list[Feedback]:
    """Tick from the session's time to ``until`` and take everything queued."""
    out = session.take_feedback()
    now = max(session.now, 0.0)
    while now < until:
        now = min(until, now + step)
        session.tick(now)
        out += session.take_feedback()
    return out


# -- the lifecycle table --------------------------------------------------------


def test_lifecycle_table_allows_only_its_transitions() -> None:
    for state, event in itertools.product(BlockState, BlockEvent):
        lifecycle = BlockLifecycle("b", state)
        if (state, event) in TRANSITIONS:
            assert lifecycle.handle(event) is TRANSITIONS[(state, event)]
        else:
            with pytest.raises(LifecycleError) as caught:
                lifecycle.handle(event)
            assert event.value in str(caught.value) and state.value in str(caught.value)


def test_final_states_have_no_way_out() -> None:
    finals = {BlockState.DONE, BlockState.INTERRUPTED, BlockState.FAILED}
    assert not [key for key in TRANSITIONS if key[0] in finals]


def test_a_block_goes_pending_then_in_execution_then_done() -> None:
    session = Session("Alice")
    session.receive_bml(bml("b1", NOD.format(start=1, end=2)), now=0.0)
    assert session.state("b1") is BlockState.IN_EXECUTION  # a block starts when it arrives
    session.tick(1.5)
    assert session.state("b1") is BlockState.IN_EXECUTION
    session.tick(2.0)
    assert session.state("b1") is BlockState.DONE


def test_an_appended_block_is_pending_until_its_start() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=2)), now=0.0)
    session.receive_bml(bml("b2", NOD.format(start=0, end=1), "APPEND"), now=0.5)
    assert session.state("b2") is BlockState.PENDING
    plan = session.plan("b2")
    assert plan is not None and plan.start == pytest.approx(2.0)
    session.tick(2.0)
    assert session.state("b2") is BlockState.IN_EXECUTION


# -- feedback -------------------------------------------------------------------


def test_prediction_gives_every_solved_time() -> None:
    session = Session("Alice")
    plan = session.receive_bml(bml("b1", NOD.format(start=1, end=3)), now=10.0)
    assert plan is not None
    [prediction] = [f for f in session.take_feedback() if f.kind == "prediction"]
    element = xml(prediction)
    assert etree.QName(element).localname == "predictionFeedback"
    block = element.find("b:bml", NS)
    assert block is not None and block.get("id") == "b1"
    assert float(block.get("globalStart", "nan")) == pytest.approx(10.0)
    assert float(block.get("globalEnd", "nan")) == pytest.approx(13.0)
    head = element.find("b:head", NS)
    assert head is not None and head.get("id") == "b1:nod1"  # OpenBMLParser reads block:id
    assert head.get("lexeme") == "NOD"
    [scheduled] = plan.behaviours
    for sync, time in scheduled.times.items():
        if sync in head.attrib:
            assert float(head.get(sync, "nan")) == pytest.approx(time, abs=1e-6)
        else:  # repeated strokes and speech markers are <sync> children
            [child] = [c for c in head.findall("b:sync", NS) if c.get("id") == sync]
            assert float(child.get("globalTime", "nan")) == pytest.approx(time, abs=1e-6)
    assert float(head.get("start", "nan")) == pytest.approx(11.0)
    assert float(head.get("end", "nan")) == pytest.approx(13.0)


def test_progress_feedback_comes_once_each_in_time_order() -> None:
    session = Session("Alice")
    text = bml(
        "b1",
        '<speech id="s1"><text>Hello <sync id="m1"/>there, friend.</text></speech>'
        '<head id="nod1" lexeme="NOD" stroke="s1:m1"/>',
    )
    plan = session.receive_bml(text, now=5.0)
    assert plan is not None
    feedback = drain(session, plan.end + 1.0, step=0.07)
    times = [f.time for f in feedback]
    assert times == sorted(times)
    assert len({f.xml for f in feedback}) == len(feedback)  # nothing twice
    progress = [xml(f) for f in feedback if f.kind == "syncPointProgress"]
    expected = {
        f"b1:{s.id}:{sync}": time for s in plan.behaviours for sync, time in s.times.items()
    }
    got = {e.get("id"): e for e in progress}
    assert set(got) == set(expected)
    assert len(progress) == len(expected)
    for ident, element in got.items():
        assert float(element.get("globalTime", "nan")) == pytest.approx(expected[ident], abs=1e-6)
        assert float(element.get("time", "nan")) == pytest.approx(
            expected[ident] - plan.start, abs=1e-6
        )
    blocks = [xml(f).get("id") for f in feedback if f.kind == "blockProgress"]
    assert blocks == ["b1:start", "b1:end"]
    assert feedback[0].kind == "prediction"
    assert feedback[-1].kind == "blockProgress"


def test_a_coarse_tick_reports_what_it_passed_in_time_order() -> None:
    fine, coarse = Session(), Session()
    text = bml("b1", NOD.format(start=0.5, end=2) + '<gesture id="g1" lexeme="BEAT" start="1"/>')
    fine.receive_bml(text, now=0.0)
    coarse.receive_bml(text, now=0.0)
    many = drain(fine, 5.0, step=0.01)
    coarse.tick(5.0)
    once = coarse.take_feedback()
    assert [f.xml for f in once] == [f.xml for f in many]


def test_ticking_backwards_reports_nothing_again() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=1)), now=0.0)
    first = drain(session, 2.0)
    session.tick(0.5)
    session.tick(2.0)
    assert session.take_feedback() == []
    assert first


def test_warnings_are_bml_warning_feedback_with_the_standard_type() -> None:
    session = Session()
    session.receive_bml(bml("b1", '<head id="nod1" lexeme="NOD" start="ghost:end"/>'), now=0.0)
    [warning] = [f for f in session.take_feedback() if f.kind == "warning"]
    element = xml(warning)
    assert etree.QName(element).localname == "warningFeedback"
    assert element.get("type") == "NO_SUCH_TARGET"
    assert "ghost" in (element.text or "")


def test_unparsable_bml_gives_a_parsing_failure_and_the_session_goes_on() -> None:
    session = Session()
    assert session.receive_bml("<bml id='x'><head", now=0.0) is None
    [warning] = session.take_feedback()
    assert xml(warning).get("type") == "PARSING_FAILURE"
    assert session.receive_bml(bml("b2", NOD.format(start=0, end=1)), now=0.1) is not None


def test_a_block_whose_required_parts_cannot_hold_fails() -> None:
    session = Session()
    body = (
        NOD.format(start=0, end=1)
        + "<required>"
        + '<constraint id="one"><synchronize><sync ref="nod1:stroke"/><sync ref="0.5"/>'
        + "</synchronize></constraint>"
        + '<constraint id="two"><synchronize><sync ref="nod1:stroke"/><sync ref="0.7"/>'
        + "</synchronize></constraint></required>"
    )
    assert session.receive_bml(bml("b1", body), now=0.0) is None
    assert session.state("b1") is BlockState.FAILED
    feedback = session.take_feedback()
    assert [xml(f).get("type") for f in feedback] == ["IMPOSSIBLE_TO_SCHEDULE"]
    session.tick(5.0)
    assert session.take_feedback() == []


# -- interruption and composition ----------------------------------------------


def test_interrupting_a_running_block_ends_it_and_stops_its_progress() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=4)), now=0.0)
    drain(session, 1.0)
    assert session.interrupt("b1", now=1.0)
    assert session.state("b1") is BlockState.INTERRUPTED
    [end] = session.take_feedback()
    element = xml(end)
    assert element.get("id") == "b1:end"
    assert element.get(f"{{{BMLA_NS}}}status") == "INTERRUPTED"
    assert float(element.get("globalTime", "nan")) == pytest.approx(1.0)
    assert drain(session, 6.0) == []


def test_interrupting_an_unknown_or_finished_block_is_a_warning() -> None:
    session = Session()
    assert not session.interrupt("nothing", now=0.0)
    [warning] = session.take_feedback()
    assert xml(warning).get("type") == "NO_SUCH_TARGET"
    session.receive_bml(bml("b1", NOD.format(start=0, end=1)), now=0.0)
    drain(session, 2.0)
    assert not session.interrupt("b1", now=2.0)
    assert session.state("b1") is BlockState.DONE


def test_merge_starts_now_beside_running_blocks() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=4)), now=0.0)
    plan = session.receive_bml(bml("b2", NOD.format(start=0, end=1), "MERGE"), now=1.0)
    assert plan is not None and plan.start == pytest.approx(1.0)
    assert session.state("b1") is BlockState.IN_EXECUTION


def test_append_starts_after_every_earlier_block_ends() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=4)), now=0.0)
    session.receive_bml(bml("b2", NOD.format(start=1, end=3)), now=0.0)
    plan = session.receive_bml(bml("b3", NOD.format(start=0, end=1), "APPEND"), now=0.5)
    assert plan is not None and plan.start == pytest.approx(4.0)
    assert plan.time_of("nod1", "start") == pytest.approx(4.0)


def test_replace_interrupts_running_and_pending_blocks_first() -> None:
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=4)), now=0.0)
    session.receive_bml(bml("b2", NOD.format(start=0, end=1), "APPEND"), now=0.0)
    session.take_feedback()
    plan = session.receive_bml(bml("b3", NOD.format(start=0, end=1), "REPLACE"), now=1.0)
    assert plan is not None and plan.start == pytest.approx(1.0)
    assert session.state("b1") is BlockState.INTERRUPTED
    assert session.state("b2") is BlockState.INTERRUPTED
    ends = [xml(f).get("id") for f in session.take_feedback() if f.kind == "blockProgress"]
    assert ends[:2] == ["b1:end", "b2:end"]


def test_a_new_block_is_solved_against_a_running_blocks_fixed_times() -> None:
    session = Session()
    first = session.receive_bml(bml("b1", NOD.format(start=0, end=4)), now=0.0)
    assert first is not None
    stroke = first.time_of("nod1", "stroke")
    assert stroke is not None
    drain(session, 1.0)
    second = session.receive_bml(
        bml("b2", '<gesture id="g1" lexeme="BEAT" stroke="b1:nod1:end"/>'), now=1.0
    )
    assert second is not None
    assert second.time_of("g1", "stroke") == pytest.approx(4.0, abs=1e-9)
    # The running block keeps its times.
    assert session.plan("b1") is first


def test_a_reference_to_an_unknown_block_is_a_warning() -> None:
    session = Session()
    plan = session.receive_bml(
        bml("b2", '<gesture id="g1" lexeme="BEAT" stroke="nope:nod1:end"/>'), now=0.0
    )
    assert plan is not None
    types = [xml(f).get("type") for f in session.take_feedback() if f.kind == "warning"]
    assert types == ["NO_SUCH_TARGET"]


# -- frames ---------------------------------------------------------------------


def test_frames_are_neutral_without_face_behaviours() -> None:
    session = Session()
    session.receive_bml(bml("b1", '<gesture id="g1" lexeme="BEAT"/>'), now=0.0)
    frame = session.frame(0.5)
    assert isinstance(frame, FapFrame)
    assert not frame.mask.any()
    assert frame.time == 0.5


def test_the_face_engine_animates_a_smile_through_the_registry() -> None:
    session = Session()
    session.receive_bml(
        bml("b1", '<faceLexeme id="f1" lexeme="RAISE_BROWS" start="1" end="3"/>'), now=0.0
    )
    before, during, after = session.frame(0.5), session.frame(2.0), session.frame(4.0)
    assert not before.mask.any()
    assert during.mask.any() and np.abs(during.vector).max() > 0
    assert not np.any(after.vector)


def test_a_block_arriving_between_ticks_keeps_feedback_in_time_order() -> None:
    # b1's sync points between the last tick and b2's arrival come before
    # b2's prediction, not after it.
    session = Session()
    session.receive_bml(bml("b1", NOD.format(start=0, end=2)), now=0.0)
    session.take_feedback()
    session.receive_bml(bml("b2", NOD.format(start=0, end=1)), now=1.0)
    feedback = session.take_feedback()
    times = [f.time for f in feedback]
    assert times == sorted(times)
    kinds = [(f.block_id, f.kind) for f in feedback]
    assert ("b1", "syncPointProgress") in kinds
    assert kinds.index(("b2", "prediction")) > max(
        i for i, k in enumerate(kinds) if k == ("b1", "syncPointProgress")
    )
