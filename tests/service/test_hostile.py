"""Hostile input over real WebSockets: no client can hurt another (issue 10).

``realizer serve`` as it is deployed (its own process, the default
settings, real sessions, parser and face) on a free
loopback port. A hostile client sends every input of the audit
(:mod:`realizer.service.hostile`) while a viewer of another character counts
frames and that character's submitter measures how long ``accepted`` takes.
Checked: no gap between the viewer's frames over 50 ms (three frame periods
at 60 fps), ``accepted`` within 50 ms, less than 100 MB of memory growth of
the server and its planner processes, the other listeners of the hostile
client's character still connected, and every character accepting new
blocks afterwards.

Timing is judged only when the machine is not overloaded (load average at
most the number of cores, before and after the attack); otherwise the
timing assertions are skipped with the figures in the reason, and
everything else is still checked.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import os
import time
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from realizer.service.hostile import BML_NS, HTTP_REQUESTS, hostile_messages
from tests.service.conftest import UNIT
from tests.service.harness import http_json
from tests.service.process import ServeProcess, serve_process

#: The longest gap allowed between two frames a viewer sees, seconds (three
#: frame periods at 60 fps).
FRAME_GAP = 0.050
#: How long ``accepted`` may take, seconds.
ACCEPT_LATENCY = 0.050
#: Growth of the server's resident memory allowed, bytes.
MEMORY_GROWTH = 100 * 1024 * 1024


def _descendants(pid: int) -> list[int]:
    """``pid`` and every process below it (the planner processes are forked
    by the fork server, a child of the server)."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents.setdefault(int(fields[1]), []).append(int(entry.name))
    found, pending = [], [pid]
    while pending:
        current = pending.pop()
        found.append(current)
        pending.extend(parents.get(current, ()))
    return found


def resident_bytes(pid: int) -> int:
    """The resident memory of process ``pid`` and its descendants, bytes."""
    if not Path("/proc/self/statm").exists():
        pytest.skip("no /proc to read the memory from")
    total = 0
    for process in _descendants(pid):
        with contextlib.suppress(OSError):
            total += int(Path(f"/proc/{process}/statm").read_text().split()[1])
    return total * os.sysconf("SC_PAGE_SIZE")


def overloaded() -> str:
    """Why timing cannot be judged now, or ``""``."""
    load = os.getloadavg()[0]
    cores = os.cpu_count() or 1
    return f"load average {load:.1f} over {cores} cores" if load > cores else ""


def smile(block_id: str, end: float = 0.3, character: str = "") -> str:
    who = f' characterId="{character}"' if character else ""
    return (
        f'<bml xmlns="{BML_NS}" id="{block_id}"{who}><faceLexeme id="s" '
        f'lexeme="RAISE_MOUTH_CORNERS" start="0" end="{end}"/></bml>'
    )


async def read_json(ws: ClientConnection, timeout: float = 10 * UNIT) -> dict[str, Any]:
    message: dict[str, Any] = json.loads(await asyncio.wait_for(ws.recv(), timeout))
    return message


async def until_state(ws: ClientConnection, block: str, states: set[str]) -> str:
    while True:
        message = await read_json(ws)
        if message["type"] == "block" and message["block"] == block and message["state"] in states:
            return str(message["state"])


async def drain(
    ws: ClientConnection, counter: list[int], until: asyncio.Event | None = None
) -> None:
    """Read everything a connection gets (a prompt reader), counting messages;
    ``until`` is set when the block ``sentinel`` is done."""
    with contextlib.suppress(ConnectionClosed):
        async for message in ws:
            counter[0] += 1
            if until is not None and '"block": "sentinel", "state": "done"' in str(message):
                until.set()


async def count_frames(ws: ClientConnection, arrivals: list[float], stop: asyncio.Event) -> None:
    loop = asyncio.get_running_loop()
    while not stop.is_set():
        try:
            message = await asyncio.wait_for(ws.recv(), 0.5)
        except TimeoutError:
            continue
        if isinstance(message, bytes):
            arrivals.append(loop.time())


