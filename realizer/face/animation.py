"""The ``Animation`` contract: what an engine makes of one scheduled behaviour.

It lives in the face layer, below the engines and beside the mixer
(:mod:`realizer.face.tracks`) that combines animations into one FAP frame,
so that engines (above) and tracks (here) both depend on it without a loop
(docs/architecture.md). Values are MPEG-4 FAPs (Tekalp and Ostermann 2000,
section 2.1) in FAPU-scaled units.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt


class Animation(Protocol):
    """A FAP animation between ``start`` and ``end`` (global seconds).

    ``evaluate(now)`` gives ``(values, weights)``: two ``(68,)`` float64
    vectors, FAP *n* at index *n - 1*; weight 0 means the FAP is not set.
    """

    @property
    def start(self) -> float: ...
    @property
    def end(self) -> float: ...
    @property
    def priority(self) -> int: ...
    def evaluate(self, now: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


FloatArray = npt.NDArray[np.float64]


class DerivedAnimation:
    """An animation made from another, ``base``: ``start``, ``end``,
    ``priority``, ``blend`` and ``evaluate`` are the base's unless a subclass
    (a frozen, slotted dataclass with a ``base`` field) changes one.

    What the mixer's wrappers share: an interrupted animation
    (:class:`realizer.face.tracks.InterruptedAnimation`), one whose values a
    BMLA parameter change scales or one shown from a later moment
    (:mod:`realizer.control`).
    """

    __slots__ = ()
    base: Animation

    @property
    def start(self) -> float:
        return self.base.start

    @property
    def end(self) -> float:
        return self.base.end

    @property
    def priority(self) -> int:
        return self.base.priority

    @property
    def blend(self) -> str:
        return str(getattr(self.base, "blend", "add"))

    def evaluate(self, now: float) -> tuple[FloatArray, FloatArray]:
        return self.base.evaluate(now)
