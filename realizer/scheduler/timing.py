"""Timing models: what an engine tells the scheduler about one behaviour.

Paul 2010, section 3.3.3: each behaviour has one preferred length per phase and
a cost that rises on both sides of it, quadratic so that the costs of
interlocked behaviours add up and their minimum is found in closed form:
``y = a (t1 - t0)^2 + b (t1 - t0) + c``. A :class:`Phase` stores the same
parabola as a preferred duration and a weight (``a = weight``,
``b = -2 weight preferred``, ``c = weight preferred^2``), plus hard bounds.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from realizer.errors import RealizerError


class TimingModelError(RealizerError):
    """A timing model that contradicts itself (e.g. minimum above maximum)."""


@dataclass(frozen=True, slots=True)
class Phase:
    """The stretch between two neighbouring sync points; seconds throughout."""

    preferred: float
    weight: float = 1.0
    minimum: float = 0.0
    maximum: float = math.inf

    def __post_init__(self) -> None:
        if not (self.weight > 0 and math.isfinite(self.weight)):
            raise TimingModelError(f"phase weight must be positive and finite, not {self.weight}")
        if not (0 <= self.minimum <= self.maximum):
            raise TimingModelError(
                f"phase bounds must satisfy 0 <= minimum <= maximum, not "
                f"{self.minimum}..{self.maximum}"
            )
        if not math.isfinite(self.preferred) or self.preferred < 0:
            raise TimingModelError(f"preferred duration must be >= 0, not {self.preferred}")

    @property
    def quadratic(self) -> tuple[float, float, float]:
        """``(a, b, c)`` of Paul 2010's ``y = a d^2 + b d + c``."""
        return (self.weight, -2 * self.weight * self.preferred, self.weight * self.preferred**2)

    def cost(self, duration: float) -> float:
        return self.weight * (duration - self.preferred) ** 2


@dataclass(frozen=True, slots=True)
class TimingModel:
    """A behaviour's sync points in canonical order and the phases between them."""

    syncs: tuple[str, ...]
    phases: tuple[Phase, ...]
    #: weight, preferred, minimum and maximum of each phase, one after the
    #: other: what the solver reads, made once per model rather than once
    #: per behaviour planned (engines hand out one model for many behaviours)
    table: tuple[float, ...] = field(init=False, repr=False, compare=False)
    #: each sync point's position in :attr:`syncs`
    positions: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.phases) != len(self.syncs) - 1:
            raise TimingModelError(
                f"{len(self.syncs)} sync points need {len(self.syncs) - 1} phases, "
                f"not {len(self.phases)}"
            )
        table = tuple(
            itertools.chain.from_iterable(
                (p.weight, p.preferred, p.minimum, p.maximum) for p in self.phases
            )
        )
        object.__setattr__(self, "table", table)
        object.__setattr__(self, "positions", {s: i for i, s in enumerate(self.syncs)})

    @property
    def preferred_duration(self) -> float:
        return sum(phase.preferred for phase in self.phases)

    def preferred_offsets(self) -> dict[str, float]:
        """Each sync point's preferred time after ``start``."""
        offsets = {self.syncs[0]: 0.0}
        total = 0.0
        for sync, phase in zip(self.syncs[1:], self.phases, strict=True):
            total += phase.preferred
            offsets[sync] = total
        return offsets
