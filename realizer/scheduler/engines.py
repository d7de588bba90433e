"""Engines and the registry that maps behaviours to them.

Engines own timing knowledge (docs/architecture.md). Each engine says
which behaviours it handles, gives a :class:`~realizer.scheduler.timing.TimingModel`
for each (its sync points in canonical order, preferred durations, costs and
bounds) and, once the scheduler has solved the times, realizes the behaviour
as an :class:`Animation` (or nothing, for behaviours no body part shows).
The scheduler never special-cases a behaviour type.

:class:`DefaultEngine` gives plain models to every BML 1.0 behaviour type so
that gesture, locomotion and posture schedule and report feedback although no
body is drawn; speech timing comes from a :class:`~realizer.scheduler.speech.SpeechTiming`.
The face engine (realizer.face.engine) refines face, head and gaze.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from realizer.bml_parser import Behaviour
from realizer.scheduler.speech import RateSpeechTiming, SpeechTiming
from realizer.scheduler.timing import Phase, TimingModel


class Animation(Protocol):
    """What an engine makes of one scheduled behaviour (global seconds)."""

    @property
    def start(self) -> float: ...
    @property
    def end(self) -> float: ...
    @property
    def priority(self) -> int: ...
    def evaluate(self, now: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


class Engine(Protocol):
    def handles(self, behaviour: Behaviour) -> bool: ...
    def plan(self, behaviour: Behaviour) -> TimingModel: ...
    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> Any: ...


#: Preferred phase durations (seconds) of the default models, by sync set.
_GESTURE_PHASES = {
    ("start", "ready"): 0.3,
    ("ready", "strokeStart"): 0.15,
    ("strokeStart", "stroke"): 0.2,
    ("stroke", "strokeEnd"): 0.15,
    ("strokeEnd", "relax"): 0.3,
    ("relax", "end"): 0.3,
}
_FACE_PHASES = (0.3, 1.0, 0.3)  # attack, sustain, release
_HOLD_PHASES = (0.5, 1.5, 0.5)
_REPEAT = 0.5  # between repeated strokes


@lru_cache(maxsize=256)
def _plain_model(syncs: tuple[str, ...]) -> TimingModel:
    """The default model of a behaviour with these sync points (models are immutable)."""
    if len(syncs) == 2:
        return TimingModel(syncs, (Phase(1.0),))
    if syncs[1] == "attackPeak":
        return TimingModel(syncs, tuple(Phase(p) for p in _FACE_PHASES))
    if syncs[1] == "ready" and len(syncs) == 4:
        # gaze, posture, locomotion: the hold between ready and relax lasts
        # as long as it is asked to.
        weights = (1.0, 0.05, 1.0)
        return TimingModel(
            syncs, tuple(Phase(p, w) for p, w in zip(_HOLD_PHASES, weights, strict=True))
        )
    phases = []
    for before, after in itertools.pairwise(syncs):
        if after.startswith("stroke:"):
            preferred = _REPEAT
        else:
            preferred = _GESTURE_PHASES.get((before.partition(":")[0], after), 0.3)
        phases.append(Phase(preferred))
    return TimingModel(syncs, tuple(phases))


@dataclass(frozen=True, slots=True)
class DefaultEngine:
    """Plain timing models for every behaviour type; realizes nothing."""

    speech: SpeechTiming = field(default_factory=RateSpeechTiming)
    speech_weight: float = 10.0  # speech stretches reluctantly
    speech_squeeze: float = 0.6  # a phase may shrink to 60 % ...
    speech_stretch: float = 2.0  # ... or grow to 200 % of its natural length
    wait_weight: float = 1e-3  # <wait> takes whatever length it is given

    def handles(self, behaviour: Behaviour) -> bool:
        return True

    def plan(self, behaviour: Behaviour) -> TimingModel:
        if behaviour.type == "speech" and behaviour.speech is not None:
            return self._speech(behaviour)
        if behaviour.type == "wait":
            return TimingModel(behaviour.syncs, (Phase(1.0, weight=self.wait_weight),))
        return _plain_model(behaviour.syncs)

    def _speech(self, behaviour: Behaviour) -> TimingModel:
        assert behaviour.speech is not None
        plan = self.speech.plan(behaviour.speech)
        times = [0.0, *(plan.markers[name] for name in behaviour.syncs[1:-1]), plan.duration]
        phases = []
        for earlier, later in itertools.pairwise(times):
            length = later - earlier
            phases.append(
                Phase(
                    length,
                    weight=self.speech_weight,
                    minimum=length * self.speech_squeeze,
                    maximum=length * self.speech_stretch if length > 0 else 0.0,
                )
            )
        return TimingModel(behaviour.syncs, tuple(phases))

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> None:
        return None


@dataclass(slots=True)
class EngineRegistry:
    """Engines in priority order; the default engine answers for the rest."""

    engines: list[Engine] = field(default_factory=list)
    default: DefaultEngine = field(default_factory=DefaultEngine)

    @classmethod
    def standard(cls) -> EngineRegistry:
        """The default engine and, where importable, the face engine."""
        registry = cls()
        try:
            from realizer.face.engine import FaceEngine
        except ImportError:  # pragma: no cover - the face engine ships with the package
            return registry
        registry.engines.append(FaceEngine.default())
        return registry

    def engine_for(self, behaviour: Behaviour) -> Engine:
        for engine in self.engines:
            if engine.handles(behaviour):
                return engine
        return self.default

    def plan(self, behaviour: Behaviour) -> TimingModel:
        model = self.engine_for(behaviour).plan(behaviour)
        if model.syncs != behaviour.syncs:
            # The scheduler addresses sync points by the parser's names.
            model = _align(model, behaviour.syncs)
        return model

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> Any:
        return self.engine_for(behaviour).realize(behaviour, times)


def _align(model: TimingModel, syncs: tuple[str, ...]) -> TimingModel:
    """Re-express a model over ``syncs`` (phases spanning missing points merge)."""
    offsets = model.preferred_offsets()
    known = [s for s in syncs if s in offsets]
    phases = []
    for before, after in itertools.pairwise(syncs):
        if before in offsets and after in offsets:
            phases.append(Phase(max(0.0, offsets[after] - offsets[before])))
        else:
            phases.append(Phase(0.3 if known else 1.0))
    return TimingModel(syncs, tuple(phases))
