"""Helpers shared by the benchmarks: best-of timing and figures a machine can compare.

Every benchmark area reports its headline figures through :func:`figure`:
it prints the figure and, when the figure has a goal, the goal and the ratio
of the figure to it with "met" or "not met"; and it records the figure so
that ``realizer bench --json FILE`` writes every area's figures as JSON
(see ``benchmarks/README.md`` for the format). Free-form tables may still be
printed; only what goes through :func:`figure` (or :func:`skipped`) reaches
the JSON.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

#: The figures recorded since the last :func:`take_figures`, in order.
_FIGURES: list[dict[str, Any]] = []
#: Parts of an area that could not be measured here, with the reason.
_SKIPPED: list[dict[str, str]] = []


def best_of(
    function: Callable[[], object],
    *,
    repeats: int = 5,
    number: int = 1,
    clock: Callable[[], float] = time.perf_counter,
) -> float:
    """The best time of ``number`` calls, over ``repeats`` tries, in seconds per call.

    ``clock`` is wall time by default; :data:`CPU_CLOCK` measures the CPU
    time of the calling thread instead, which leaves out the time the
    operating system gave other processes (on a shared machine, a window
    of a few milliseconds is often cut by them), so what it measures is the
    cost of the work itself.
    """
    best = float("inf")
    for _ in range(repeats):
        start = clock()
        for _ in range(number):
            function()
        best = min(best, (clock() - start) / number)
    return best


#: The CPU time of the calling thread (seconds), for :func:`best_of`.
CPU_CLOCK: Callable[[], float] = time.thread_time


def _fmt(value: float) -> str:
    if not math.isfinite(value):
        return str(value)
    magnitude = abs(value)
    if magnitude >= 100:
        return f"{value:,.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    if magnitude >= 1:
        return f"{value:.2f}"
    return f"{value:.3g}"


def _finite(value: float) -> float | None:
    """JSON has no NaN or infinity: an unmeasurable figure is written as null."""
    return value if math.isfinite(value) else None


def figure(
    name: str,
    value: float,
    unit: str,
    *,
    goal: float | None = None,
    higher_is_better: bool = False,
    note: str = "",
    quiet: bool = False,
) -> dict[str, Any]:
    """Print (unless ``quiet``) and record one figure; return its record.

    ``goal`` is the bound the figure must stay under (or over, with
    ``higher_is_better``); the ratio printed and recorded is always
    ``value / goal``, so a ratio <= 1 meets a lower-is-better goal and a
    ratio >= 1 a higher-is-better one.
    """
    value = float(value)
    record: dict[str, Any] = {"name": name, "value": _finite(value), "unit": unit}
    line = f"{name}: {_fmt(value)} {unit}"
    if goal is not None:
        ratio = value / goal if goal else float("inf")
        met = value >= goal if higher_is_better else value <= goal
        record.update(
            goal=float(goal),
            higher_is_better=higher_is_better,
            ratio=_finite(ratio),
            met=bool(met),
        )
        bound = ">=" if higher_is_better else "<="
        verdict = "met" if met else "NOT met"
        line += f"  [goal {bound} {_fmt(goal)} {unit}, ratio {ratio:.3f}: {verdict}]"
    if note:
        record["note"] = note
        line += f"  ({note})"
    _FIGURES.append(record)
    if not quiet:
        print(line)
    return record


def skipped(name: str, reason: str) -> None:
    """Print and record that ``name`` was not measured, and why."""
    _SKIPPED.append({"name": name, "reason": reason})
    print(f"{name}: skipped ({reason})")


def take_figures() -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The figures and skips recorded so far, clearing both lists."""
    figures, skips = list(_FIGURES), list(_SKIPPED)
    _FIGURES.clear()
    _SKIPPED.clear()
    return figures, skips
