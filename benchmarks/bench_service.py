"""Load benchmark of the real-time service, on loopback only.

Starts ``realizer serve`` (the real session, parser and face) as a child
process on a free loopback port, connects viewers and one submitter, and
for each load (characters x viewers) measures

* latency: from sending a BML block to receiving the first frame that shows
  it (its FAPs set), at every viewer of that character: p50, p99; and its
  service part, delivery: from a frame's due time (frame 0 is on the host's
  monotonic clock, ``/health``) to its arrival at each viewer;
* frame interval jitter: |receive interval - period| at one viewer per
  character (p99, max), and the server clock's own lateness (``/health``);
* frames dropped: frame numbers a viewer never received (its mailbox kept
  the newest), and ticks the server clock skipped;
* drift: how the fastest delivery changed from the first to the last fifth
  of the run (a clock that drifted would move it; load raises it too);
* CPU (percent of one core) of the server process with its planner processes,
  and the resident memory of the server process;
* viewers of int16 vertex deltas, which make the server deform faces;
* a stalled viewer (never reads, float32 vertex frames): the server's
  memory before and after, with another viewer still served.

Goal: p99 latency under one frame period at 60 fps with 10
characters and 100 viewers; no drift over 10 minutes (``--long``).

The server runs without idle motion (``--no-idle``; start one that way for
``--port``), so a face moves only for a probe; viewers ask for ``same``
messages (``same=true``), as the project's clients do.

The viewers are lean raw-protocol clients (``LeanViewer``) in one Python
process on the same machine; their CPU use still competes with the
server's, so the figures are an upper bound of what a remote viewer would
see. Timings are printed,
never asserted. ``run(quick=True)`` takes about half a minute, the default
under two minutes; ``python benchmarks/bench_service.py --long`` adds a
10-minute run at 10 characters x 100 viewers.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import bisect
import contextlib
import itertools
import json
import os
import random
import re
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any, NamedTuple

import msgpack
import psutil
from websockets.asyncio.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure

ROOT = Path(__file__).resolve().parents[1]
FPS = 60.0

PROBE = (
    '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="{id}">'
    '<faceLexeme id="s" lexeme="RAISE_MOUTH_CORNERS" amount="1" start="0" end="{end}"/>'
    "</bml>"
)


# Plain classes, not dataclasses: `realizer bench` loads this file without
# registering it in sys.modules, which dataclasses need for string annotations.
class ViewerLog:
    """One viewer's receipts: (frame number, arrival time, any FAP set)."""

    def __init__(self, character: str) -> None:
        self.character = character
        self.receipts: list[tuple[int, float, bool]] = []


class Result(NamedTuple):
    characters: int
    viewers: int
    seconds: float
    latencies: list[float]
    delivery: list[float]
    acceptance: list[float]
    probes: int
    probes_seen: int
    jitter_p99: float
    jitter_max: float
    drift: float
    dropped: int
    expected: int
    skipped: int
    lateness_max: float
    lateness_p99: float
    written_p99: float  # the server's own: frame due -> fan-out done (nan: not reported)
    cpu: float
    rss_mb: float


def _drain(stream: IO[bytes]) -> None:
    with stream:
        stream.read()


#: ``realizer serve --planner-processes N`` for the servers started here
#: (None: the default); set by ``run(planner_processes=...)``.
PLANNER_PROCESSES: int | None = None


def start_server(fps: float, extra: list[str]) -> tuple[subprocess.Popen[bytes], int]:
    # No idle motion: a face moves only for a probe block, so the first frame
    # with FAPs set is the one that shows it, and a resting face is unchanged.
    command = [sys.executable, "-m", "realizer", "serve", "--port", "0", "--fps", str(fps)]
    if PLANNER_PROCESSES is not None:
        command += ["--planner-processes", str(PLANNER_PROCESSES)]
    process = subprocess.Popen(
        [*command, "--no-idle", *extra],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
    )
    assert process.stderr is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = process.stderr.readline().decode()
        match = re.search(r"serving on \S+:(\d+)", line)
        if match:
            # Keep reading: a server whose log fills the pipe blocks in its writes.
            threading.Thread(target=_drain, args=(process.stderr,), daemon=True).start()
            return process, int(match.group(1))
        if not line and process.poll() is not None:
            break
    process.kill()
    raise RuntimeError("realizer serve did not start")


