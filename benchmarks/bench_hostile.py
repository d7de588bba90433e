"""Processing time of each hostile message against the 50 ms budget.

Feeds every message of :mod:`realizer.service.hostile` (the inputs of the
service's hostile-input audit) to a stage of real sessions, as the
service's planner threads do, and prints the best time of each with its
ratio to the budget: three frame periods at 60 fps, the longest gap a viewer
may see. Messages for the viewer endpoint are timed through the reader the
viewer handler uses. A message that costs more than the budget does not
stall the clock (it is processed off the event loop), but it delays its own
character and the next message of its own connection by that much.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import contextlib

from _timing import figure

from realizer.service.errors import BadMessage
from realizer.service.hostile import hostile_messages
from realizer.service.messages import read_submitter_message, read_subscribe_message
from realizer.service.stage import Stage
from realizer.session import Session

#: Seconds: three frame periods at 60 fps.
BUDGET = 0.050


def _process(stage: Stage, text: str, now: float) -> None:
    try:
        request = read_submitter_message(text)
    except BadMessage:
        return
    if request["type"] == "bml":
        stage.submit_bml(request["bml"], now, character=request.get("character"))
    else:
        stage.interrupt(request.get("character", "alice"), request["block"], now)


def run(quick: bool = False) -> None:
    repeats = 1 if quick else 3
    messages = hostile_messages("alice")
    seen: set[str] = set()
    worst = 0.0
    for message in messages:
        if message.name.startswith("empty block "):
            continue  # 39 copies of "an empty block"
        best = float("inf")
        for _ in range(repeats):
            stage = Stage(lambda character: Session(character))
            stage.submit_bml(
                '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="warm"/>',
                0.0,
                character="alice",
            )
            began = time.perf_counter()
            if message.endpoint == "/bml":
                _process(stage, message.text, 0.1)
            else:
                with contextlib.suppress(BadMessage):
                    read_subscribe_message(message.text)
            best = min(best, time.perf_counter() - began)
        name = message.name if message.name not in seen else f"{message.name} (again)"
        seen.add(message.name)
        worst = max(worst, best)
        figure(f"defect {message.defect}: {name}", best * 1e3, "ms", goal=BUDGET * 1e3)
    figure("the slowest hostile message", worst * 1e3, "ms", goal=BUDGET * 1e3)


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
