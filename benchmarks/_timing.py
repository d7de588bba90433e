"""Small timing helpers shared by the benchmarks (best of several repeats)."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_of(function: Callable[[], object], *, repeats: int = 5, number: int = 1) -> float:
    """The best wall time of ``number`` calls, over ``repeats`` tries, in seconds per call."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            function()
        best = min(best, (time.perf_counter() - start) / number)
    return best
