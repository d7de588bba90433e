"""Engines and their registry: a timing model for every behaviour type, and the plug-in hook."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pytest

from realizer.bml_parser import BML_NS, EXT_NS, REALIZER_NS, Behaviour, parse_bml
from realizer.engines import DefaultEngine, EngineRegistry
from realizer.engines.speech import SpeechEngine
from realizer.scheduler.plan import schedule_block
from realizer.scheduler.timing import Phase, TimingModel
from realizer.session import Session

#: One of every BML 1.0 core behaviour, faceFacs (a BML 1.0 core extension)
#: and this project's face extensions. (BML 1.0 has no ``<face>``: the
#: draft's ``<face>`` becomes faceLexeme or faceFacs in the parser.)
EVERY_TYPE = f"""<bml xmlns="{BML_NS}" xmlns:ext="{EXT_NS}" xmlns:rf="{REALIZER_NS}" id="all">
  <gesture id="gesture1" lexeme="BEAT"/>
  <pointing id="pointing1" target="door"/>
  <posture id="posture1"><stance type="STANDING"/></posture>
  <postureShift id="postureShift1"><stance type="SITTING"/></postureShift>
  <locomotion id="locomotion1" target="door"/>
  <gaze id="gaze1" target="LEFT" influence="EYES"/>
  <gazeShift id="gazeShift1" target="RIGHT" influence="HEAD"/>
  <head id="head1" lexeme="NOD" repetition="3"/>
  <headDirectionShift id="headDirectionShift1" target="LEFT"/>
  <faceLexeme id="faceLexeme1" lexeme="RAISE_BROWS"/>
  <ext:faceFacs id="faceFacs1" au="12"/>
  <faceShift id="faceShift1" lexeme="RAISE_BROWS"/>
  <wait id="wait1"/>
  <speech id="speech1"><text>Hello <sync id="m"/>world.</text></speech>
  <rf:fap id="fap1" values="3=400"/>
  <rf:emotion id="emotion1" word="afraid"/>
  <rf:viseme id="viseme1" viseme1="10"/>
  <rf:expression id="expression1" expression1="joy" intensity1="50"/>
</bml>"""

FACE_SYNCS = ("start", "attackPeak", "relax", "end")
STROKE_SYNCS = ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end")
SHIFT_SYNCS = ("start", "end")


def behaviours() -> dict[str, Behaviour]:
    return {b.id: b for b in parse_bml(EVERY_TYPE).block.behaviours}


@pytest.mark.parametrize("behaviour_id", sorted(behaviours()))
def test_every_behaviour_type_gets_a_timing_model(behaviour_id: str) -> None:
    behaviour = behaviours()[behaviour_id]
    model = EngineRegistry.standard().plan(behaviour)
    assert model.syncs == behaviour.syncs
    assert len(model.phases) == len(model.syncs) - 1
    assert model.preferred_duration > 0
    assert all(p.minimum <= p.preferred <= p.maximum for p in model.phases)


def test_canonical_sync_points_by_type() -> None:
    found = behaviours()
    for name in ("faceLexeme1", "faceFacs1", "emotion1"):
        assert found[name].syncs == FACE_SYNCS, name
    for name in ("gesture1", "pointing1"):
        assert found[name].syncs == STROKE_SYNCS, name
    for name in ("gazeShift1", "postureShift1", "wait1"):
        assert found[name].syncs == SHIFT_SYNCS, name
    # a head with repetition="3": strokes 1..3 between strokeStart and strokeEnd
    assert found["head1"].syncs == (
        "start", "ready", "strokeStart", "stroke", "stroke:2", "stroke:3", "strokeEnd",
        "relax", "end",
    )  # fmt: skip
    assert found["speech1"].syncs == ("start", "m", "end")


def test_a_block_of_every_type_schedules_without_warnings() -> None:
    plan = schedule_block(parse_bml(EVERY_TYPE).block, registry=EngineRegistry.standard())
    assert plan.warnings == ()
    assert {b.id for b in plan.behaviours} == set(behaviours())
    for scheduled in plan.behaviours:  # unconstrained: each at its preferred timing
        model = plan.models[scheduled.id]
        offsets = model.preferred_offsets()
        start = scheduled.times["start"]
        assert start == pytest.approx(0.0, abs=1e-9)
        for sync, offset in offsets.items():
            assert scheduled.times[sync] - start == pytest.approx(offset, abs=1e-9)


def test_the_speech_engine_stretches_speech_reluctantly_and_never_squeezes_it() -> None:
    speech = behaviours()["speech1"]
    gesture = behaviours()["gesture1"]
    engine = SpeechEngine.default()
    assert engine.backend is not None, engine.unavailable
    speech_weight = min(p.weight for p in engine.plan(speech).phases)
    gesture_weight = max(p.weight for p in DefaultEngine().plan(gesture).phases)
    assert speech_weight > gesture_weight
    for phase in engine.plan(speech).phases:
        assert phase.minimum == pytest.approx(phase.preferred)
        assert phase.maximum == pytest.approx(phase.preferred + engine.limits.max_pause)


@dataclass(frozen=True, slots=True)
class Glow:
    """A test animation: FAP 3 at 100 FAPU-scaled units while it runs."""

    start: float
    end: float
    priority: int = 5

    def evaluate(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        values = np.zeros(68)
        weights = np.zeros(68)
        values[2], weights[2] = 100.0, 1.0
        return values, weights


@dataclass(slots=True)
class GestureEngine:
    """A custom engine for gestures: its own timing, and an animation."""

    realized: list[tuple[str, dict[str, float]]]

    def handles(self, behaviour: Behaviour) -> bool:
        return behaviour.type == "gesture"

    def plan(self, behaviour: Behaviour) -> TimingModel:
        return TimingModel(behaviour.syncs, tuple(Phase(1.0) for _ in behaviour.syncs[1:]))

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> Glow:
        self.realized.append((behaviour.id, dict(times)))
        return Glow(times["start"], times["end"])


def test_an_engine_in_the_registry_plans_and_animates_its_behaviours() -> None:
    engine = GestureEngine([])
    registry = EngineRegistry.standard()
    registry.engines.insert(0, engine)
    session = Session(registry=registry)
    plan = session.receive_bml(
        f'<bml xmlns="{BML_NS}" id="b1"><gesture id="g1" lexeme="BEAT"/></bml>', now=10.0
    )
    assert plan is not None
    # its timing model: six phases of 1 s
    assert plan.time_of("g1", "end") == pytest.approx(16.0)
    [(behaviour_id, times)] = engine.realized
    assert behaviour_id == "g1" and times["start"] == pytest.approx(10.0)
    during, after = session.frame(12.0), session.frame(17.0)
    assert during.mask[2] and during.values[2] == pytest.approx(100.0)
    assert not after.mask.any()
