"""Per character-frame cost: one session's ``tick`` and FAP ``frame``, as a service tick pays.

A character playing a block (a smile, a nod, raised brows and a gaze, all
moving the face) is ticked and asked for its frame at 60 fps, with no
finished blocks kept and with the session's whole allowance of them
(``SessionLimits.finished_kept``, 64), and an idle character (neutral face).
Goal: under 20 microseconds per character-frame, whatever the number of
finished blocks (so 800 characters a core at 60 fps). Timings are the CPU
time of the thread (:data:`_timing.CPU_CLOCK`), best of many windows of
:data:`WINDOW` frames: the cost of the work, which on a shared machine
wall time over longer windows mostly is not. Printed, never asserted.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import CPU_CLOCK, best_of, figure

from realizer.bml_parser import BML_NS
from realizer.session import Session

GOAL_US = 20.0
FPS = 60.0
#: Frames per timed window.
WINDOW = 15

PLAYING = (
    f'<bml xmlns="{BML_NS}" id="{{id}}" composition="MERGE">'
    '<faceLexeme id="smile" lexeme="RAISE_MOUTH_CORNERS" amount="0.8" start="0" end="30"/>'
    '<faceLexeme id="brows" lexeme="RAISE_BROWS" amount="0.5" start="1" end="29"/>'
    '<head id="nod" lexeme="NOD" start="2" end="28" repetition="20"/>'
    '<gaze id="look" target="camera" start="0" end="30"/>'
    "</bml>"
)
SHORT = f'<bml xmlns="{BML_NS}" id="{{id}}"><head id="n" lexeme="NOD" start="0" end="0.1"/></bml>'


def session_with(finished: int) -> tuple[Session, float]:
    """A session whose block plays from ``now`` on, after ``finished`` short blocks ended."""
    session = Session("bench", face=None)
    now = 0.0
    for i in range(finished):
        session.receive_bml(SHORT.format(id=f"old{i}"), now)
        now += 0.2
        session.tick(now)
    session.receive_bml(PLAYING.format(id="playing"), now)
    session.take_feedback()
    return session, now


def per_frame(session: Session, start: float, frames: int) -> float:
    """Seconds per tick + frame over ``frames`` consecutive frames from ``start``.

    The frames stay within 3 to 27 s after ``start``, while every behaviour of
    the block moves the face (the clock wraps there; a session ignores a
    time earlier than its last, so only the frames are asked again).
    """
    clock = {"n": 0}

    def step() -> None:
        clock["n"] += 1
        now = start + 3.0 + (clock["n"] % int(24 * FPS)) / FPS
        session.tick(now)
        session.take_feedback()
        session.frame(now)

    return best_of(step, repeats=max(5, frames // WINDOW), number=WINDOW, clock=CPU_CLOCK)


def run(quick: bool = False) -> None:
    frames = 300 if quick else 1500
    results = {}
    for finished in (0, 64):
        session, start = session_with(finished)
        kept = len([b for b in session._blocks if b.startswith("old")])
        seconds = per_frame(session, start, frames)
        results[finished] = seconds
        figure(
            f"tick + FAP frame, playing 4 behaviours, {kept} finished blocks kept",
            seconds * 1e6,
            "us",
            goal=GOAL_US,
        )
    idle = Session("idle", face=None)
    figure("tick + FAP frame, idle character", per_frame(idle, 0.0, frames) * 1e6, "us",
           goal=GOAL_US)  # fmt: skip
    figure(
        "growth with 64 kept finished blocks",
        results[64] / results[0],
        "x",
        goal=1.1,
        note="the cost must not grow with kept blocks",
    )
    print(f"characters per core at {FPS:g} fps: {1 / FPS / results[0]:,.0f}")


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
