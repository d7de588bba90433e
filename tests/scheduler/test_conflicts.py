"""Conflicts a user can understand: required parts fail the block, warnings say why."""

from __future__ import annotations

import pytest

from realizer.bml_parser import BML_NS, WarningType, parse_bml
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import SchedulingFailed, schedule_block
from realizer.session import BlockState, Session


def block(body: str) -> str:
    return f'<bml xmlns="{BML_NS}" id="x">{body}</bml>'


ISSUE_EXAMPLE = block(
    '<faceLexeme id="a" lexeme="RAISE_BROWS" start="0" end="2"/>'
    '<required><faceLexeme id="b" lexeme="WIDEN_EYES" start="a:end" end="a:start+1"/>'
    "</required>"
)


def test_a_required_behaviour_whose_references_cannot_hold_fails_the_block() -> None:
    with pytest.raises(SchedulingFailed) as caught:
        schedule_block(parse_bml(ISSUE_EXAMPLE).block, registry=EngineRegistry.standard())
    [warning] = caught.value.warnings
    assert warning.type is WarningType.IMPOSSIBLE_TO_SCHEDULE
    message = warning.message
    # the references and the bounds that conflict, in the document's words
    for part in ('b start="a:end"', 'b end="a:start+1"', 'a start="0"', 'a end="2"'):
        assert part in message
    assert "'a' cannot be removed because a required part refers to it" in message


def test_the_session_reports_the_failed_block_and_runs_nothing() -> None:
    session = Session()
    assert session.receive_bml(ISSUE_EXAMPLE, now=0.0) is None
    assert session.state("x") is BlockState.FAILED
    kinds = [f.kind for f in session.take_feedback()]
    assert kinds == ["warning"]


def test_a_removed_behaviour_is_named_with_the_constraints_that_conflict() -> None:
    text = block(
        '<head id="n" lexeme="NOD" start="1" end="2"/>'
        '<faceLexeme id="f" lexeme="RAISE_MOUTH_CORNERS" start="n:end" end="n:start"/>'
    )
    plan = schedule_block(parse_bml(text).block, registry=EngineRegistry.standard())
    assert plan.dropped == {"f"}
    [warning] = [w for w in plan.warnings if w.type is WarningType.IMPOSSIBLE_TO_SCHEDULE]
    assert warning.id == "x:f"
    assert 'f start="n:end"' in warning.message and 'f end="n:start"' in warning.message


def test_a_conflicting_constraint_is_named_with_its_relation() -> None:
    text = block(
        '<head id="n" lexeme="NOD" start="1" end="2"/>'
        '<faceLexeme id="m" lexeme="RAISE_MOUTH_CORNERS" start="0" end="3"/>'
        '<constraint id="c1"><before ref="n:start"><sync ref="m:end"/></before></constraint>'
    )
    plan = schedule_block(parse_bml(text).block, registry=EngineRegistry.standard())
    [warning] = [w for w in plan.warnings if w.type is WarningType.IMPOSSIBLE_TO_SCHEDULE]
    assert warning.id == "x:c1"
    assert "<before> of constraint 'c1' (ref=\"n:start\")" in warning.message
    assert 'n start="1"' in warning.message and 'm end="3"' in warning.message


# -- resource channels ---------------------------------------------------------------


def scheduled(body: str) -> tuple[set[str], list[str]]:
    plan = schedule_block(parse_bml(block(body)).block, registry=EngineRegistry.standard())
    return {b.id for b in plan.behaviours}, [
        f"{w.id}: {w.message}"
        for w in plan.warnings
        if w.type is WarningType.IMPOSSIBLE_TO_SCHEDULE
    ]


def test_the_later_of_two_gazes_with_identical_timing_is_removed_with_a_warning() -> None:
    kept, warnings = scheduled(
        '<gaze id="g1" target="camera" start="0" end="2"/>'
        '<gaze id="g2" target="user" start="0" end="2"/>'
    )
    assert kept == {"g1"}
    [warning] = warnings
    assert (
        warning.startswith("x:g2: ") and "gaze channel" in warning and "'g2' is removed" in warning
    )


def test_a_behaviour_inside_another_on_its_channel_is_removed_if_later() -> None:
    kept, warnings = scheduled(
        '<head id="h1" lexeme="NOD" start="0" end="3"/>'
        '<head id="h2" lexeme="NOD" start="1" end="2"/>'
        '<head id="h3" lexeme="TILT" start="1" end="2"/>'  # another axis: combines
    )
    assert kept == {"h1", "h3"} and len(warnings) == 1 and "head-pitch channel" in warnings[0]


