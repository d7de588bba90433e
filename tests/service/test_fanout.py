"""The fan-out writes each viewer's frame as WebSocket bytes built once per
tick (``binary_frame``) straight to its socket: the bytes websockets itself
would write, and a real client reads them as frames, in order."""

from __future__ import annotations

import asyncio

from websockets.asyncio.client import connect
from websockets.frames import Frame, Opcode

from realizer.service import codec
from realizer.service.server import FaceAssets, binary_frame
from tests.service.conftest import UNIT
from tests.service.doubles import FakeFace, FakeSession, fake_deform
from tests.service.harness import http_json, running_service

ASSETS = FaceAssets(FakeFace(), fake_deform)


def test_binary_frame_is_what_websockets_writes_for_a_server() -> None:
    for size in (0, 1, 125, 126, 127, 65535, 65536, 300_000):
        payload = bytes(range(256)) * (size // 256) + bytes(size % 256)
        expected = Frame(Opcode.BINARY, payload).serialize(mask=False, extensions=[])
        assert binary_frame(payload) == expected, size


def test_viewers_read_the_directly_written_frames_in_order_and_health_times_the_fan_out() -> None:
    async def scenario() -> tuple[list[list[int]], dict[str, object]]:
        async with running_service(FakeSession, ASSETS) as service:
            url = f"ws://127.0.0.1:{service.port}/view?character=fan&vertices=float32"
            numbers: list[list[int]] = []
            async with (
                connect(url, max_size=None) as one,
                connect(url, max_size=None) as two,
            ):
                for viewer in (one, two):
                    got = []
                    for _ in range(20):
                        message = codec.unpack(await asyncio.wait_for(viewer.recv(), 5 * UNIT))
                        if message["type"] == "frame":
                            got.append(message["n"])
                    numbers.append(got)
                direct = sum(v.direct for v in service.viewers["fan"])
            health = await http_json(service.port, "/health")
            assert direct > 0
            return numbers, health

    numbers, health = asyncio.run(scenario())
    for got in numbers:
        assert len(got) >= 15 and got == sorted(got) and len(set(got)) == len(got)
    clock = health["clock"]
    assert isinstance(clock, dict)
    assert 0 <= clock["written_p50_seconds"] <= clock["written_p99_seconds"]
