"""Nothing to say, nothing sent: an unchanged frame costs a viewer a `same` of 21 bytes.

A real server (the asyncio shell with the session double) and real
WebSocket viewers of every format that ask for it (``same=true``): while
the face rests, every tick brings a `same` of at most 21 bytes; when the
FAPs change, a whole frame; after a subscription, a whole frame first. A
viewer that does not ask (a version-1 client) still gets a frame every tick.
"""

from __future__ import annotations

import asyncio
import json

from websockets.asyncio.client import connect

from realizer.service import codec
from realizer.service.server import FaceAssets
from tests.service.conftest import UNIT
from tests.service.doubles import FakeFace, FakeSession, fake_deform, smile_bml
from tests.service.harness import running_service

ASSETS = FaceAssets(FakeFace(), fake_deform)


async def messages(viewer: object, count: int) -> list[bytes]:
    got = []
    for _ in range(count):
        data = await asyncio.wait_for(viewer.recv(), 5 * UNIT)  # type: ignore[attr-defined]
        got.append(data)
    return got


#: The largest `same` message, bytes (msgpack; the WebSocket header adds 2).
SAME_BYTES = 21


def test_a_resting_face_costs_every_kind_of_viewer_21_bytes_a_tick() -> None:
    async def scenario() -> dict[str, list[bytes]]:
        async with running_service(FakeSession, ASSETS) as service:
            base = f"ws://127.0.0.1:{service.port}/view?character=rest&same=true"
            seen = {}
            for kind in ("none", "int16", "float32"):
                async with connect(f"{base}&vertices={kind}", max_size=None) as viewer:
                    seen[kind] = await messages(viewer, 30)
            return seen

    for kind, data in asyncio.run(scenario()).items():
        decoded = [codec.unpack(d) for d in data]
        assert decoded[0]["type"] == "mesh", kind
        assert decoded[1]["type"] == "frame", kind  # the first frame comes whole
        sames = decoded[2:]
        assert [m["type"] for m in sames] == ["same"] * len(sames), kind
        assert all(len(d) <= SAME_BYTES for d in data[2:]), kind
        numbers = [m["n"] for m in decoded[1:]]
        assert numbers == sorted(numbers) and len(set(numbers)) == len(numbers)


def test_a_changed_face_is_sent_whole_and_a_resubscribed_viewer_gets_a_whole_frame() -> None:
    async def scenario() -> tuple[list[dict[str, object]], list[dict[str, object]]]:
        async with running_service(FakeSession, ASSETS) as service:
            base = f"ws://127.0.0.1:{service.port}"
            async with (
                connect(
                    f"{base}/view?character=Ann&vertices=int16&same=true", max_size=None
                ) as viewer,
                connect(f"{base}/bml") as submitter,
            ):
                before = [codec.unpack(d) for d in await messages(viewer, 5)]
                await submitter.send(
                    json.dumps({"type": "bml", "bml": smile_bml("c1"), "character": "Ann"})
                )
                during: list[dict[str, object]] = []
                for _ in range(int(300 * UNIT)):  # at most 5 s of frames
                    during.append(codec.unpack(await asyncio.wait_for(viewer.recv(), 5 * UNIT)))
                    if during[-1]["type"] == "frame" and during[-1]["fap"]["ids"]:  # type: ignore[index]
                        break
                await viewer.send('{"type": "subscribe", "character": "Ben"}')
                after: list[dict[str, object]] = []
                while len(after) < 3:
                    message = codec.unpack(await asyncio.wait_for(viewer.recv(), 5 * UNIT))
                    if message["type"] == "mesh" or after:
                        after.append(message)
                return before + during, after

    stream, after = asyncio.run(scenario())
    lit = [m for m in stream if m["type"] == "frame" and m["fap"]["ids"]]  # type: ignore[index]
    assert lit and "delta" in lit[0]  # the change came as a whole frame with its vertices
    assert [m["type"] for m in after[:2]] == ["mesh", "frame"]