def test_a_required_behaviour_keeps_its_channel() -> None:
    kept, warnings = scheduled(
        '<gaze id="g1" target="camera" start="0" end="2"/>'
        '<required><gaze id="g2" target="user" start="0" end="2"/></required>'
    )
    assert kept == {"g2"} and "'g1' is removed" in warnings[0]


def test_a_partial_overlap_keeps_both_and_warns() -> None:
    kept, warnings = scheduled(
        '<head id="h1" lexeme="SHAKE" start="0" end="2"/>'
        '<head id="h2" lexeme="SHAKE" start="1" end="3"/>'
    )
    assert (
        kept == {"h1", "h2"}
        and "partial overlap" in warnings[0]
        and "1.000 to 2.000" in warnings[0]
    )


def test_behaviours_on_different_channels_or_one_after_another_do_not_conflict() -> None:
    kept, warnings = scheduled(
        '<gaze id="g1" target="camera" start="0" end="1"/>'
        '<gaze id="g2" target="user" start="1" end="2"/>'
        '<head id="h1" lexeme="NOD" start="0" end="2"/>'
        '<gazeShift id="s1" target="camera" start="0" end="2"/>'
        '<faceLexeme id="f1" lexeme="RAISE_MOUTH_CORNERS" start="0" end="2"/>'
        '<faceLexeme id="f2" lexeme="RAISE_BROWS" start="0" end="2"/>'
    )
    assert kept == {"g1", "g2", "h1", "s1", "f1", "f2"} and warnings == []


# -- resource channels across blocks (a character's blocks side by side) ------------


def session_warnings(session: Session) -> list[str]:
    return [fb.xml for fb in session.take_feedback() if fb.kind == "warning"]


def test_a_gaze_inside_a_gaze_of_an_earlier_block_is_removed_with_a_warning() -> None:
    session = Session("x")
    first = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b1"><gaze id="g1" target="camera" start="0" end="3"/></bml>',
        0.0,
    )
    assert first is not None
    second = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b2" composition="MERGE">'
        '<gaze id="g2" target="user" start="0" end="2"/>'
        '<head id="h1" lexeme="NOD" start="0" end="1"/></bml>',
        0.5,
    )
    assert second is not None
    assert {b.id for b in second.behaviours} == {"h1"}
    [warning] = [w for w in session_warnings(session) if "IMPOSSIBLE_TO_SCHEDULE" in w]
    assert 'id="b2:g2"' in warning
    assert "'b1:g1' and 'g2' both need the gaze channel" in warning
    assert "'g2' is removed" in warning


def test_across_blocks_a_partial_overlap_warns_and_a_later_block_does_not_conflict() -> None:
    session = Session("x")
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b1"><head id="h1" lexeme="SHAKE" start="0" end="2"/></bml>',
        0.0,
    )
    partial = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b2"><head id="h2" lexeme="SHAKE" start="1" end="3"/></bml>',
        0.0,
    )
    assert partial is not None and {b.id for b in partial.behaviours} == {"h2"}
    [warning] = [w for w in session_warnings(session) if "IMPOSSIBLE_TO_SCHEDULE" in w]
    assert "partial overlap" in warning and "'b1:h1'" in warning
    # an appended block starts when the others end: nothing to share
    appended = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b3" composition="APPEND">'
        '<head id="h3" lexeme="SHAKE" start="0" end="1"/></bml>',
        0.0,
    )
    assert appended is not None and {b.id for b in appended.behaviours} == {"h3"}
    assert not [w for w in session_warnings(session) if "IMPOSSIBLE_TO_SCHEDULE" in w]


def test_across_blocks_a_required_behaviour_runs_beside_the_earlier_one() -> None:
    session = Session("x")
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b1"><gaze id="g1" target="camera" start="0" end="2"/></bml>',
        0.0,
    )
    plan = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b2"><required>'
        '<gaze id="g2" target="user" start="0" end="2"/></required></bml>',
        0.0,
    )
    assert plan is not None and {b.id for b in plan.behaviours} == {"g2"}
    [warning] = [w for w in session_warnings(session) if "IMPOSSIBLE_TO_SCHEDULE" in w]
    assert "both run" in warning
