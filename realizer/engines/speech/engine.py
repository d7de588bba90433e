"""The speech engine: a ``<speech>`` behaviour's timing model from its speech plan.

The markers of ``<text>`` (BML 1.0 ``<sync id>``) become the behaviour's sync
points between ``start`` and ``end``; each phase between neighbours prefers
the length the speech timing (a TTS, or the syllable estimate) gives it.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field

from realizer.bml_parser import Behaviour
from realizer.engines.speech.timing import RateSpeechTiming, SpeechTiming
from realizer.scheduler.timing import Phase, TimingModel


@dataclass(frozen=True, slots=True)
class SpeechEngine:
    """Plans ``<speech>``; realizes nothing yet (no lip sync)."""

    timing: SpeechTiming = field(default_factory=RateSpeechTiming)
    weight: float = 10.0  # speech stretches reluctantly
    squeeze: float = 0.6  # a phase may shrink to 60 % ...
    stretch: float = 2.0  # ... or grow to 200 % of its natural length

    def handles(self, behaviour: Behaviour) -> bool:
        return behaviour.type == "speech" and behaviour.speech is not None

    def plan(self, behaviour: Behaviour) -> TimingModel:
        assert behaviour.speech is not None
        plan = self.timing.plan(behaviour.speech)
        times = [0.0, *(plan.markers[name] for name in behaviour.syncs[1:-1]), plan.duration]
        phases = []
        for earlier, later in itertools.pairwise(times):
            length = later - earlier
            phases.append(
                Phase(
                    length,
                    weight=self.weight,
                    minimum=length * self.squeeze,
                    maximum=length * self.stretch if length > 0 else 0.0,
                )
            )
        return TimingModel(behaviour.syncs, tuple(phases))

    def realize(self, behaviour: Behaviour, times: Mapping[str, float]) -> None:
        return None
