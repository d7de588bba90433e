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

from realizer.service._planner_warm import warm_up
from realizer.service.assets import session_factory
from realizer.service.errors import BadMessage
from realizer.service.hostile import HostileMessage, hostile_messages
from realizer.service.limits import DEFAULT_LIMITS
from realizer.service.messages import read_submitter_message, read_subscribe_message
from realizer.service.planner import PlannerPool, PlanningRecipe
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
    # What planning loads on first use (tables, scipy's sparse solver) is
    # loaded before any message is timed, as the service's planner
    # processes have it loaded when they start: otherwise the first big
    # block (with --quick, one run each) is timed with the imports (290 ms
    # for "250 behaviours with unknown attributes", 40 to 80 ms warm).
    warm_up()
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
    _through_a_planner_process(messages)


def _through_a_planner_process(messages: list[HostileMessage]) -> None:
    """The BML messages again through a planner process, as ``realizer serve``
    handles them: the round trips and pickles included."""
    pool = PlannerPool(1, PlanningRecipe(), DEFAULT_LIMITS.planning_milliseconds)
    worst, name = 0.0, ""
    try:
        for message in messages:
            if message.endpoint != "/bml" or message.name.startswith("empty block "):
                continue
            stage = Stage(session_factory(None), planner=pool)
            stage.submit_bml(
                '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="warm"/>',
                0.0,
                character="alice",
            )
            began = time.perf_counter()
            _process(stage, message.text, 0.1)
            spent = time.perf_counter() - began
            if spent > worst:
                worst, name = spent, message.name
    finally:
        pool.close()
    figure(f"the slowest through a planner process ({name})", worst * 1e3, "ms", goal=BUDGET * 1e3)


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
