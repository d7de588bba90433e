"""Every feedback message the service writes is valid BML 1.0 feedback.

The whole conformance corpus and every example is performed through the
service's sans-I/O core (:class:`realizer.service.stage.Stage` with real
sessions), played to the end, and half of it interrupted midway; every
``WireFeedback`` is read back by the strict parser
:func:`realizer.bml_parser.feedback.parse_feedback`, and what it says is
checked against the session's own plan (the prediction's times are the
solved times; progress comes in the documented order).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from realizer.bml_parser import BML_NS, BMLA_NS
from realizer.bml_parser.feedback import (
    BlockProgress,
    FeedbackError,
    PredictionFeedback,
    SyncPointProgress,
    parse_feedback,
)
from realizer.feedback import block_progress, prediction
from realizer.service.stage import Stage, WireFeedback
from realizer.session import Session
from tests.conftest import EXAMPLES, conformance_files

DOCUMENTS = [*conformance_files(), *sorted(EXAMPLES.glob("*.xml"))]


def perform(path: Path, interrupt: bool) -> tuple[Stage, list[str]]:
    stage = Stage(lambda character: Session(character))
    sent = stage.submit_bml(path.read_text("utf-8"), 0.0)
    messages = [m.xml for m in sent.messages if isinstance(m, WireFeedback)]
    now = 0.0
    found = stage.characters.get(sent.character)
    while now < 120.0 and found is not None and (found.open_blocks or now < 1.0):
        now = round(now + 0.1, 6)
        if interrupt and now == 0.5:
            for block_id in list(found.open_blocks):
                messages += [
                    m.xml for m in stage.interrupt(sent.character, block_id, now)
                    if isinstance(m, WireFeedback)
                ]  # fmt: skip
        for tick in stage.tick(now):
            messages += [m.xml for m in tick.messages if isinstance(m, WireFeedback)]
    return stage, messages


@pytest.mark.parametrize("interrupt", [False, True], ids=["played", "interrupted"])
@pytest.mark.parametrize("path", DOCUMENTS, ids=lambda p: p.name)
def test_every_feedback_message_parses_strictly(path: Path, interrupt: bool) -> None:
    _, messages = perform(path, interrupt)
    assert messages, "the service always answers"
    parsed = [parse_feedback(xml) for xml in messages]
    ends = [p for p in parsed if isinstance(p, BlockProgress) and p.sync == "end"]
    starts = [p for p in parsed if isinstance(p, BlockProgress) and p.sync == "start"]
    # every block that started ends once; one revoked before it began
    # (BMLA's REVOKED) ends without a start
    started = [e for e in ends if e.status != "REVOKED"]
    assert len(started) == len(starts) and len({e.block_id for e in ends}) == len(ends)
    for end in ends:
        assert end.status in ({"INTERRUPTED", "REVOKED"} if interrupt else {"DONE"}) | {"DONE"}
    predicted = [p for p in parsed if isinstance(p, PredictionFeedback)]
    progress = {
        (p.behaviour_id, p.sync): p.global_time for p in parsed if isinstance(p, SyncPointProgress)
    }
    for feedback in predicted:
        for behaviour in feedback.behaviours:
            for sync, time in behaviour.times.items():
                if (behaviour.behaviour.id, sync) in progress:
                    assert progress[(behaviour.behaviour.id, sync)] == pytest.approx(time, abs=2e-6)


def test_the_corpus_is_there() -> None:
    if not conformance_files():
        pytest.skip("conformance corpus not found")
    assert len(conformance_files()) >= 50


def test_a_speech_prediction_keeps_its_text_and_markers_and_required_attributes() -> None:
    session = Session("Alice")
    session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b1"><speech id="s1"><text>Hello <sync id="m1"/>there'
        '</text></speech><gesture id="g1" lexeme="BEAT" stroke="s1:m1"/>'
        '<gaze id="z1" target="camera" start="0" end="1"/></bml>',
        now=0.0,
    )
    [fb] = [f for f in session.take_feedback() if f.kind == "prediction"]
    parsed = parse_feedback(fb.xml)
    assert isinstance(parsed, PredictionFeedback)
    by_id = {b.behaviour.id: b for b in parsed.behaviours}
    speech = by_id["s1"].behaviour
    assert speech.speech is not None and speech.speech.plain == "Hello there"
    assert speech.speech.sync_ids == ("m1",)
    assert list(by_id["s1"].times) == ["start", "m1", "end"]
    assert by_id["g1"].behaviour.lexeme == "BEAT"
    assert by_id["z1"].behaviour.param("target") == "camera"
    assert by_id["g1"].times["stroke"] == pytest.approx(by_id["s1"].times["m1"], abs=1e-6)


def test_a_draft_behaviour_is_predicted_as_its_bml_1_0_element() -> None:
    session = Session()
    session.receive_bml((EXAMPLES / "13_draft_dialect.xml").read_text(), now=0.0)
    [fb] = [f for f in session.take_feedback() if f.kind == "prediction"]
    parsed = parse_feedback(fb.xml)
    assert isinstance(parsed, PredictionFeedback)
    types = {b.behaviour.id: (b.behaviour.type, b.behaviour.dialect) for b in parsed.behaviours}
    assert types == {"f1": ("faceFacs", "ext"), "h1": ("head", "bml")}


@pytest.mark.parametrize(
    "xml, problem",
    [
        (f'<blockProgress xmlns="{BML_NS}" id="b1" globalTime="1"/>', "form"),
        (f'<blockProgress xmlns="{BML_NS}" id="b1:start"/>', "globalTime"),
        (f'<blockProgress xmlns="{BML_NS}" id="b1:end" globalTime="1" status="INTERRUPTED"/>',
         "status"),
        (f'<blockProgress xmlns="{BML_NS}" xmlns:bmla="{BMLA_NS}" id="b1:end" globalTime="1" '
         'bmla:status="BROKEN"/>', "BMLA"),
        (f'<syncPointProgress xmlns="{BML_NS}" id="b1:x:start" globalTime="1"/>', "'time'"),
        (f'<syncPointProgress xmlns="{BML_NS}" id="b1:x:start" time="a" globalTime="1"/>',
         "number"),
        (f'<warningFeedback xmlns="{BML_NS}" id="b1" type="OOPS">x</warningFeedback>', "type"),
        ('<blockProgress id="b1:start" globalTime="1"/>', "not a BML 1.0 feedback"),
        (f'<predictionFeedback xmlns="{BML_NS}"><bml id="b1"/></predictionFeedback>', "neither"),
        (f'<predictionFeedback xmlns="{BML_NS}"><head id="b1:h1" start="0" end="1"/>'
         "</predictionFeedback>", "lexeme"),
        (f'<predictionFeedback xmlns="{BML_NS}"><speech id="b1:s1" start="0" end="1">'
         '<sync id="m1"/></speech></predictionFeedback>', "sync"),
        (f'<predictionFeedback xmlns="{BML_NS}"><head id="b1:h1" lexeme="NOD" start="x:end"/>'
         "</predictionFeedback>", "not a time"),
    ],
)  # fmt: skip
def test_the_strict_parser_refuses_what_is_not_bml_1_0_feedback(xml: str, problem: str) -> None:
    with pytest.raises(FeedbackError) as caught:
        parse_feedback(xml)
    assert problem in caught.value.message


def test_the_old_feedback_shapes_are_refused() -> None:
    """The shapes of the issue: speech markers outside <text>, a head without lexeme."""
    old_speech = (
        f'<predictionFeedback xmlns="{BML_NS}"><bml id="b1" globalStart="0" globalEnd="1"/>'
        '<speech id="s1" start="0" end="1"><sync id="m1" globalTime="0.5"/></speech>'
        "</predictionFeedback>"
    )
    with pytest.raises(FeedbackError):
        parse_feedback(old_speech)
    good = block_progress("b1", "end", 1.0, "A", "INTERRUPTED")
    assert isinstance(parse_feedback(good.xml), BlockProgress)
    assert parse_feedback(prediction("b1", 0.0, 1.0, [], 0.0, None).xml)