def test_a_same_never_replaces_a_frame_waiting_in_the_mailbox() -> None:
    from realizer.service.server import Viewer

    class Closed:
        class protocol:  # stands in for websockets' protocol object
            state = None

    viewer = Viewer(Closed(), "c", None)  # type: ignore[arg-type]
    viewer.offer(b"frame 1")  # not writable: into the mailbox
    viewer.offer_same(b"same 2")
    assert viewer.latest == b"frame 1"
    viewer.latest = None
    viewer.offer_same(b"same 3")
    viewer.offer_same(b"same 4")  # a same may replace a same
    assert viewer.latest == b"same 4" and viewer.latest_same
    viewer.offer(b"frame 5")
    assert viewer.latest == b"frame 5" and not viewer.latest_same


def test_a_viewer_that_does_not_ask_for_same_gets_a_whole_frame_every_tick() -> None:
    async def scenario() -> list[dict[str, object]]:
        async with running_service(FakeSession, ASSETS) as service:
            url = f"ws://127.0.0.1:{service.port}/view?character=old"
            async with connect(url, max_size=None) as viewer:
                return [codec.unpack(d) for d in await messages(viewer, 20)]

    decoded = asyncio.run(scenario())
    assert [m["type"] for m in decoded] == ["mesh"] + ["frame"] * 19


def test_a_subscribe_message_turns_same_on_and_off() -> None:
    async def scenario() -> tuple[list[str], list[str]]:
        async with running_service(FakeSession, ASSETS) as service:
            url = f"ws://127.0.0.1:{service.port}/view?character=sw"
            async with connect(url, max_size=None) as viewer:
                await messages(viewer, 3)
                await viewer.send('{"type": "subscribe", "same": true}')
                on = [codec.unpack(d)["type"] for d in await messages(viewer, 20)]
                await viewer.send('{"type": "subscribe", "same": false}')
                off = [codec.unpack(d)["type"] for d in await messages(viewer, 20)]
                return on, off

    on, off = asyncio.run(scenario())
    assert on.count("same") >= 10  # after the new mesh and its first whole frame
    assert off[-10:] == ["frame"] * 10


def test_coded_viewers_with_same_decode_every_frame_when_another_coded_viewer_joins() -> None:
    """The coded stream is one per character: a `same` never skips a coded
    frame a coded viewer needs to decode the next (a joining viewer's intra
    frame goes to every coded viewer)."""
    from realizer.face.fapcoding import FapStreamDecoder

    async def scenario() -> list[tuple[str, bool | None]]:
        async with running_service(FakeSession, ASSETS) as service:
            base = f"ws://127.0.0.1:{service.port}"
            view = f"{base}/view?character=Cod&coded=true&same=true"
            decoder = FapStreamDecoder()
            seen: list[tuple[str, bool | None]] = []  # (type, decoded) of viewer A
            async with (
                connect(view, max_size=None) as first,
                connect(f"{base}/bml") as submitter,
            ):

                async def read(count: int) -> None:
                    for _ in range(count):
                        message = codec.unpack(await asyncio.wait_for(first.recv(), 5 * UNIT))
                        if message["type"] == "frame":
                            ok = decoder.decode(
                                message["coded"], message["n"], message.get("codedRef")
                            )
                            seen.append(("frame", ok is not None))
                        elif message["type"] == "same":
                            seen.append(("same", None))

                await read(10)  # the mesh, an intra frame, then sames
                async with connect(view, max_size=None) as second:
                    await second.recv()  # its mesh
                    await read(5)
                    await submitter.send(
                        json.dumps({"type": "bml", "bml": smile_bml("c2"), "character": "Cod"})
                    )
                    await read(40)
            return seen

    seen = asyncio.run(scenario())
    frames = [ok for kind, ok in seen if kind == "frame"]
    assert any(kind == "same" for kind, _ in seen)
    # the first intra frame, the joining viewer's intra frame, the smile: all decoded
    assert len(frames) >= 3 and all(frames), seen


def test_the_python_client_repeats_the_last_frame_for_a_same_even_after_receive() -> None:
    from realizer.client import ViewClient
    from tests.service.browser import service_in_thread

    with (
        service_in_thread(FakeSession, ASSETS, fps=60.0) as service,
        ViewClient(f"ws://127.0.0.1:{service.port}", character="py") as view,
    ):
        first = view.receive(5 * UNIT)  # read raw: the whole first frame
        frames = list(view.frames(5, timeout=5 * UNIT))
    assert first["type"] == "frame"
    assert all(f["same"] and f["fap"] == first["fap"] for f in frames)
    numbers = [first["n"], *(f["n"] for f in frames)]
    assert numbers == sorted(numbers) and len(set(numbers)) == 6
