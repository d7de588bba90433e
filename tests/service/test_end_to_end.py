"""End to end: the real server on a free loopback port, the real session,
parser and face, and real WebSocket clients (issue 6, "Done when").

Every wait is a multiple of UNIT (REALIZER_TEST_TIME_UNIT scales it); no
test asserts how fast anything is, only what arrives and in which order.
"""

from __future__ import annotations

import asyncio
import json
import re
import socket
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from realizer.service import codec
from realizer.service.assets import face_assets, load_face, session_factory
from realizer.service.limits import ServiceLimits
from realizer.service.server import WRITE_LIMIT, FaceAssets
from tests.service.conftest import UNIT
from tests.service.harness import running_service

CONFORMANCE = Path(__file__).resolve().parents[2].parent / "shared" / "conformance"
if not CONFORMANCE.exists():  # a worktree beside /work/shared
    CONFORMANCE = Path("/work/shared/conformance")
BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
#: raise_l_cornerlip, raise_r_cornerlip and their outer-lip twins (seed 002 Table 7)
MOUTH_CORNER_FAPS = {12, 13, 59, 60}


@cache
def real_face() -> Any:
    return load_face()


@cache
def real_assets() -> FaceAssets:
    return face_assets(real_face())


def real_sessions() -> Any:
    return session_factory(real_face())


def smile(block_id: str, start: float, end: float, character: str | None = None) -> str:
    who = f' characterId="{character}"' if character else ""
    return (
        f'<bml xmlns="{BML_NS}" id="{block_id}"{who}>'
        f'<faceLexeme id="smile" lexeme="RAISE_MOUTH_CORNERS" amount="1" '
        f'start="{start}" end="{end}"/></bml>'
    )


async def read_json(ws: ClientConnection, timeout: float = 10 * UNIT) -> dict[str, Any]:
    message: dict[str, Any] = json.loads(await asyncio.wait_for(ws.recv(), timeout))
    return message


async def until_block_final(ws: ClientConnection, block: str) -> list[dict[str, Any]]:
    """Messages up to and including the block's final state."""
    received = []
    while True:
        message = await read_json(ws)
        received.append(message)
        if (
            message["type"] == "block"
            and message["block"] == block
            and message["state"] != "accepted"
        ):
            return received


def attribute(xml: str, name: str) -> str | None:
    match = re.search(rf'\s{name}\s*=\s*"([^"]*)"', xml)
    return match.group(1) if match else None


def test_feedback_for_a_conformance_document_arrives_complete_and_in_time_order() -> None:
    document = (CONFORMANCE / "openbmlparser-bmltest" / "testnod_offset.xml").read_text()

    async def scenario() -> list[dict[str, Any]]:
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            assert (await read_json(submitter))["type"] == "welcome"
            await submitter.send(document)  # plain BML, as a BML client sends it
            return await until_block_final(submitter, "bml1")

    messages = asyncio.run(scenario())
    feedback = [m for m in messages if m["type"] == "feedback"]
    states = [m["state"] for m in messages if m["type"] == "block"]
    kinds = [m["kind"] for m in feedback]
    assert states == ["accepted", "done"]
    assert kinds[0] == "prediction" and "warning" not in kinds
    times = [m["time"] for m in feedback]
    assert times == sorted(times)
    progress = {attribute(m["xml"], "id"): m["time"] for m in feedback if m["kind"] != "prediction"}
    # complete: the block's start and end, and every behaviour's start and end
    for sync in ("bml1:start", "bml1:end"):
        assert sync in progress
    for behaviour in ("nod1", "nod2"):
        assert f"bml1:{behaviour}:start" in progress and f"bml1:{behaviour}:end" in progress
    # the document's required timing: nod1:start + 1 = nod2:start - 1
    assert progress["bml1:nod2:start"] - progress["bml1:nod1:start"] == pytest.approx(2, abs=0.02)
    assert progress["bml1:end"] == max(progress.values())


