"""The draft revision of 2008: read onto the BML 1.0 types, kept as written."""

from __future__ import annotations

import pytest

from realizer.bml_parser import DRAFT_NS, canonical, parse_bml, serialise
from realizer.bml_parser.feedback import PredictionFeedback, parse_feedback
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import schedule_block
from realizer.session import Session
from tests.conftest import EXAMPLES

DRAFT = EXAMPLES / "15_draft_2008.xml"


def draft(body: str) -> str:
    return f'<bml xmlns="{DRAFT_NS}" id="d">{body}</bml>'


def test_the_draft_document_maps_onto_bml_1_0_types_without_warnings() -> None:
    result = parse_bml(DRAFT.read_bytes())
    assert result.warnings == ()
    by_id = {b.id: b for b in result.block.behaviours}
    assert by_id["nod"].type == "head" and by_id["nod"].lexeme == "NOD"
    assert by_id["shake"].lexeme == "SHAKE"
    assert by_id["point"].type == "pointing"
    assert dict(by_id["point"].params) == {"target": "user", "mode": "RIGHT_HAND"}
    assert by_id["look"].type == "gaze" and by_id["look"].param("influence") == "HEAD"
    # the draft's own sync set: a gaze has the seven sync points
    assert by_id["look"].syncs == (
        "start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end"
    )  # fmt: skip


def test_the_draft_document_round_trips_losslessly() -> None:
    data = DRAFT.read_bytes()
    assert canonical(serialise(parse_bml(data).block)) == canonical(data)


def test_the_draft_document_schedules_with_its_ties() -> None:
    plan = schedule_block(parse_bml(DRAFT.read_bytes()).block, registry=EngineRegistry.standard())
    assert plan.warnings == () and plan.dropped == frozenset()
    assert plan.time_of("nod", "stroke") == pytest.approx(plan.time_of("look", "stroke"), abs=1e-6)
    assert plan.time_of("point", "stroke") == pytest.approx(plan.time_of("nod", "stroke"), abs=1e-6)
    nod_end = plan.time_of("nod", "end")
    assert nod_end is not None
    assert plan.time_of("shake", "start") == pytest.approx(nod_end + 0.2, abs=1e-6)


def test_draft_behaviours_are_predicted_as_valid_bml_1_0() -> None:
    session = Session()
    session.receive_bml(DRAFT.read_text(), now=0.0)
    [fb] = [f for f in session.take_feedback() if f.kind == "prediction"]
    parsed = parse_feedback(fb.xml)
    assert isinstance(parsed, PredictionFeedback)
    elements = {b.behaviour.id: b.behaviour.local_name for b in parsed.behaviours}
    assert elements == {"look": "gaze", "nod": "head", "shake": "head", "point": "pointing"}


@pytest.mark.parametrize("rotation", ["NOD", "SHAKE", "TILT"])
def test_every_draft_rotation_is_a_head_lexeme(rotation: str) -> None:
    result = parse_bml(draft(f'<head id="h" action="ROTATION" rotation="{rotation}"/>'))
    assert result.warnings == () and result.block.behaviours[0].lexeme == rotation


@pytest.mark.parametrize(
    "body, problem",
    [
        ('<head id="h" action="ORIENTATION"/>', "action='ORIENTATION' is not supported"),
        ('<head id="h"/>', "needs type, or action"),
        ('<gesture id="g" type="POINT"/>', "needs a target"),
        ('<gaze id="z" target="camera" modality="ELBOW"/>', "modality='ELBOW' is not one of"),
    ],
)
def test_draft_behaviours_that_cannot_be_mapped_say_why(body: str, problem: str) -> None:
    [warning] = parse_bml(draft(body)).warnings
    assert str(warning.type) == "CANNOT_CREATE_BEHAVIOR" and problem in warning.message


def test_the_older_draft_spelling_still_reads() -> None:
    result = parse_bml((EXAMPLES / "13_draft_dialect.xml").read_bytes())
    assert result.warnings == ()
    assert {b.type for b in result.block.behaviours} == {"faceFacs", "head"}


@pytest.mark.parametrize(
    "document",
    [
        '<bml id="b"><face id="f"/></bml>',  # no namespace: read as the draft
        '<bml xmlns="http://www.mindmakers.org/projects/BML" id="b"><face id="f"/></bml>',
    ],
)
def test_a_draft_face_without_type_is_refused_with_a_warning(document: str) -> None:
    # found by the block-lifecycle property test: a KeyError escaped the parser
    [warning] = parse_bml(document).warnings
    assert str(warning.type) == "CANNOT_CREATE_BEHAVIOR" and "'type'" in warning.message
