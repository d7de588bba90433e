"""Regression tests of the stage's block lifecycle under hostile input (issue 10).

The real session, parser and scheduler, driven through the sans-I/O stage
with explicit times: no sockets, no clock.
"""

from __future__ import annotations

from typing import Any

import pytest
from lxml import etree

from realizer.service.limits import ServiceLimits
from realizer.service.stage import END_GRACE_SECONDS, BlockEvent, Stage, WireFeedback
from realizer.session import Session
from tests.service.doubles import FakeFeedback, FakePlan, FakeSession, smile_bml

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"


def real_stage(**limits: int) -> Stage:
    return Stage(lambda character: Session(character), ServiceLimits(**limits))


def events(messages: Any) -> list[tuple[str, str]]:
    return [(m.block_id, m.state) for m in messages if isinstance(m, BlockEvent)]


def kinds(messages: Any) -> list[str]:
    return [m.kind for m in messages if isinstance(m, WireFeedback)]


def block(block_id: str, body: str = "", extra: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" id="{block_id}"{extra}>{body}</bml>'


# -- defect 6: zero-length blocks end --------------------------------------------


def test_an_empty_block_is_accepted_and_done_in_the_same_answer() -> None:
    stage = real_stage()
    result = stage.submit_bml(block("e0"), 0.0)
    assert result.accepted
    assert events(result.messages) == [("e0", "accepted"), ("e0", "done")]
    assert not stage.characters["default"].open_blocks


def test_forty_empty_blocks_do_not_lock_the_character() -> None:
    stage = real_stage()
    for n in range(40):
        assert stage.submit_bml(block(f"e{n}"), 0.01 * n).accepted
    assert stage.submit_bml(smile_bml("after"), 1.0).accepted


def test_a_block_whose_behaviours_are_all_removed_ends_at_once() -> None:
    impossible = '<faceLexeme id="f" lexeme="RAISE_BROWS" start="2" end="1"/>'
    result = real_stage().submit_bml(block("z", impossible), 0.0)
    assert ("z", "accepted") in events(result.messages)
    assert events(result.messages)[-1] == ("z", "done")


# -- defect 7: failures after planning fail the block cleanly -------------------


@pytest.mark.parametrize(
    "behaviour",
    [
        '<faceLexeme id="a" lexeme="RAISE_BROWS" start="1e308"/>',
        '<faceLexeme id="a" lexeme="RAISE_BROWS" start="bml:start+1e308"/>',
        f'<faceLexeme id="a" lexeme="RAISE_BROWS" start="{"1" * 400}"/>',
    ],
)
def test_huge_times_are_refused_with_a_warning_and_no_prediction(behaviour: str) -> None:
    stage = real_stage()
    result = stage.submit_bml(block("big", behaviour), 0.0)
    assert not result.accepted
    assert kinds(result.messages) == ["warning"]
    assert events(result.messages) == [("big", "rejected")]
    assert stage.submit_bml(smile_bml("next"), 0.1).accepted


def test_an_append_block_ending_at_1e308_is_refused() -> None:
    stage = real_stage()
    stage.submit_bml(smile_bml("first"), 0.0)
    body = '<faceLexeme id="a" lexeme="RAISE_BROWS" end="1e308"/>'
    result = stage.submit_bml(block("late", body, ' composition="APPEND"'), 0.1)
    assert events(result.messages) == [("late", "rejected")]


def test_a_session_failing_after_its_prediction_gives_a_rejection_and_no_prediction() -> None:
    class FailsAfterPredicting(FakeSession):
        def receive_bml(self, text: Any, now: float, *, strict: bool = False) -> FakePlan:
            super().receive_bml(text, now)  # queues the prediction
            raise OverflowError("cannot convert float infinity to integer")

    stage = Stage(FailsAfterPredicting)
    result = stage.submit_bml(smile_bml("x"), 0.0)
    assert not result.accepted
    assert kinds(result.messages) == ["warning"]
    assert "internal error" in result.messages[0].xml  # no details reach the peer
    assert events(result.messages) == [("x", "rejected")]
    assert not stage.characters["default"].open_blocks


def test_a_realization_failure_in_the_session_fails_the_block_before_its_prediction(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    session = Session("s")

    def broken(*_: Any) -> None:
        raise ValueError("cannot realize")

    monkeypatch.setattr(type(session.registry), "realize", broken)
    stage = Stage(lambda _: session)
    result = stage.submit_bml(smile_bml("r"), 0.0)
    assert kinds(result.messages) == ["warning"]
    assert "could not be realized (ValueError)" in result.messages[0].xml
    assert events(result.messages) == [("r", "rejected")]


def test_a_block_its_session_never_ends_is_failed_after_its_deadline() -> None:
    class Forgetful(FakeSession):
        def tick(self, now: float) -> None:  # never reports an end
            pass

    stage = Stage(lambda c: Forgetful(c, duration=1.0))
    assert stage.submit_bml(smile_bml("lost"), 0.0).accepted
    assert events(m for t in stage.tick(1.0 + END_GRACE_SECONDS / 2) for m in t.messages) == []
    late = [m for t in stage.tick(1.0 + 2 * END_GRACE_SECONDS) for m in t.messages]
    assert events(late) == [("lost", "failed")]
    assert kinds(late) == ["warning"]


# -- defect 11: acceptance is this call's own outcome ---------------------------


def test_a_duplicate_arriving_as_the_old_block_starts_is_rejected() -> None:
    stage = real_stage()
    stage.submit_bml(smile_bml("first"), 0.0)  # runs 0 to 1 s
    appended = stage.submit_bml(
        block("dup", '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="1"/>',
              ' composition="APPEND"'),
        0.1,
    )  # fmt: skip
    assert appended.accepted
    # at 1.0 s the first ends and "dup" starts, in this very call
    again = stage.submit_bml(block("dup", '<faceLexeme id="g" lexeme="X" end="1"/>'), 1.0)
    assert not again.accepted
    assert ("dup", "accepted") not in events(again.messages)
    assert events(again.messages)[-1] == ("dup", "rejected")


# -- defect 5 (stage side): warnings per block are bounded ----------------------


def test_warnings_of_one_block_are_bounded_whatever_the_session_makes() -> None:
    class Chatty(FakeSession):
        def receive_bml(self, text: Any, now: float, *, strict: bool = False) -> FakePlan:
            plan = super().receive_bml(text, now)
            prediction = self.feedback.pop()
            for n in range(4_200):
                xml = f'<warningFeedback id="w{n}" type="PARSING_FAILURE">x</warningFeedback>'
                self.feedback.append(FakeFeedback("warning", "w", now, xml))
            self.feedback.append(prediction)
            return plan

    stage = Stage(Chatty, ServiceLimits(warnings_per_block=10))
    result = stage.submit_bml(smile_bml("w"), 0.0)
    warnings = [m for m in result.messages if isinstance(m, WireFeedback) and m.kind == "warning"]
    assert len(warnings) == 10
    assert "4191 more warnings" in warnings[-1].xml
    assert result.accepted


def test_a_block_with_thousands_of_unknown_attributes_gives_few_warnings() -> None:
    body = "".join(f'<faceLexeme id="f{n}" lexeme="X" odd="1" end="1"/>' for n in range(250))
    result = real_stage().submit_bml(block("many", body), 0.0)
    assert len([k for k in kinds(result.messages) if k == "warning"]) <= 100
    assert result.accepted


# -- defect 10: feedback is always well-formed XML -------------------------------


@pytest.mark.parametrize("block_id", ["\x00", "a\x01b", "\udc80", "\ufffe", "x\x1fy"])
def test_interrupting_an_id_xml_cannot_carry_gives_well_formed_feedback(block_id: str) -> None:
    stage = real_stage()
    stage.submit_bml(smile_bml("a"), 0.0)
    for message in stage.interrupt("default", block_id, 0.1):
        if isinstance(message, WireFeedback):
            etree.fromstring(message.xml.encode("utf-8"))
    for message in stage.interrupt("no\x00such", block_id, 0.1):
        if isinstance(message, WireFeedback):
            element = etree.fromstring(message.xml.encode("utf-8"))
            assert "\ufffd" in element.get("id", "") or "\ufffd" in (element.text or "")
