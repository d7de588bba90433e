"""Regression tests of the service's defects of the hostile-input audit (issue 10).

The real server on a free loopback port and real WebSocket clients; the
session is the test double where the scheduler's timings do not matter.
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from realizer.service.errors import BadMessage
from realizer.service.hostile import HTTP_REQUESTS
from realizer.service.limits import ServiceLimits
from realizer.service.messages import read_submitter_message, read_subscribe_message
from realizer.service.server import ClockStats, FaceAssets
from realizer.service.stage import Stage, _guess_block_id
from tests.service.conftest import UNIT
from tests.service.doubles import FakeFace, FakeSession, fake_deform, smile_bml
from tests.service.harness import http_json, running_service, viewers_and_close_codes

ASSETS = FaceAssets(FakeFace(), fake_deform)  # type: ignore[arg-type]


async def read_json(ws: Any, timeout: float = 10 * UNIT) -> dict[str, Any]:
    message: dict[str, Any] = json.loads(await asyncio.wait_for(ws.recv(), timeout))
    return message


async def raw_http(port: int, data: bytes) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(data)
    await writer.drain()
    head = await asyncio.wait_for(reader.read(300), 5 * UNIT)
    writer.close()
    return head


def status(head: bytes) -> int:
    return int(head.split(b" ", 2)[1]) if head.startswith(b"HTTP/1.1 ") else 0


# -- defects 8 and 9: JSON that is not text or not readable ---------------------


@pytest.mark.parametrize(
    "text",
    [
        '{"type":"interrupt","block":"\\udc80","character":"alice"}',
        '{"type":"bml","bml":"<bml/>","character":"\\udc80"}',
        '{"type":"bml","bml":"\\ud800"}',
        '{"a":' + "[" * 100_000,
        '{"type":"bml","n":' + "9" * 5000 + "}",
        '{"type":"bml","bml":"x","n":NaN}',
    ],
)
def test_unreadable_json_is_a_bad_message_never_another_exception(text: str) -> None:
    with pytest.raises(BadMessage):
        read_submitter_message(text)


@pytest.mark.parametrize(
    "text",
    ["[" * 100_000, '{"type":"subscribe","fap":' + "9" * 5000 + "}", '{"character":"\\udc80"}'],
)
def test_unreadable_subscribe_messages_are_bad_messages(text: str) -> None:
    with pytest.raises(BadMessage):
        read_subscribe_message(text)


def test_a_lone_surrogate_interrupt_drops_no_listener_and_gets_a_parsing_failure(
    caplog: pytest.LogCaptureFixture,
) -> None:
    async def scenario() -> tuple[dict[str, Any], str, int | None, int | None]:
        async with (
            running_service(FakeSession, ASSETS) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml?character=alice") as listener,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json&character=alice") as sender,
            connect(f"ws://127.0.0.1:{service.port}/view?character=alice") as viewer,
        ):
            await read_json(sender)  # welcome
            await sender.send('{"type":"interrupt","block":"\\udc80","character":"alice"}')
            answer = await read_json(sender)
            await viewer.send("[" * 100_000)
            await sender.send(smile_bml("b1", character="alice"))
            heard = str(await asyncio.wait_for(listener.recv(), 10 * UNIT))
            return answer, heard, listener.close_code, viewer.close_code

    answer, heard, listener_code, viewer_code = asyncio.run(scenario())
    assert answer["kind"] == "warning" and 'type="PARSING_FAILURE"' in answer["xml"]
    assert "lone surrogate" in answer["xml"]
    # the sender's mistake is told to the sender only; the listener hears b1 next
    assert 'id="b1"' in heard and listener_code is None and viewer_code is None
    assert "Traceback" not in caplog.text and "internal error" not in caplog.text


# -- defect 12: HTTP requests the service does not serve ------------------------


def test_odd_http_requests_get_an_answer() -> None:
    async def scenario() -> list[tuple[str, int, int]]:
        async with running_service(FakeSession, ASSETS) as service:
            return [
                (name, expected, status(await raw_http(service.port, request)))
                for name, _, request, expected in HTTP_REQUESTS
            ]

    for name, expected, got in asyncio.run(scenario()):
        assert got == expected, name


def test_a_doubled_authorization_header_is_401_with_tokens_set(
    caplog: pytest.LogCaptureFixture,
) -> None:
    request = (
        b"GET /bml HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        b"Authorization: Bearer s\r\nAuthorization: Bearer s\r\n"
        b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    )

    async def scenario() -> bytes:
        async with running_service(
            FakeSession, ASSETS, submit_token="s", view_token="v"
        ) as service:
            return await raw_http(service.port, request)

    assert status(asyncio.run(scenario())) == 401
    assert "Traceback" not in caplog.text


# -- defect 13: viewers cannot fill the character table ---------------------------


def test_viewers_alone_make_a_bounded_number_of_characters() -> None:
    limits = ServiceLimits(characters=6, viewer_characters=3)

    async def scenario() -> tuple[list[int | None], bool]:
        async with running_service(FakeSession, ASSETS, limits=limits) as service:
            base = f"ws://127.0.0.1:{service.port}"
            viewers, codes = await viewers_and_close_codes(base, 5, 5 * UNIT)
            async with connect(f"{base}/bml?format=json&character=carol") as submitter:
                await read_json(submitter)
                await submitter.send(smile_bml("c1"))
                accepted = False
                while True:
                    message = await read_json(submitter)
                    if message["type"] == "block":
                        accepted = message["state"] == "accepted"
                        break
            for viewer in viewers:
                await viewer.close()
            return codes, accepted

    codes, accepted = asyncio.run(scenario())
    assert codes == [None, None, None, 1013, 1013]
    assert accepted  # a submitter still gets a character


def test_idle_characters_are_freed_after_the_named_time() -> None:
    stage = Stage(FakeSession, ServiceLimits(characters=3, viewer_characters=3))
    for n in range(3):
        stage.character(f"v{n}", for_viewer=True)
    assert stage.forget_idle(10.0, 300) == []  # not idle long enough
    assert sorted(stage.forget_idle(400.0, 300, keep=["v1"])) == ["v0", "v2"]
    stage.submit_bml(smile_bml("b", character="w"), 400.0)
    assert stage.forget_idle(800.0, 300) == ["v1"]  # w's block is open (never ticked)
    stage.tick(401.5)  # the block ends at 401 s
    assert stage.forget_idle(800.0, 300) == ["w"]


# -- defect 14: a bad query parameter closes with 1008 ----------------------------


def test_a_bad_view_query_closes_with_1008() -> None:
    async def scenario() -> int | None:
        async with running_service(FakeSession, ASSETS) as service:
            ws = await connect(f"ws://127.0.0.1:{service.port}/view?vertices=bogus")
            with pytest.raises(ConnectionClosed):
                await asyncio.wait_for(ws.recv(), 5 * UNIT)
            return ws.close_code

    assert asyncio.run(scenario()) == 1008


# -- defect 15: /health reports the real longest gap between frames ---------------


def test_the_clock_stats_report_a_stall_in_full() -> None:
    stats = ClockStats()
    for n in range(10):
        stats.tick_began(n / 60)
    stats.tick_began(10 / 60 + 7.0)  # a 7-second stall, then the frame due now
    assert stats.max_frame_gap_seconds == pytest.approx(7.0 + 1 / 60)
    assert stats.summary()["max_frame_gap_seconds"] == stats.max_frame_gap_seconds


def test_health_reports_the_longest_frame_gap() -> None:
    async def scenario() -> dict[str, Any]:
        async with running_service(FakeSession, ASSETS) as service:
            await asyncio.sleep(0.2)
            time.sleep(0.3)  # the loop stalls for 0.3 s
            await asyncio.sleep(0.1)
            return await http_json(service.port, "/health")

    health = asyncio.run(scenario())
    assert health["maxFrameGapSeconds"] >= 0.3
    assert health["clock"]["max_frame_gap_seconds"] == health["maxFrameGapSeconds"]


# -- the refused document's id is found in linear time ---------------------------


@pytest.mark.parametrize("text", ["<bml " * 800, "<bml" + " " * 4090, "<a:bml" + " id=" * 1000])
def test_guessing_a_refused_blocks_id_is_linear(text: str) -> None:
    began = time.perf_counter()
    assert _guess_block_id(text) == ""
    assert time.perf_counter() - began < 0.5


def test_guessing_a_refused_blocks_id_finds_it() -> None:
    assert _guess_block_id('<?xml version="1.0"?><b:bml x="1" id="b7" <oops') == "b7"
