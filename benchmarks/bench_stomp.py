"""Latency of the ActiveMQ (STOMP) bridge, on loopback only.

Starts a real ActiveMQ broker (Debian's, as the tests do:
tests/service/activemq.py) and the real service with its bridge
(realizer.service.stomp) in this process, then a STOMP client publishes
``--blocks`` small BML blocks on the BML topic, one at a time, and times,
for each, from the publish to the arrival on the feedback topic of

* its prediction (the broker twice, the bridge, the planner),
* its ``blockProgress`` start (which waits for the next clock tick too).

Also printed: how long the broker took to accept connections. Timings are
printed, never asserted (benchmarks/README.md).

    python benchmarks/bench_stomp.py [--blocks 100]     (or: realizer bench stomp)
"""

from __future__ import annotations

import argparse
import asyncio
import os
import queue
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the broker launcher of the tests

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


async def measure(blocks: int, broker_url: str, port: int) -> dict[str, list[float]]:
    import stomp

    from realizer.service.assets import face_assets, load_face, session_factory
    from realizer.service.server import RealizerService, ServiceConfig
    from realizer.service.stage import Stage
    from realizer.service.stomp import StompBridge, StompConfig

    face = load_face()
    service = RealizerService(
        ServiceConfig(host="127.0.0.1", port=0), Stage(session_factory(face)), face_assets(face)
    )
    await service.start()
    bridge = StompBridge(StompConfig(broker_url))
    await bridge.start(service)
    received: queue.Queue[tuple[float, str]] = queue.Queue()

    class Listener:
        def on_message(self, frame: Any) -> None:
            received.put((time.perf_counter(), frame.body))

    client = stomp.Connection12([("127.0.0.1", port)])
    client.set_listener("bench", Listener())
    client.connect(wait=True)
    client.subscribe(bridge.layout.feedback_topic, id="fb")
    while not bridge.connected:
        await asyncio.sleep(0.01)
    await asyncio.sleep(0.3)  # the feedback subscription settles
    times: dict[str, list[float]] = {"prediction": [], "start": []}
    try:
        for n in range(blocks):
            block = f"k{n}"
            text = (
                f'<bml xmlns="{BML_NS}" id="{block}" characterId="Kim">'
                '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="0.05"/></bml>'
            )
            sent = time.perf_counter()
            client.send(bridge.layout.bml_topic, text)
            wanted = {"prediction": "<predictionFeedback", "start": f'id="{block}:start"'}
            got: dict[str, float] = {}
            while len(got) < 2:
                at, body = await asyncio.to_thread(received.get, True, 10)
                if f'id="{block}' not in body and f'"{block}:' not in body:
                    continue
                for name, needle in wanted.items():
                    if name not in got and needle in body:
                        got[name] = at - sent
            for name, value in got.items():
                times[name].append(value)
            await asyncio.sleep(0.1)
    finally:
        client.disconnect()
        await service.shutdown()
        await bridge.stop()
    return times


def run(quick: bool = False, blocks: int | None = None) -> None:
    """Time the bridge (``realizer bench stomp``); 20 blocks quick, 100 otherwise."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _timing import figure, skipped

    try:  # the tests' broker launcher: in a checkout, not in the wheel
        from tests.service.activemq import missing, start_broker
    except ImportError:
        skipped(
            "stomp bridge, publish -> prediction p50",
            "no tests/service/activemq.py here (run from a checkout of the repository)",
        )
        return
    count = blocks or (20 if quick else 100)
    why = missing()
    if why:
        skipped("stomp bridge, publish -> prediction p50", why)
        return
    try:
        import stomp  # noqa: F401
    except ImportError:
        skipped("stomp bridge, publish -> prediction p50", "the stomp extra is not installed")
        return
    with tempfile.TemporaryDirectory() as folder:
        broker = start_broker(Path(folder))
        try:
            times = asyncio.run(measure(count, broker.url, broker.port))
        finally:
            broker.stop()
    print(
        f"{count} blocks, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores "
        "(the first block makes its character)"
    )
    figure("activemq start, until it accepts connections", broker.started_seconds, "s")
    for name, values in times.items():
        ms = [v * 1000 for v in values]
        figure(f"stomp bridge, publish -> {name} p50", statistics.median(ms), "ms")
        figure(f"stomp bridge, publish -> {name} p99", percentile(ms, 0.99), "ms")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=100)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    run(args.quick, args.blocks)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