async def raw_http(port: int, data: bytes) -> int:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(data)
    await writer.drain()
    head = await asyncio.wait_for(reader.read(200), 5 * UNIT)
    writer.close()
    return int(head.split(b" ", 2)[1]) if head.startswith(b"HTTP/1.1 ") else 0


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_hostile_inputs_hurt_no_other_client() -> None:
    async def scenario(server: ServeProcess) -> dict[str, Any]:
        base = server.url
        port = server.port
        figures: dict[str, Any] = {}
        async with (
            connect(f"{base}/view?character=bob") as viewer,
            connect(f"{base}/bml?format=json&character=bob") as bob,
            connect(f"{base}/bml?format=json&character=alice") as hostile,
            connect(f"{base}/bml?character=alice") as alice_xml,
            connect(f"{base}/bml?format=json&character=alice") as alice_json,
            connect(f"{base}/view?character=alice") as hostile_viewer,
        ):
            assert (await read_json(bob))["type"] == "welcome"
            assert (await read_json(hostile))["type"] == "welcome"
            assert (await read_json(alice_json))["type"] == "welcome"
            # bob's face moves all along: a long nod
            nod = (
                f'<bml xmlns="{BML_NS}" id="nod"><head id="h" lexeme="NOD" '
                'repetition="32" start="0" end="30"/></bml>'
            )
            await bob.send(nod)
            assert await until_state(bob, "nod", {"accepted"}) == "accepted"
            for n in range(3):  # warm up: the first blocks load what they need
                await bob.send(smile(f"warm{n}"))
                await until_state(bob, f"warm{n}", {"done"})

            stop = asyncio.Event()
            arrivals: list[float] = []
            frames = asyncio.create_task(count_frames(viewer, arrivals, stop))
            xml_count, json_count, hostile_count = [0], [0], [0]
            sentinel_done = asyncio.Event()
            listeners = [
                asyncio.create_task(drain(alice_xml, xml_count)),
                asyncio.create_task(drain(alice_json, json_count)),
                asyncio.create_task(drain(hostile, hostile_count, sentinel_done)),
                asyncio.create_task(drain(hostile_viewer, [0])),
            ]
            memory_before = resident_bytes(server.process.pid)
            loop = asyncio.get_running_loop()

            async def attack() -> None:
                for message in hostile_messages("alice"):
                    if message.endpoint == "/bml":
                        await hostile.send(message.text)
                    else:
                        await hostile_viewer.send(message.text)
                # the last one's answer says the connection's queue is done
                await hostile.send(smile("sentinel", character="alice"))

            latencies: list[float] = []

            async def measure_bob() -> None:
                for n in range(12):
                    sent = loop.time()
                    await bob.send(smile(f"b{n}", end=0.05))
                    await until_state(bob, f"b{n}", {"accepted", "rejected"})
                    latencies.append(loop.time() - sent)
                    await asyncio.sleep(0.15)

            attacking = asyncio.create_task(attack())
            await measure_bob()
            await attacking
            # the hostile connection's queue is processed when its sentinel is done
            await asyncio.wait_for(sentinel_done.wait(), 60 * UNIT)
            stop.set()
            await frames
            memory_after = resident_bytes(server.process.pid)
            health = await http_json(port, "/health")
            processes = len(_descendants(server.process.pid)) - 1

            gaps = [b - a for a, b in itertools.pairwise(arrivals)]
            figures.update(
                frames=len(arrivals),
                max_gap=max(gaps, default=float("inf")),
                max_latency=max(latencies),
                memory_growth=memory_after - memory_before,
                health_gap=health["clock"]["max_frame_gap_seconds"],
                processes=processes,
            )

            # the other listeners of alice are still there and still hear her
            for ws in (alice_xml, alice_json, hostile, hostile_viewer):
                assert ws.close_code is None, ws.close_code
            assert xml_count[0] > 0 and json_count[0] > 0
            for task in listeners:
                task.cancel()
            for character in ("alice", "bob", "default"):
                async with connect(f"{base}/bml?format=json&character={character}") as ws:
                    await read_json(ws)
                    await ws.send(smile(f"after-{character}"))
                    state = await until_state(ws, f"after-{character}", {"done", "rejected"})
                    assert state == "done", character
            for name, _, request, status in HTTP_REQUESTS:
                assert await raw_http(port, request) == status, name
        return figures

    why_before = overloaded()
    began = time.perf_counter()
    with serve_process() as server:  # the deployed default
        figures = asyncio.run(scenario(server))
    print(f"hostile test figures ({time.perf_counter() - began:.1f} s): {figures}")
    assert figures["frames"] > 30
    assert figures["memory_growth"] < MEMORY_GROWTH, figures
    why = why_before or overloaded()
    if why:
        pytest.skip(f"timing not judged: {why}; figures {figures}")
    assert figures["max_gap"] <= FRAME_GAP, figures
    assert figures["max_latency"] < ACCEPT_LATENCY, figures
