"""The viewers' fan-out: what one viewer-frame costs the server, and its floor.

Starts the real service in this process (the real session and default face,
its clock stopped so that this benchmark drives the ticks) with 10
characters and N real WebSocket viewers connected from a child process that
only reads, then times, per viewer-frame (a whole frame to every viewer,
no ``same`` messages):

* the server's whole tick (``Stage.tick`` of the 10 sessions, then
  ``RealizerService._deliver_frame``: each format encoded once, its
  WebSocket bytes built once), per viewer-frame: the goal's "due -> written
  to the last viewer" on an idle machine;
* the same tick as the service's clock runs it (``_clock_tick``: each
  character ticked and its frame queued, then written, in slices of
  ``FAN_OUT_SLICE`` seconds; nothing here waits for the loop, so this is the
  slicing's own cost);
* ``Viewer.offer`` alone, writing the prebuilt bytes to each socket;
* the path before it: the same checks, then websockets' ``send_binary`` +
  ``send_data`` per viewer (the protocol object builds and flushes each
  frame);
* the floor: ``os.write`` of the prebuilt bytes to each socket, nothing
  else in Python (the kernel's loopback TCP send is most of it);
* that floor split over two threads (``os.write`` releases the GIL: what
  a writer thread can overlap on a second core).

Best of the rounds, wall and CPU time of the calling thread; the goal
"frame due -> written to the last viewer p99 under 2 ms at 10 characters x
100 viewers" needs 1,000 viewer-frames in 2 ms, 2 us each on one core. Timings
are printed, never asserted.
"""

from __future__ import annotations

import asyncio
import base64
import os
import selectors
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

CHARACTERS = 10
#: 2 ms for 1,000 viewer-frames (10 characters x 100 viewers).
GOAL_US = 2.0


def _readers(port: int, viewers: int) -> None:
    """Child process (``bench_fanout.py --readers PORT N``): ``viewers``
    WebSocket viewers that read and discard."""
    chooser = selectors.DefaultSelector()
    for i in range(viewers):
        sock = socket.create_connection(("127.0.0.1", port))
        key = base64.b64encode(os.urandom(16)).decode()
        sock.sendall(
            f"GET /view?character=c{i % CHARACTERS:02d}&fap=true&audio=none HTTP/1.1\r\n"
            f"Host: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
        )
        sock.setblocking(False)
        chooser.register(sock, selectors.EVENT_READ)
    while chooser.get_map():
        for key, _ in chooser.select():
            try:
                data = key.fileobj.recv(1 << 16)  # type: ignore[union-attr]
            except BlockingIOError:
                continue
            except OSError:
                data = b""
            if not data:
                chooser.unregister(key.fileobj)
                key.fileobj.close()  # type: ignore[union-attr]