def stop_server(process: subprocess.Popen[bytes]) -> None:
    process.terminate()
    try:
        process.wait(15)
    except subprocess.TimeoutExpired:
        process.kill()


def health(port: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=5) as reply:
        data: dict[str, Any] = json.loads(reply.read())
        return data


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q / 100 * (len(ordered) - 1)))]


class LeanViewer(asyncio.Protocol):
    """A minimal WebSocket viewer (RFC 6455 client side, no extensions) for
    the load: hundreds of them in one Python process must cost far less than
    the server, or the figures measure the client. It records each frame's
    number, arrival time and whether it has FAPs set; it answers pings."""

    def __init__(self, port: int, character: str, log: ViewerLog, vertices: str) -> None:
        self.request = (
            f"GET /view?character={character}&fap=true&vertices={vertices}&same=true HTTP/1.1\r\n"
            f"Host: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {base64.b64encode(os.urandom(16)).decode()}\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n"
        ).encode()
        self.log = log
        self.lit = False  # whether the last whole frame had FAPs set
        self.frame_bytes = 0  # bytes of frames and sames, WebSocket headers included
        self.frame_messages = 0
        self.buffer = bytearray()
        self.opened = False
        self.mesh: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.transport: asyncio.Transport | None = None
        self.clock = asyncio.get_running_loop().time

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        transport.write(self.request)

    def data_received(self, data: bytes) -> None:
        now = self.clock()
        self.buffer += data
        if not self.opened:
            end = self.buffer.find(b"\r\n\r\n")
            if end < 0:
                return
            if not self.buffer.startswith(b"HTTP/1.1 101"):
                self.mesh.set_exception(RuntimeError(bytes(self.buffer[:80]).decode()))
                return
            del self.buffer[: end + 4]
            self.opened = True
        buffer = self.buffer
        while len(buffer) >= 2:
            opcode, length, start = buffer[0] & 0x0F, buffer[1] & 0x7F, 2
            if length == 126:
                length, start = int.from_bytes(buffer[2:4], "big"), 4
            elif length == 127:
                length, start = int.from_bytes(buffer[2:10], "big"), 10
            if len(buffer) < start + length:
                break
            payload = bytes(buffer[start : start + length])
            del buffer[: start + length]
            if opcode == 2:
                message = msgpack.unpackb(payload)
                if message["type"] == "frame":
                    self.lit = bool(message.get("fap", {}).get("ids"))
                    self.log.receipts.append((message["n"], now, self.lit))
                    self.frame_bytes += start + length
                    self.frame_messages += 1
                elif message["type"] == "same":  # frame n shows what the last one did
                    self.log.receipts.append((message["n"], now, self.lit))
                    self.frame_bytes += start + length
                    self.frame_messages += 1
                elif message["type"] == "mesh" and not self.mesh.done():
                    self.mesh.set_result(None)
            elif opcode == 9:  # ping: answer with a masked pong
                self.send(0xA, payload)

    def send(self, opcode: int, payload: bytes) -> None:
        mask = os.urandom(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        assert self.transport is not None and len(payload) < 126
        self.transport.write(bytes([0x80 | opcode, 0x80 | len(payload)]) + mask + masked)

    def close(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.send(0x8, (1000).to_bytes(2, "big"))
            self.transport.close()


async def measure(
    port: int,
    characters: int,
    viewers: int,
    seconds: float,
    vertices: str,
    *,
    ports: list[int] | None = None,
    settle: float = 0.5,
    window: Callable[[], None] = lambda: None,
) -> dict[str, Any]:
    """The load: viewers (spread over ``ports`` when given: a cluster's
    gateways), then one submitter on ``port`` sending the probes after
    ``settle`` seconds; ``window`` is called as the measured window opens
    and as it closes."""
    loop = asyncio.get_running_loop()
    names = [f"c{i:02d}" for i in range(characters)]
    base = f"ws://127.0.0.1:{port}"
    logs: list[ViewerLog] = []
    lean: list[LeanViewer] = []
    for i in range(viewers):
        log = ViewerLog(names[i % characters])
        at = ports[i % len(ports)] if ports else port
        _, viewer = await loop.create_connection(
            lambda log=log, at=at: LeanViewer(at, log.character, log, vertices), "127.0.0.1", at
        )
        await asyncio.wait_for(viewer.mesh, 60)
        lean.append(viewer)
        logs.append(log)
    submitter = await connect(f"{base}/bml?format=json", compression=None)
    await submitter.recv()  # welcome

    accepted: dict[str, float] = {}  # block id -> arrival of its `accepted`

    async def drain_feedback() -> None:
        try:
            async for text in submitter:
                if '"accepted"' in text:
                    message = json.loads(text)
                    if message.get("type") == "block" and message.get("state") == "accepted":
                        accepted[message["block"]] = loop.time()
        except Exception:
            pass

    feedback = loop.create_task(drain_feedback())
    await asyncio.sleep(settle)  # let every viewer settle (a cluster: its interest reach owners)
    probes: list[tuple[str, float]] = []
    sent_at: dict[str, float] = {}
    window()
    began = loop.time()
    # One probe per character every 0.6 s (each lasts 0.25 s, so the face is
    # neutral again before the next), spread evenly over the period.
    spacing = 0.6 / characters
    chance = random.Random(6)
    index = 0
    while loop.time() - began < seconds:
        character = names[index % characters]
        block = PROBE.format(id=f"p{index}", end=0.25)
        sent = loop.time()
        await submitter.send(json.dumps({"type": "bml", "bml": block, "character": character}))
        probes.append((character, sent))
        sent_at[f"p{index}"] = sent
        index += 1
        # A random phase against the server's ticks: BML arrives at any
        # moment of a frame period, as it would from real clients.
        phase = chance.uniform(0, 1 / FPS)
        await asyncio.sleep(max(0.0, began + index * spacing + phase - loop.time()))
    await asyncio.sleep(0.5)
    ended = loop.time()
    window()
    for viewer in lean:
        viewer.close()
    await submitter.close()
    feedback.cancel()
    acceptance = [accepted[i] - t for i, t in sent_at.items() if i in accepted]
    return {
        "logs": logs,
        "probes": probes,
        "began": began,
        "ended": ended,
        "acceptance": acceptance,
        # frame and same messages, WebSocket headers included (the whole run)
        "frame_bytes": sum(lean_viewer.frame_bytes for lean_viewer in lean),
        "frame_messages": sum(lean_viewer.frame_messages for lean_viewer in lean),
    }


def probe_latencies(
    probes: list[tuple[str, float]], logs: list[ViewerLog]
) -> tuple[list[float], int, int]:
    """(latencies, probes seen, probe-viewer pairs): for each probe and each
    viewer of its character, the time to the first frame with FAPs set that
    arrived after the probe was sent (within 0.6 s)."""
    latencies: list[float] = []
    seen = pairs = 0
    # Per viewer, the arrival times of frames with FAPs set, sorted: the
    # first at or after a probe was sent is the frame that showed it.
    lit_times = [[t for _, t, lit in log.receipts if lit] for log in logs]
    for character, sent in probes:
        for log, times in zip(logs, lit_times, strict=True):
            if log.character != character:
                continue
            pairs += 1
            at = bisect.bisect_left(times, sent)
            if at < len(times) and times[at] - sent < 0.6:
                latencies.append(times[at] - sent)
                seen += 1
    return latencies, seen, pairs


def dropped_frames(logs: list[ViewerLog]) -> tuple[int, int]:
    """(dropped, expected): frame numbers each viewer never received between
    its first and last receipt, and how many there were."""
    dropped = expected = 0
    for log in logs:
        if len(log.receipts) < 2:
            continue
        numbers = [n for n, _, _ in log.receipts]
        expected += numbers[-1] - numbers[0] + 1
        dropped += numbers[-1] - numbers[0] + 1 - len(set(numbers))
    return dropped, expected


def analyse(
    characters: int,
    viewers: int,
    data: dict[str, Any],
    server: psutil.Process | None,
    cpu: float,
    status: dict[str, Any],
) -> Result:
    period = 1 / FPS
    started = status["clock"]["started"]  # frame 0 on the shared monotonic clock
    logs: list[ViewerLog] = data["logs"]
    # Only what arrived in the measured window: before it, viewers were
    # still being connected one by one and frames waited in their sockets.
    for log in logs:
        log.receipts = [r for r in log.receipts if data["began"] <= r[1] <= data["ended"]]
    latencies, seen, pairs = probe_latencies(data["probes"], logs)
    delivery: list[float] = []  # frame due time -> received, for every receipt
    for log in logs:
        delivery.extend(t - (started + n * period) for n, t, _ in log.receipts)
    jitter: list[float] = []
    dropped, expected = dropped_frames(logs)
    drift = 0.0
    probe_viewers = {log.character: log for log in reversed(logs)}
    for log in probe_viewers.values():
        times = [t for _, t, _ in log.receipts]
        jitter.extend(abs((b - a) - period) for a, b in itertools.pairwise(times))
    if logs and len(logs[0].receipts) > 20:
        # Drift: the lower envelope of (receive time - due time) at the end
        # of the run minus at its start; queueing delays only add to it.
        offsets = [t - (started + n * period) for n, t, _ in logs[0].receipts]
        fifth = max(1, len(offsets) // 5)
        drift = min(offsets[-fifth:]) - min(offsets[:fifth])
    return Result(
        characters,
        viewers,
        data["ended"] - data["began"],
        latencies,
        delivery,
        data["acceptance"],
        pairs,
        seen,
        percentile(jitter, 99),
        max(jitter, default=float("nan")),
        drift,
        dropped,
        expected,
        status["clock"]["skipped"],
        status["clock"]["max_lateness_seconds"],
        status["clock"]["lateness_p99_seconds"],
        status["clock"].get("written_p99_seconds", float("nan")),
        cpu,
        server.memory_info().rss / 2**20 if server is not None else float("nan"),
    )


def _cpu_seconds(server: psutil.Process) -> float:
    """CPU seconds of the server and its descendants (its planner processes,
    which parse and plan the blocks, and their fork server)."""
    total = 0.0
    for process in [server, *server.children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            times = process.cpu_times()
            total += times.user + times.system
    return total


def run_load(
    characters: int, viewers: int, seconds: float, vertices: str = "none", port: int | None = None
) -> Result:
    """One load against a server started here, or (``port``) one already listening."""
    if port is not None:
        data = asyncio.run(measure(port, characters, viewers, seconds, vertices))
        return analyse(characters, viewers, data, None, float("nan"), health(port))
    # viewer_characters: the viewers connect before any block names their characters.
    limits = [
        *("--limit", f"viewers_per_character={max(256, viewers)}"),
        *("--limit", "characters=256", "--limit", "viewer_characters=256"),
    ]
    process, port = start_server(FPS, limits)
    try:
        server = psutil.Process(process.pid)
        began, cpu_before = time.monotonic(), _cpu_seconds(server)
        client = psutil.Process()
        client.cpu_percent()
        data = asyncio.run(measure(port, characters, viewers, seconds, vertices))
        cpu = 100 * (_cpu_seconds(server) - cpu_before) / (time.monotonic() - began)
        print(f"  ({characters} x {viewers}: client process CPU {client.cpu_percent():.0f}%)")
        status = health(port)
        return analyse(characters, viewers, data, server, cpu, status)
    finally:
        stop_server(process)


async def idle_bytes(port: int, vertices: str, seconds: float) -> tuple[float, float]:
    """(bytes a second, bytes a tick) one viewer of a resting face receives."""
    loop = asyncio.get_running_loop()
    log = ViewerLog("resting")
    _, viewer = await loop.create_connection(
        lambda: LeanViewer(port, "resting", log, vertices), "127.0.0.1", port
    )
    await asyncio.wait_for(viewer.mesh, 30)
    await asyncio.sleep(0.3)  # past the first, whole frame
    viewer.frame_bytes = viewer.frame_messages = 0
    began = loop.time()
    await asyncio.sleep(seconds)
    spent = loop.time() - began
    received, count = viewer.frame_bytes, viewer.frame_messages
    viewer.close()
    return received / spent, received / max(count, 1)


def run_idle(port: int | None, seconds: float) -> None:
    """The idle bandwidth of each viewer format: goal a few bytes per unchanged frame."""
    process = None
    if port is None:
        process, port = start_server(FPS, [])
    try:
        for name, vertices in VIEWER_FORMATS.items():
            per_second, per_tick = asyncio.run(idle_bytes(port, vertices, seconds))
            figure(
                f"idle face, {name} viewer: bytes per unchanged frame",
                per_tick,
                "bytes",
                goal=IDLE_GOAL_BYTES,
                note=f"{per_second * 8 / 1e3:.1f} kbit/s with WebSocket headers",
            )
    finally:
        if process is not None:
            stop_server(process)


#: "A few bytes" per unchanged frame, WebSocket header included.
IDLE_GOAL_BYTES = 24.0


async def stalled(port: int, seconds: float) -> tuple[int, int]:
    """(frames the healthy viewer got, frames it should have got)."""
    base = f"ws://127.0.0.1:{port}"
    # max_queue=1: the client stops reading its socket once one message waits.
    stuck = await connect(f"{base}/view?character=s&vertices=float32", max_queue=1, max_size=None)
    healthy = await connect(f"{base}/view?character=s&fap=true")
    await healthy.recv()
    loop = asyncio.get_running_loop()
    got = 0
    began = loop.time()
    while loop.time() - began < seconds:
        await healthy.recv()
        got += 1
    await healthy.close()
    stuck.transport.abort()
    return got, int(seconds * FPS)


def run_stalled(seconds: float) -> None:
    process, port = start_server(FPS, [])
    try:
        server = psutil.Process(process.pid)
        time.sleep(0.5)
        before = server.memory_info().rss / 2**20
        got, due = asyncio.run(stalled(port, seconds))
        after = server.memory_info().rss / 2**20
        print(
            f"stalled viewer (float32 vertices, never reads) for {seconds:.0f} s: server RSS "
            f"{before:.1f} -> {after:.1f} MiB; the other viewer got {got} of {due} frames"
        )
    finally:
        stop_server(process)


def print_table(results: list[Result], label: str) -> None:
    period_ms = 1000 / FPS

    def ms(values: list[float], q: float) -> float:
        return percentile([v * 1000 for v in values], q)

    print(
        "latency: BML sent -> first frame showing it received (ms); delivery: frame due -> "
        "received (ms); jitter: |receive interval - period| at one viewer per character (ms); "
        "late: server tick start after its due time (ms); written: frame due -> the server's "
        "fan-out done (ms); drift: change of the fastest delivery from the first to the "
        "last fifth of the run (ms)"
    )
    print(
        f"{'chars':>5} {'viewers':>7} | {'latency p50':>11} {'p99':>6} {'seen':>11} | "
        f"{'accepted p99':>12} | "
        f"{'delivery p50':>12} {'p99':>6} | {'jitter p99':>10} {'max':>6} | "
        f"{'dropped':>13} {'skip':>4} | {'late p99':>8} {'max':>5} | {'written p99':>11} | "
        f"{'drift':>6} | "
        f"{'cpu':>4} {'rss':>5}"
    )
    for r in results:
        print(
            f"{r.characters:>5} {r.viewers:>7} | {ms(r.latencies, 50):11.1f} "
            f"{ms(r.latencies, 99):6.1f} {r.probes_seen:>5}/{r.probes:<5} | "
            f"{ms(r.acceptance, 99):12.2f} | "
            f"{ms(r.delivery, 50):12.2f} {ms(r.delivery, 99):6.2f} | "
            f"{r.jitter_p99 * 1000:10.2f} {r.jitter_max * 1000:6.2f} | "
            f"{r.dropped:>6}/{r.expected:<6} {r.skipped:>4} | "
            f"{r.lateness_p99 * 1000:8.2f} {r.lateness_max * 1000:5.1f} | "
            f"{r.written_p99 * 1000:11.2f} | "
            f"{r.drift * 1000:6.2f} | {r.cpu:3.0f}% {r.rss_mb:4.0f}M"
        )
    for r in results:
        load = f"{label} viewers, {r.characters} x {r.viewers}"
        goals = GOALS.get((label, r.characters, r.viewers), {})
        for key, values in (
            ("latency", r.latencies),
            ("delivery", r.delivery),
            ("accepted", r.acceptance),
        ):
            figure(
                f"{load}: {DESCRIPTIONS[key]} p99",
                ms(values, 99),
                "ms",
                goal=goals.get(key),
                quiet=key not in goals,
            )
        figure(
            f"{load}: {DESCRIPTIONS['written']} p99 (server)",
            r.written_p99 * 1000,
            "ms",
            goal=goals.get("written"),
            quiet="written" not in goals,
        )
        figure(f"{load}: frame interval jitter p99", r.jitter_p99 * 1000, "ms", quiet=True)
        figure(f"{load}: frames dropped", r.dropped, "frames", quiet=True)
        figure(f"{load}: server CPU", r.cpu, "% of a core", quiet=True)
        if (r.characters, r.viewers) == (10, 100):
            print(
                f"of the latency, waiting for the next tick is up to one period "
                f"({period_ms:.1f} ms) by design (docs/service.md); drift over "
                f"{r.seconds:.0f} s: {r.drift * 1000:+.2f} ms"
            )


DESCRIPTIONS = {
    "latency": "BML sent -> first frame showing it",
    "delivery": "frame due -> received",
    "accepted": "BML sent -> accepted",
    "written": "frame due -> written to the last viewer",
}
#: The real-time goals (ms; docs/performance.md), by (viewer format, characters, viewers).
#: "written" is the server's own figure (/health: due -> the tick's fan-out done); delivery,
#: measured at the client, adds the clients' reading on this same machine.
GOALS: dict[tuple[str, int, int], dict[str, float]] = {
    ("fap", 10, 100): {"latency": 1000 / FPS + 2.0, "written": 2.0, "accepted": 3.0},
    ("int16", 50, 200): {"accepted": 5.0},
}


VIEWER_FORMATS = {"fap": "none", "int16": "int16", "float32": "float32"}


def run(
    quick: bool = False,
    long: bool = False,
    port: int | None = None,
    viewers: str | None = None,
    planner_processes: int | None = None,
) -> None:
    """Every load; ``port``: against that running server (no stalled-viewer run, no CPU or
    memory figures); ``viewers``: only that viewer format (``fap``, ``int16``, ``float32``);
    ``planner_processes``: the servers started here get ``--planner-processes N``."""
    global PLANNER_PROCESSES
    PLANNER_PROCESSES = planner_processes
    loads = (
        [(1, 1, 3.0), (10, 100, 4.0)]
        if quick
        else [
            (1, 1, 4.0),
            (1, 10, 4.0),
            (10, 10, 4.0),
            (10, 100, 5.0),
            (50, 50, 4.0),
            (50, 200, 4.0),
        ]
    )
    vertex_loads = [(1, 10, 3.0)] if quick else [(1, 10, 4.0), (10, 20, 4.0), (50, 200, 4.0)]
    where = f"the server on port {port}" if port is not None else "a server started here"
    if port is None and planner_processes is not None:
        where += f" with --planner-processes {planner_processes}"
    print(f"service load on loopback, {FPS:g} fps, {os.cpu_count()} CPUs, {where}")
    formats = ["fap", "int16"] if viewers in (None, "all") else [viewers]
    for name in formats:
        vertices = VIEWER_FORMATS[name]
        if name == "fap":
            print("viewers of FAP frames:")
            chosen = loads
        else:
            # Vertex viewers make the server deform each character's face once
            # per tick while its FAPs change (the browser viewer's kind of stream).
            print(f"viewers of {name} vertex frames (and FAPs):")
            chosen = vertex_loads if viewers in (None, "all") else loads
        print_table([run_load(c, v, s, vertices, port) for c, v, s in chosen], name)
    run_idle(port, 1.0 if quick else 3.0)
    if port is None:
        run_stalled(3.0 if quick else 5.0)
    if long:
        print("long run: 10 characters x 100 viewers for 600 s (drift)")
        print_table([run_load(10, 100, 600.0, port=port)], "fap, long")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--long", action="store_true", help="add a 10-minute drift run")
    parser.add_argument("--port", type=int, help="measure the server listening on this port")
    parser.add_argument("--viewers", choices=("all", *VIEWER_FORMATS), help="viewer format")
    parser.add_argument("--planner-processes", type=int, help="realizer serve's option")
    options = parser.parse_args()
    run(
        quick=options.quick,
        long=options.long,
        port=options.port,
        viewers=options.viewers,
        planner_processes=options.planner_processes,
    )
