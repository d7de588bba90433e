"""The default engine: plain timing models for behaviours nothing draws.

Engines own timing knowledge (docs/architecture.md). :class:`DefaultEngine`
gives a model to every BML 1.0 behaviour type so that gesture, locomotion and
posture schedule and report feedback although no body is drawn (Paul 2010,
section 3.3.3: one preferred length per phase, quadratic costs).
It realizes nothing.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

from realizer.bml_parser import Behaviour
from realizer.scheduler.timing import Phase, TimingModel

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

    wait_weight: float = 1e-3  # <wait> takes whatever length it is given

    def handles(self, behaviour: Behaviour) -> bool:
        return True

    def plan(self, behaviour: Behaviour) -> TimingModel:
        if behaviour.type == "wait":
            return TimingModel(behaviour.syncs, (Phase(1.0, weight=self.wait_weight),))
        return _plain_model(behaviour.syncs)

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> None:
        return None