def test_a_viewer_sees_a_block_at_its_scheduled_times() -> None:
    async def scenario() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/view?character=Alice") as viewer,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            mesh = codec.unpack(await viewer.recv())
            assert mesh["type"] == "mesh" and mesh["vertexCount"] == len(real_face().vertices)
            await read_json(submitter)
            frames: list[dict[str, Any]] = []

            async def collect() -> None:
                async for data in viewer:
                    frames.append(codec.unpack(data))  # type: ignore[arg-type]

            collector = asyncio.get_running_loop().create_task(collect())
            await submitter.send(
                json.dumps({"type": "bml", "bml": smile("s1", 0.3, 0.9), "character": "Alice"})
            )
            messages = await until_block_final(submitter, "s1")
            await asyncio.sleep(0.2 * UNIT)
            collector.cancel()
            return messages, frames

    messages, frames = asyncio.run(scenario())
    progress = {
        attribute(m["xml"], "id"): m["time"]
        for m in messages
        if m["type"] == "feedback" and m["kind"] != "prediction"
    }
    start, end = progress["s1:smile:start"], progress["s1:smile:end"]
    assert progress["s1:start"] <= start - 0.25  # the smile starts 0.3 s into the block

    def corners(frame: dict[str, Any]) -> float:
        faps = codec.decode_faps(frame["fap"]) if "fap" in frame else {}
        return max((abs(v) for k, v in faps.items() if k in MOUTH_CORNER_FAPS), default=0.0)

    numbers = [f["n"] for f in frames if f["type"] == "frame"]
    assert numbers == sorted(numbers)
    before = [f for f in frames if f["type"] == "frame" and f["t"] < start - 1e-6]
    during = [f for f in frames if f["type"] == "frame" and start + 0.1 <= f["t"] <= end - 0.1]
    after = [f for f in frames if f["type"] == "frame" and f["t"] > end + 1e-6]
    assert before and during and after
    assert all(corners(f) == 0 for f in before)
    assert all(corners(f) > 0 for f in during)
    assert all(corners(f) == 0 for f in after)


def test_a_stalled_viewer_does_not_stop_another_and_its_memory_stays_bounded() -> None:
    async def scenario() -> None:
        async with running_service(real_sessions(), real_assets()) as service:
            base = f"ws://127.0.0.1:{service.port}/view?character=Bob"
            # max_queue=1: this client stops reading its socket after one
            # message, so the server's writes to it back up (a stalled viewer);
            # a small receive buffer makes that happen sooner.
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.connect(("127.0.0.1", service.port))
            sock.setblocking(False)
            async with (
                connect(
                    base + "&vertices=float32", sock=sock, max_queue=1, max_size=None
                ) as stalled,
                connect(base + "&vertices=int16") as healthy,
                connect(f"ws://127.0.0.1:{service.port}/bml") as submitter,
            ):
                await submitter.send(smile("b1", 0.0, 30.0, character="Bob"))
                (slow,) = [v for v in service.viewers["Bob"] if v.options.vertices == "float32"]
                # and a small send buffer on the server's side of it
                server_socket = slow.connection.transport.get_extra_info("socket")
                server_socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
                numbers: list[int] = []
                buffered: list[int] = []
                frame_bytes = 0
                while len(numbers) < 150 or slow.replaced < 10:
                    message = codec.unpack(await asyncio.wait_for(healthy.recv(), 5 * UNIT))
                    if message["type"] == "frame":
                        numbers.append(message["n"])
                    buffered.append(slow.connection.transport.get_write_buffer_size())
                    frame_bytes = max(frame_bytes, len(slow.latest or b""))
                    assert len(numbers) < 6000 * UNIT, "the stalled viewer never backed up"
                # the healthy viewer kept getting new frames, in order
                assert numbers == sorted(set(numbers)) and numbers[-1] - numbers[0] >= 149
                # the stalled one: frames replaced in its one-frame mailbox, and
                # the socket buffer bounded by the write limit plus two frames
                assert slow.replaced >= 10 and frame_bytes > 0
                assert max(buffered) <= WRITE_LIMIT + 2 * frame_bytes
                stalled.transport.abort()  # a closing handshake would wait on the backlog

    asyncio.run(scenario())