async def _measure(viewers: int, rounds: int) -> dict[str, tuple[float, float]]:
    from dataclasses import replace

    from realizer.service import assets as service_assets
    from realizer.service.limits import DEFAULT_LIMITS
    from realizer.service.server import WRITE_LIMIT, RealizerService, ServiceConfig, binary_frame
    from realizer.service.stage import Stage

    class Driven(RealizerService):
        async def _run_clock(self) -> None:  # this benchmark drives the ticks
            return

    face = service_assets.load_face()
    limits = replace(
        DEFAULT_LIMITS,
        viewers=max(DEFAULT_LIMITS.viewers, viewers),
        viewers_per_character=max(DEFAULT_LIMITS.viewers_per_character, viewers),
        characters=max(DEFAULT_LIMITS.characters, CHARACTERS),
        viewer_characters=max(DEFAULT_LIMITS.viewer_characters, CHARACTERS),
    )
    stage = Stage(service_assets.session_factory(face), limits, default_character="c00")
    service = Driven(ServiceConfig(port=0, limits=limits), stage, service_assets.face_assets(face))
    await service.start()
    child = subprocess.Popen(
        [sys.executable, __file__, "--readers", str(service.port), str(viewers)],
        stdin=subprocess.DEVNULL,
    )
    loop = asyncio.get_running_loop()
    try:
        deadline = loop.time() + 60
        while sum(len(v) for v in service.viewers.values()) < viewers:
            if loop.time() > deadline or child.poll() is not None:
                raise RuntimeError("the viewers did not connect")
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.5)  # every pump has sent its mesh and waits
        number = 0
        every = [v for group in service.viewers.values() for v in group]

        def fan_out() -> None:
            nonlocal number
            number += 1
            for character_tick in stage.tick(number / 60):
                service._deliver_frame(number, character_tick)
            service._write_offers_at_once()

        async def clock_tick() -> None:
            # as the clock runs it: sessions, encoding and writes in slices of
            # FAN_OUT_SLICE, the loop given back between two when something
            # waits for it (nothing here: this is the slicing's own cost)
            nonlocal number
            number += 1
            await service._clock_tick(loop, number, number / 60, loop.time() + 1.0)

        fan_out()  # warm up (encoders made)
        options = every[0].options
        session = stage.characters["c00"].session
        payload = service.encoders["c00"].encode(
            number, number / 60, session.frame(number / 60), [options]
        )[options]
        wire = binary_frame(payload)

        def offer() -> None:
            for viewer in every:
                viewer.offer(payload, WRITE_LIMIT, wire)

        def offer_before() -> None:
            # Viewer.offer before the prebuilt bytes: websockets' protocol
            # object built and flushed each viewer's frame
            for viewer in every:
                connection = viewer.connection
                if viewer.writes_at_once(WRITE_LIMIT):
                    connection.protocol.send_binary(payload)
                    connection.send_data()

        fds = [v.connection.transport.get_extra_info("socket").fileno() for v in every]

        def floor(part: list[int] = fds) -> None:
            write = os.write
            for fd in part:
                write(fd, wire)

        def two_threads() -> None:
            half = len(fds) // 2
            helper = threading.Thread(target=floor, args=(fds[half:],))
            helper.start()
            floor(fds[:half])
            helper.join()

        variants: dict[str, Callable[[], Any]] = {
            "the server's whole tick (sessions, encoding once per format, fan-out)": fan_out,
            "the same tick as the clock runs it (in slices)": clock_tick,
            "Viewer.offer of prebuilt WebSocket bytes": offer,
            "Viewer.offer through websockets' send_binary (before)": offer_before,
            "floor: os.write of the bytes to each socket": floor,
            "floor split over 2 threads": two_threads,
        }
        results = {name: (float("inf"), float("inf")) for name in variants}
        for _ in range(rounds):  # interleaved: every variant sees the same machine
            for name, work in variants.items():
                await asyncio.sleep(1 / 60)  # the readers empty their sockets
                wall, cpu = time.perf_counter(), time.thread_time()
                done = work()
                if asyncio.iscoroutine(done):
                    await done
                wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
                best = results[name]
                results[name] = (min(best[0], wall), min(best[1], cpu))
        return results
    finally:
        await service.shutdown()
        try:
            child.wait(10)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()


def run(quick: bool = False) -> None:
    viewers = 200 if quick else 400
    rounds = 15 if quick else 40
    load = os.getloadavg()[0]
    print(
        f"fan-out to {viewers} loopback viewers of {CHARACTERS} characters, best of {rounds} "
        f"rounds, load average {load:.1f} on {os.cpu_count()} CPUs (us per viewer-frame, "
        "wall / CPU of this thread)"
    )
    results = asyncio.run(_measure(viewers, rounds))
    for name, (wall, cpu) in results.items():
        us_wall, us_cpu = wall / viewers * 1e6, cpu / viewers * 1e6
        figure(
            f"fan-out, {name}: per viewer-frame",
            us_wall,
            "us",
            goal=GOAL_US if name.startswith("the server") else None,
            note=f"CPU of this thread {us_cpu:.2f} us; x 1,000 = {us_wall:.1f} ms",
        )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--readers"]:
        _readers(int(sys.argv[2]), int(sys.argv[3]))
    else:
        run(quick="--quick" in sys.argv)
