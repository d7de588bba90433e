"""The frame clock keeps its cadence while a 256-behaviour block is submitted.

A real service (real sessions, the real face) with a real WebSocket viewer
and submitter: the block (the per-block limit, 256 behaviours tied to each
other) is parsed and planned off the event loop, so the viewer must keep
getting a message every tick (a frame or a ``same``) while the block is
parsed, planned and accepted: no gap over 25 ms (one frame period and a
half) is asserted. Timing is judged only when the machine is not
overloaded (load average at most the CPU count).

Two causes made the goal miss about one run in ten (29 to 31 ms), both
found with per-tick timestamps and the collector's callbacks:

* the character's lock, held by the planner thread to admit and commit the
  block (a few milliseconds), made the tick that met it skip the character:
  a gap of two frame periods. The clock now tries it again within the period
  (tests/service/test_fan_out_slices.py);
* a full garbage collection, started by the planner's allocations, walked
  this test process's heap (pytest and every module the suite imported) for
  25 to 100 ms with the interpreter lock held. ``realizer serve`` leaves its
  start-up heap out of later collections (``freeze_start_up_heap``); the
  test does the same, so it measures what a serving process does.
"""

from __future__ import annotations

import asyncio
import gc
import itertools
import json

import pytest
from websockets.asyncio.client import connect

from realizer.bml_parser import BML_NS
from realizer.service.server import freeze_start_up_heap
from tests.service.harness import judge_frame_gaps, running_service
from tests.service.test_end_to_end import real_assets, real_sessions

#: The largest gap allowed between two messages of the 60 fps stream: one
#: frame period and a half (the defects this guards against froze the
#: stream for 285 ms, the character's lock held through planning, 678 ms,
#: scipy imported on a planner thread, and 33 ms, a tick that met the
#: character's lock).
MAX_GAP_S = 0.025


def big_block(count: int = 256) -> str:
    body = []
    for i in range(count):
        previous = f"b{i - 1}:end" if i else "0"
        if i % 2:
            body.append(f'<head id="b{i}" lexeme="NOD" start="{previous}"/>')
        else:
            body.append(
                f'<faceLexeme id="b{i}" lexeme="RAISE_BROWS" amount="0.3" start="{previous}"/>'
            )
    return f'<bml xmlns="{BML_NS}" id="big">{"".join(body)}</bml>'


@pytest.mark.slow
def test_the_frame_clock_keeps_its_cadence_while_a_256_behaviour_block_is_submitted() -> None:
    async def scenario() -> tuple[list[float], float, float, str]:
        async with running_service(real_sessions(), real_assets()) as service:
            loop = asyncio.get_running_loop()
            base = f"ws://127.0.0.1:{service.port}"
            arrivals: list[float] = []
            async with (
                connect(f"{base}/view?character=Cad&fap=true", max_size=None) as viewer,
                connect(f"{base}/bml?format=json") as submitter,
            ):
                await viewer.recv()  # the mesh
                await submitter.recv()  # welcome

                async def watch() -> None:
                    async for _ in viewer:
                        arrivals.append(loop.time())

                watching = loop.create_task(watch())
                await asyncio.sleep(0.5)
                sent = loop.time()
                await submitter.send(json.dumps({"type": "bml", "bml": big_block(),
                                                 "character": "Cad"}))  # fmt: skip
                state = ""
                while state not in ("accepted", "rejected"):
                    message = json.loads(await asyncio.wait_for(submitter.recv(), 30))
                    if message["type"] == "block":
                        state = message["state"]
                accepted = loop.time()
                await asyncio.sleep(0.5)
                watching.cancel()
            return arrivals, sent, accepted, state

    real_assets(), real_sessions()("warm")  # the face and engines loaded, as realizer serve has
    freeze_start_up_heap()
    try:
        arrivals, sent, accepted, state = asyncio.run(scenario())
    finally:
        gc.unfreeze()  # the rest of the suite collects everything again
    assert state == "accepted"
    window = [t for t in arrivals if sent - 0.05 <= t <= accepted + 0.3]
    assert len(window) >= 10, "the viewer got (almost) nothing while the block was planned"
    largest = max(b - a for a, b in itertools.pairwise(window))
    print(f"largest frame gap while the block was submitted: {largest * 1e3:.1f} ms")
    judge_frame_gaps(window, MAX_GAP_S, "the frame stream")
