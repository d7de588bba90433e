"""Driving the service's stage offline, frame by frame, for ``realizer render``.

The same :class:`~realizer.service.stage.Stage` and sessions as the server
(the data flow of docs/architecture.md: frames go to viewers or to the
offscreen renderer), with the clock replaced
by a loop over frame times n / fps: no asyncio, no sockets, and a video
that shows exactly what a viewer at that rate would have seen.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from realizer.service.stage import BlockEvent, Stage, WireFeedback

_GLOBAL_END = re.compile(r"globalEnd\s*=\s*[\"']([-+0-9.eE]+)[\"']")


@dataclass(frozen=True, slots=True)
class OfflineFrame:
    """Frame ``number`` at ``time`` seconds, with the feedback of that tick."""

    number: int
    time: float
    frame: Any  # FapFrame
    feedback: tuple[WireFeedback, ...]


@dataclass(frozen=True, slots=True)
class OfflineRun:
    """A block handed to a stage at time 0: its frames, lazily."""

    block_id: str
    accepted: bool
    predicted_end: float | None  # seconds, from the prediction feedback
    first_feedback: tuple[WireFeedback, ...]
    frames: Iterator[OfflineFrame]
    #: the character the block went to (for its session's speech audio)
    character: str = ""


def predicted_end(feedback: tuple[WireFeedback, ...] | list[WireFeedback]) -> float | None:
    """The latest ``globalEnd`` any prediction feedback announces, seconds."""
    ends = [
        float(match.group(1))
        for fb in feedback
        if fb.kind == "prediction"
        for match in _GLOBAL_END.finditer(fb.xml)
    ]
    finite = [end for end in ends if math.isfinite(end)]
    return max(finite) if finite else None


def run_offline(
    stage: Stage,
    text: str,
    fps: float,
    *,
    character: str | None = None,
    tail: float = 0.5,
    max_duration: float = 120.0,
) -> OfflineRun:
    """Submit ``text`` at time 0 and iterate frames until ``tail`` seconds
    after the block's end (or ``max_duration`` seconds)."""
    result = stage.submit_bml(text, 0.0, character=character)
    first = tuple(m for m in result.messages if isinstance(m, WireFeedback))
    end = predicted_end(first)

    def frames() -> Iterator[OfflineFrame]:
        stop_at = max_duration
        number = 0
        while number / fps <= stop_at:
            now = number / fps
            ticks = [t for t in stage.tick(now) if t.character == result.character]
            if not ticks:
                return
            tick = ticks[0]
            for message in tick.messages:
                if isinstance(message, BlockEvent) and message.block_id == result.block_id:
                    stop_at = min(stop_at, message.time + tail)
            feedback = tuple(m for m in tick.messages if isinstance(m, WireFeedback))
            yield OfflineFrame(number, tick.time, tick.frame, feedback)
            number += 1

    return OfflineRun(
        result.block_id,
        result.accepted,
        end,
        first,
        frames() if result.accepted else iter(()),
        result.character,
    )
