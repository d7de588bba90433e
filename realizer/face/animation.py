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
