"""Test doubles for unit tests of the service shell only.

The end-to-end tests (test_end_to_end.py) use the real Session, parser and
face; these doubles let the shell's own logic (routing, limits, mailboxes,
encoding) be checked without depending on the scheduler's timings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realizer.bml_parser import ParseResult, parse_bml
from realizer.face.frame import FapFrame


@dataclass(frozen=True, slots=True)
class FakeFeedback:
    kind: str
    block_id: str
    time: float
    xml: str


@dataclass(frozen=True, slots=True)
class FakePlan:
    """What a session returns for an accepted block: its span, seconds."""

    start: float
    end: float


class FakeSession:
    """Each accepted block runs for ``duration`` seconds from ``now`` and sets
    FAP 12 (raise_l_cornerlip) to 100 while it runs."""

    def __init__(self, character_id: str, duration: float = 1.0) -> None:
        self.character_id = character_id
        self.duration = duration
        self.calls: list[tuple[str, float]] = []
        self.running: dict[str, tuple[float, float]] = {}
        self.started: set[str] = set()
        self.feedback: list[FakeFeedback] = []

    def receive_bml(self, text: str | ParseResult, now: float, *, strict: bool = False) -> FakePlan:
        self.calls.append(("receive_bml", now))
        block = (text if isinstance(text, ParseResult) else parse_bml(text)).block
        self.running[block.id] = (now, now + self.duration)
        self.feedback.append(
            FakeFeedback("prediction", block.id, now, f'<predictionFeedback id="{block.id}"/>')
        )
        return FakePlan(now, now + self.duration)

    def interrupt(self, block_id: str, now: float) -> None:
        self.calls.append(("interrupt", now))
        if block_id in self.running:
            start, _ = self.running[block_id]
            self.running[block_id] = (start, now)

    def tick(self, now: float) -> None:
        self.calls.append(("tick", now))
        for block_id, (start, end) in list(self.running.items()):
            if now >= start and block_id not in self.started:
                self.started.add(block_id)
                xml = f'<blockProgress id="{block_id}:start" globalTime="{start}"/>'
                self.feedback.append(FakeFeedback("blockProgress", block_id, start, xml))
            if now >= end:
                del self.running[block_id]
                xml = f'<blockProgress id="{block_id}:end" globalTime="{end}"/>'
                self.feedback.append(FakeFeedback("blockProgress", block_id, end, xml))

    def take_feedback(self) -> list[FakeFeedback]:
        taken, self.feedback = self.feedback, []
        return taken

    def frame(self, now: float) -> FapFrame:
        active = any(start <= now < end for start, end in self.running.values())
        return FapFrame.from_mapping({12: 100.0} if active else {}, time=now)


def smile_bml(block_id: str = "bml1", character: str | None = None, behaviours: int = 1) -> str:
    who = f' characterId="{character}"' if character else ""
    body = "".join(
        f'<faceLexeme id="f{i}" lexeme="RAISE_MOUTH_CORNERS" start="0" end="1"/>'
        for i in range(behaviours)
    )
    return (
        f'<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="{block_id}"{who}>{body}</bml>'
    )


class FakeFace:
    """Four vertices; deform moves vertex 0 up by FAP 12 x 1e-5 m."""

    def __init__(self) -> None:
        self.vertices = np.array(
            [[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.01]], dtype=np.float32
        )
        self.faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)


def fake_deform(face: FakeFace, vector: np.ndarray) -> np.ndarray:
    out = face.vertices.astype(np.float64).copy()
    out[0, 1] += vector[11] * 1e-5
    return out
