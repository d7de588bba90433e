"""The cluster's own timings, for ``/health`` and ``realizer bench cluster``.

Each worker and gateway keeps the recent durations of its own steps (a
request's way through the gateway and the owner, a frame's way from its
due time to the NATS client and on to the last viewer at a gateway), so the
cost the cluster adds over ``realizer serve`` is measured where it is
spent, not only inferred from what the clients see (docs/cluster.md).
"""

from __future__ import annotations

from collections import deque

#: How many recent values each figure keeps (a minute of frames at 60 fps).
RECENT = 3600


class Durations:
    """The recent durations of one step, in seconds: p50, p99, max, count."""

    __slots__ = ("count", "recent")

    def __init__(self, size: int = RECENT) -> None:
        self.recent: deque[float] = deque(maxlen=size)
        self.count = 0

    def add(self, seconds: float) -> None:
        self.recent.append(seconds)
        self.count += 1

    def summary(self) -> dict[str, float | int]:
        """``{"count", "p50_seconds", "p99_seconds", "max_seconds"}`` of the
        recent values (zeros when there are none)."""
        ordered = sorted(self.recent)

        def share(q: float) -> float:
            return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else 0.0

        return {
            "count": self.count,
            "p50_seconds": share(0.5),
            "p99_seconds": share(0.99),
            "max_seconds": ordered[-1] if ordered else 0.0,
        }


def summaries(durations: dict[str, Durations]) -> dict[str, dict[str, float | int]]:
    return {name: d.summary() for name, d in durations.items()}


__all__ = ["RECENT", "Durations", "summaries"]
