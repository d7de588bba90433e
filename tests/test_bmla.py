"""AsapRealizer's BMLA through the service: preplan and activate, onStart,
appendAfter, bmla:interrupt of blocks and of single behaviours, parameter
value changes of running behaviours, and their feedback.

The examples (examples/bml/16..19) are submitted to the service's core
(:class:`realizer.service.stage.Stage` with real sessions, real parser,
scheduler and face engine) and played with explicit times; every feedback
message is read back by the strict feedback parser.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.bml_parser import BML_NS, BMLA_NS, canonical, parse_bml, serialise
from realizer.bml_parser.feedback import (
    BlockProgress,
    FeedbackMessage,
    PredictionFeedback,
    SyncPointProgress,
    parse_feedback,
)
from realizer.engines import EngineRegistry
from realizer.service.stage import BlockEvent, Stage, WireFeedback
from realizer.session import BlockState, Session
from tests.conftest import EXAMPLES

PREPLAN = (EXAMPLES / "16_bmla_preplan.xml").read_text()
ACTIVATE = (EXAMPLES / "17_bmla_activate.xml").read_text()
INTERRUPT = (EXAMPLES / "18_bmla_interrupt.xml").read_text()
ATTRIBUTES = (EXAMPLES / "19_bmla_block_attributes.xml").read_text()
#: FAP 12, raise_l_cornerlip: the smile's (Face and 2-D mesh animation in MPEG-4, Table 7)
CORNER = 11


class Played:
    """A stage with one real session, fed and ticked by hand."""

    def __init__(self) -> None:
        self.stage = Stage(lambda character: Session(character))
        self.feedback: list[tuple[float, FeedbackMessage]] = []
        self.states: list[tuple[str, str]] = []
        self.now = 0.0

    def take(self, messages: object) -> None:
        for m in messages:  # type: ignore[attr-defined]
            if isinstance(m, WireFeedback):
                self.feedback.append((m.time, parse_feedback(m.xml)))  # strictly
            elif isinstance(m, BlockEvent):
                self.states.append((m.block_id, m.state))

    def send(self, text: str) -> None:
        self.take(self.stage.submit_bml(text, self.now).messages)

    def until(self, end: float, step: float = 0.05) -> None:
        while self.now < end - 1e-9:
            self.now = round(self.now + step, 6)
            for tick in self.stage.tick(self.now):
                self.take(tick.messages)

    @property
    def session(self) -> Session:
        session = self.stage.characters["default"].session
        assert isinstance(session, Session)
        return session

    def blocks(self, block: str) -> list[BlockProgress]:
        return [m for _, m in self.feedback if isinstance(m, BlockProgress) and m.block_id == block]

    def progress(self, block: str) -> dict[str, float]:
        out = {}
        for _, m in self.feedback:
            if isinstance(m, BlockProgress) and m.block_id == block:
                out[m.sync] = m.global_time
            elif isinstance(m, SyncPointProgress) and m.block_id == block:
                out[f"{m.behaviour_id}:{m.sync}"] = m.global_time
        return out

    def corner(self, at: float) -> float:
        return float(self.session.frame(at).values[CORNER])


def test_the_bmla_examples_round_trip() -> None:
    for text in (PREPLAN, ACTIVATE, INTERRUPT, ATTRIBUTES):
        result = parse_bml(text)
        assert result.warnings == ()
        assert canonical(serialise(result.block)) == canonical(text)
    control = parse_bml(ATTRIBUTES).block.control
    assert control.interrupt == ("chatter",) and control.append_after == ("greeting",)
    assert control.on_start == ("later",) and parse_bml(PREPLAN).block.control.preplan


def test_a_preplanned_block_waits_and_an_activate_starts_it_with_a_new_prediction() -> None:
    played = Played()
    played.send(PREPLAN)
    [(_, first)] = [(t, m) for t, m in played.feedback if isinstance(m, PredictionFeedback)]
    assert isinstance(first, PredictionFeedback)
    assert played.session.state("later") is BlockState.PENDING
    played.until(1.0)
    assert played.progress("later") == {}  # nothing runs before it is activated
    played.send(ACTIVATE)  # at 1.0: activates "later" at 1.5
    played.until(6.0)
    later = played.progress("later")
    assert later["start"] == pytest.approx(1.5, abs=1e-6)
    assert later["smile:start"] == pytest.approx(1.5, abs=1e-6)
    predictions = [m for _, m in played.feedback if isinstance(m, PredictionFeedback)]
    starts = [b.global_start for p in predictions for b in p.blocks if b.block_id == "later"]
    assert starts[0] == pytest.approx(0.0) and starts[-1] == pytest.approx(1.5, abs=1e-6)
    trigger = played.progress("trigger")
    assert trigger["go:start"] == pytest.approx(1.5, abs=1e-6)  # the control's own feedback
    assert ("later", "done") in played.states and ("trigger", "done") in played.states


def test_the_prediction_of_a_preplanned_block_says_pending() -> None:
    session = Session()
    session.receive_bml(PREPLAN, now=0.0)
    [fb] = [f for f in session.take_feedback() if f.kind == "prediction"]
    assert 'bmla:status="PENDING"' in fb.xml and isinstance(
        parse_feedback(fb.xml), PredictionFeedback
    )


def test_a_parameter_value_change_fades_a_running_smile() -> None:
    played = Played()
    played.send(PREPLAN)
    played.send(ACTIVATE)  # at 0: later starts at 0.5, the fade runs from 1.5 to 2.5
    played.until(3.2)
    reference = Session()
    reference.receive_bml(PREPLAN.replace('bmla:preplan="true"', ""), now=0.5)
    for at in (1.0, 1.45):  # before the change: as without it
        assert played.corner(at) == pytest.approx(float(reference.frame(at).values[CORNER]))
    full = float(reference.frame(3.0).values[CORNER])
    assert full > 0
    # after the ramp a fifth of the smile; halfway (1 + 0.2) / 2 of it
    assert played.corner(3.0) == pytest.approx(0.2 * full, rel=1e-6)
    halfway = float(reference.frame(2.0).values[CORNER])
    assert played.corner(2.0) == pytest.approx(0.6 * halfway, rel=1e-6)


def test_bmla_interrupt_stops_one_behaviour_and_the_block_goes_on() -> None:
    played = Played()
    played.send(PREPLAN)
    played.send(ACTIVATE)  # later runs from 0.5
    played.until(0.7)
    played.send(INTERRUPT)  # at 0.7: the nod stops at 1.0
    played.until(6.0)
    later = played.progress("later")
    assert later["nod:end"] == pytest.approx(1.0, abs=1e-6)  # reported when it stopped
    nod_syncs = [k for k in later if k.startswith("nod:")]
    assert all(later[k] <= 1.0 + 1e-6 for k in nod_syncs)
    assert "smile:end" in later and later["end"] > 3.0  # the block ran to its end
    ends = [m for m in played.blocks("later") if m.sync == "end"]
    assert [e.status for e in ends] == ["DONE"]


def test_bmla_interrupt_without_include_stops_the_block() -> None:
    played = Played()
    played.send(PREPLAN)
    played.send(ACTIVATE)
    played.until(0.7)
    played.send(INTERRUPT.replace(' include="nod"', ""))
    played.until(3.0)
    ends = [m for m in played.blocks("later") if m.sync == "end"]
    assert [(e.status, round(e.global_time, 6)) for e in ends] == [("INTERRUPTED", 1.0)]


def test_block_attributes_interrupt_append_after_and_on_start() -> None:
    played = Played()
    played.send(
        f'<bml xmlns="{BML_NS}" id="chatter"><head id="h" lexeme="NOD" start="0" end="5"/></bml>'
    )
    played.send(
        f'<bml xmlns="{BML_NS}" id="greeting"><head id="h" lexeme="TILT" start="0" end="2"/></bml>'
    )
    played.send(PREPLAN)
    played.until(0.5)
    played.send(ATTRIBUTES)  # at 0.5: interrupts chatter, waits for greeting, then starts later
    played.until(8.0)
    assert ("chatter", "interrupted") in played.states
    greeting, reply, later = (played.progress(b) for b in ("greeting", "reply", "later"))
    assert reply["start"] == pytest.approx(greeting["end"], abs=1e-6)
    assert later["start"] == pytest.approx(reply["start"], abs=1e-6)  # onStart
    order = [f"{m.block_id}:{m.sync}" for _, m in played.feedback if isinstance(m, BlockProgress)]
    assert order.index("greeting:end") < order.index("reply:start") < order.index("later:start")


def test_unknown_bmla_targets_are_warned_about() -> None:
    session = Session()
    session.receive_bml(ATTRIBUTES, now=0.0)  # no chatter, greeting or later here
    texts = [f.xml for f in session.take_feedback() if f.kind == "warning"]
    assert any("chatter" in t and "NO_SUCH_TARGET" in t for t in texts)
    assert any("greeting" in t for t in texts)
    assert any("no preplanned block 'later'" in t for t in texts)  # at its start


def test_a_speech_volume_change_scales_its_audio() -> None:
    text = (
        f'<bml xmlns="{BML_NS}" xmlns:bmla="{BMLA_NS}" id="talk"><speech id="s1">'
        "<text>Hello there, this is a rather long sentence to hear.</text></speech>"
        '<bmla:parametervaluechange id="quiet" target="talk:s1" paramId="volume" start="0" '
        'end="0.01"><bmla:trajectory type="linear" initialValue="1" targetValue="0.25"/>'
        "</bmla:parametervaluechange></bml>"
    )
    # one registry: both sessions play the same synthesis (two syntheses of
    # one text by eSpeak NG differ by a few samples and up to 3 % at the peaks)
    registry = EngineRegistry.standard()
    loud, quiet = Session(registry=registry), Session(registry=registry)
    loud.receive_bml(text.replace('targetValue="0.25"', 'targetValue="1"'), now=0.0)
    quiet.receive_bml(text, now=0.0)
    loud.tick(0.05)
    quiet.tick(0.05)
    a, b = loud.audio(0.2, 1.0), quiet.audio(0.2, 1.0)
    if a is None:
        pytest.skip("no speech audio here (no TTS backend)")
    samples_a = np.asarray(getattr(a, "samples", a), dtype=float)
    samples_b = np.asarray(getattr(b, "samples", b), dtype=float)
    assert np.abs(samples_a).max() > 0
    assert np.abs(samples_b).max() == pytest.approx(0.25 * np.abs(samples_a).max(), rel=0.02)