def test_oversized_and_malformed_input_is_answered_and_nothing_else_is_disturbed() -> None:
    limits = ServiceLimits(message_bytes=16 * 1024)

    async def scenario() -> None:
        async with (
            running_service(real_sessions(), real_assets(), limits=limits) as service,
            # read only now and then: an unbounded client queue, so that
            # closing at the end does not wait behind unread frames
            connect(f"ws://127.0.0.1:{service.port}/view", max_queue=None) as viewer,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as careful,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as careless,
        ):
            await viewer.recv()
            await read_json(careful)
            await read_json(careless)
            # malformed BML: a warning with the parser's position, the block rejected
            await careless.send('<bml xmlns="' + BML_NS + '" id="bad"><faceLexeme id=')
            warning, rejected = await read_json(careless), await read_json(careless)
            assert warning["kind"] == "warning" and 'type="PARSING_FAILURE"' in warning["xml"]
            assert "line 1" in warning["xml"]
            assert (rejected["block"], rejected["state"]) == ("bad", "rejected")
            # a malformed envelope: a warning, the connection goes on
            await careless.send('{"type": "bml", "bml": 42}')
            assert 'type="PARSING_FAILURE"' in (await read_json(careless))["xml"]
            # an oversized message: closed with 1009 and a reason
            await careless.send(smile("big", 0, 1) + " " * (20 * 1024))
            with pytest.raises(ConnectionClosed):
                while True:
                    await read_json(careless)
            assert careless.close_code == 1009 and careless.close_reason
            # everyone else: still served
            await careful.send(json.dumps({"type": "bml", "bml": smile("fine", 0, 0.3)}))
            states = [
                m["state"] for m in await until_block_final(careful, "fine") if m["type"] == "block"
            ]
            assert states == ["accepted", "done"]
            numbers = []
            while len(numbers) < 3:
                message = codec.unpack(await asyncio.wait_for(viewer.recv(), 5 * UNIT))
                if message["type"] == "frame":
                    numbers.append(message["n"])
            assert numbers == sorted(set(numbers))

    asyncio.run(scenario())


def test_an_interrupt_ends_a_running_block_as_interrupted() -> None:
    async def scenario() -> list[dict[str, Any]]:
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            await read_json(submitter)
            await submitter.send(json.dumps({"type": "bml", "bml": smile("long", 0, 60)}))
            while (await read_json(submitter)).get("state") != "accepted":
                pass
            await asyncio.sleep(0.2 * UNIT)
            await submitter.send(json.dumps({"type": "interrupt", "block": "long"}))
            return await until_block_final(submitter, "long")

    messages = asyncio.run(scenario())
    assert messages[-1]["state"] == "interrupted"
    assert any(m.get("kind") == "blockProgress" for m in messages)


def test_a_replace_block_ends_the_blocks_it_replaces_as_interrupted() -> None:
    replace = smile("second", 0, 0.3).replace('id="second"', 'id="second" composition="REPLACE"')

    async def scenario() -> list[dict[str, Any]]:
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            await read_json(submitter)
            await submitter.send(json.dumps({"type": "bml", "bml": smile("first", 0, 60)}))
            while (await read_json(submitter)).get("state") != "accepted":
                pass
            await submitter.send(json.dumps({"type": "bml", "bml": replace}))
            return await until_block_final(submitter, "second")

    messages = asyncio.run(scenario())
    states = [(m["block"], m["state"]) for m in messages if m["type"] == "block"]
    assert states == [("first", "interrupted"), ("second", "accepted"), ("second", "done")]
