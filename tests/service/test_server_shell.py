"""The asyncio shell with a test double of the session: HTTP on the same
port, tokens, connection-level refusals, the viewer mailbox.

The behaviour of the whole realizer over the wire is checked with the real
session in test_end_to_end.py.
"""

from __future__ import annotations

import asyncio
import json

import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from realizer import __version__
from realizer.service import codec
from realizer.service.errors import ConfigError
from realizer.service.limits import ServiceLimits
from realizer.service.server import FaceAssets, ServiceConfig, Viewer
from tests.service.conftest import UNIT
from tests.service.doubles import FakeFace, FakeSession, fake_deform, smile_bml
from tests.service.harness import http_get, http_json, running_service

ASSETS = FaceAssets(FakeFace(), fake_deform)


def test_health_version_and_the_viewer_page_are_plain_http_on_the_same_port() -> None:
    async def scenario() -> None:
        async with running_service(FakeSession, ASSETS) as service:
            health = await http_json(service.port, "/health")
            version = await http_json(service.port, "/version")
            status, kind, page = await http_get(service.port, "/")
            missing, _, _ = await http_get(service.port, "/../etc/passwd")
        assert health["status"] == "ok" and health["fps"] == 60.0
        assert version == {"realizer": __version__, "protocol": 1, "fps": 60.0}
        assert status == 200 and kind.startswith("text/html") and b"<canvas" in page
        assert missing == 404

    asyncio.run(scenario())


def test_without_tokens_the_service_refuses_a_public_address() -> None:
    with pytest.raises(ConfigError, match="without tokens"):
        ServiceConfig(host="0.0.0.0")
    assert ServiceConfig(host="0.0.0.0", view_token="v").host == "0.0.0.0"
    assert ServiceConfig(host="::1").host == "::1"


def test_a_view_token_may_view_but_not_submit_and_no_token_may_do_neither() -> None:
    async def scenario() -> None:
        async with running_service(
            FakeSession, ASSETS, submit_token="s3cret", view_token="look"
        ) as service:
            base = f"ws://127.0.0.1:{service.port}"
            async with connect(f"{base}/view?token=look") as viewer:
                assert codec.unpack(await viewer.recv())["type"] == "mesh"
            async with connect(
                f"{base}/bml", additional_headers={"Authorization": "Bearer s3cret"}
            ) as submitter:
                await submitter.send(smile_bml())
                assert "predictionFeedback" in await submitter.recv()
            for path, status in (("/bml?token=look", 403), ("/bml", 401), ("/view", 401)):
                with pytest.raises(InvalidStatus) as refused:
                    async with connect(base + path):
                        pass
                assert refused.value.response.status_code == status

    asyncio.run(scenario())


def test_binary_sent_to_the_submitter_endpoint_closes_it_with_1003_and_a_reason() -> None:
    async def scenario() -> None:
        async with running_service(FakeSession, ASSETS) as service:
            async with connect(f"ws://127.0.0.1:{service.port}/bml") as submitter:
                await submitter.send(b"\x00\x01")
                with pytest.raises(ConnectionClosed):
                    await asyncio.wait_for(submitter.recv(), 5 * UNIT)
            assert submitter.close_code == 1003 and "text" in (submitter.close_reason or "")

    asyncio.run(scenario())


def test_viewers_over_the_per_character_limit_are_closed_with_1013() -> None:
    async def scenario() -> None:
        limits = ServiceLimits(viewers_per_character=1)
        async with running_service(FakeSession, ASSETS, limits=limits) as service:
            base = f"ws://127.0.0.1:{service.port}/view?character=Alice"
            async with connect(base) as first, connect(base) as second:
                assert codec.unpack(await first.recv())["type"] == "mesh"
                with pytest.raises(ConnectionClosed):
                    await asyncio.wait_for(second.recv(), 5 * UNIT)
                assert second.close_code == 1013
                assert "1 viewers per character" in (second.close_reason or "")

    asyncio.run(scenario())


def test_a_bad_subscribe_is_answered_with_an_error_message_and_the_viewer_goes_on() -> None:
    async def scenario() -> None:
        async with (
            running_service(FakeSession, ASSETS) as service,
            connect(f"ws://127.0.0.1:{service.port}/view") as viewer,
        ):

            async def next_message() -> dict[str, object]:
                return codec.unpack(await asyncio.wait_for(viewer.recv(), 5 * UNIT))

            assert (await next_message())["type"] == "mesh"
            await viewer.send(json.dumps({"type": "subscribe", "vertices": "png"}))
            while (await next_message())["type"] != "error":
                pass
            await viewer.send(json.dumps({"type": "subscribe", "character": "Bob"}))
            while (message := await next_message())["type"] != "mesh":
                pass
            frame = await next_message()
            assert message["character"] == "Bob" and frame["character"] == "Bob"

    asyncio.run(scenario())


def test_the_submitter_json_mode_says_welcome_and_reports_block_states() -> None:
    async def scenario() -> None:
        async with (
            running_service(FakeSession, ASSETS) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml?format=json") as submitter,
        ):
            welcome = json.loads(await submitter.recv())
            await submitter.send(json.dumps({"type": "bml", "bml": smile_bml("s1")}))
            received: list[dict[str, object]] = []
            while not received or received[-1].get("state") not in ("done", "rejected"):
                received.append(json.loads(await asyncio.wait_for(submitter.recv(), 5 * UNIT)))
        assert welcome["type"] == "welcome" and welcome["limits"]["queued_blocks"] == 32
        states = [m["state"] for m in received if m["type"] == "block"]
        kinds = [m["kind"] for m in received if m["type"] == "feedback"]
        assert states == ["accepted", "done"]
        assert kinds == ["prediction", "blockProgress", "blockProgress"]

    asyncio.run(scenario())


def test_a_viewer_mailbox_keeps_only_the_newest_frame() -> None:
    viewer = Viewer(connection=None, character="a", options=None)  # type: ignore[arg-type]
    for frame in (b"1", b"2", b"3"):
        viewer.offer(frame)
    assert viewer.latest == b"3" and viewer.replaced == 2 and viewer.offered == 3


def test_the_python_client_submits_views_and_decodes_vertex_deltas() -> None:
    from realizer.client import SubmitClient, ViewClient
    from tests.service.browser import service_in_thread

    with service_in_thread(FakeSession, ASSETS) as service:
        url = f"ws://127.0.0.1:{service.port}"
        with (
            ViewClient(url, character="Ann", vertices="int16") as view,
            SubmitClient(url, character="Ann") as client,
        ):
            seen: list[dict[str, object]] = []
            state = client.run_block(smile_bml("c1"), on_message=seen.append, timeout=5 * UNIT)
            lifted = [
                view.vertices(f)[0, 1]
                for f in view.frames(count=int(120 * UNIT), timeout=5 * UNIT)
                if view.faps(f)
            ]
            view.subscribe(character="Ben")
            while view.receive(5 * UNIT)["type"] != "mesh":
                pass
    assert state == "done"
    assert [m["state"] for m in seen if m["type"] == "block"] == ["accepted", "done"]
    assert view.mesh["character"] == "Ben"
    # FakeSession: FAP 12 = 100 lifts vertex 0 by 100 x 1e-5 m while a block runs
    assert lifted and all(abs(y - 1e-3) <= codec.DELTA_STEP for y in lifted)


class _Closing:
    """Stands in for a connection: records the close it is asked for."""

    def __init__(self) -> None:
        self.closed: tuple[int, str] | None = None

    async def close(self, code: int, reason: str) -> None:
        self.closed = (code, reason)


def test_a_submitter_over_its_feedback_backlog_is_closed_with_1008() -> None:
    from realizer.service.server import RealizerService, Submitter
    from realizer.service.stage import Stage

    async def scenario() -> _Closing:
        limits = ServiceLimits(feedback_backlog=3)
        service = RealizerService(
            ServiceConfig(port=0, limits=limits), Stage(FakeSession, limits), ASSETS
        )
        connection = _Closing()
        submitter = Submitter(connection, "xml", "default")  # type: ignore[arg-type]
        for n in range(5):  # a burst over the backlog, just queued: not a slow reader yet
            service._push(submitter, f"<feedback n='{n}'/>")
        assert not submitter.closing and len(submitter.outbox) == 5
        # the oldest message has waited feedback_stall_seconds: this reader is stuck
        queued_at, text = submitter.outbox[0]
        submitter.outbox[0] = (queued_at - limits.feedback_stall_seconds, text)
        service._push(submitter, "<feedback n='5'/>")
        await asyncio.sleep(0)
        assert submitter.closing and not submitter.outbox
        return connection

    connection = asyncio.run(scenario())
    assert connection.closed is not None and connection.closed[0] == 1008
    assert "backlog over 3" in connection.closed[1]


def test_a_burst_is_bounded_at_four_times_the_backlog() -> None:
    from realizer.service.server import RealizerService, Submitter
    from realizer.service.stage import Stage

    async def scenario() -> tuple[_Closing, int]:
        limits = ServiceLimits(feedback_backlog=3)
        service = RealizerService(
            ServiceConfig(port=0, limits=limits), Stage(FakeSession, limits), ASSETS
        )
        connection = _Closing()
        submitter = Submitter(connection, "xml", "default")  # type: ignore[arg-type]
        queued = []
        for n in range(20):
            service._push(submitter, f"<feedback n='{n}'/>")
            queued.append(len(submitter.outbox))
        await asyncio.sleep(0)
        return connection, max(queued)

    connection, most = asyncio.run(scenario())
    assert most == 12
    assert connection.closed is not None and connection.closed[0] == 1008


def test_a_viewer_flooding_subscribes_is_closed_with_1008() -> None:
    from realizer.service.server import RealizerService
    from realizer.service.stage import Stage

    async def scenario() -> _Closing:
        limits = ServiceLimits(subscribe_backlog=2)
        service = RealizerService(
            ServiceConfig(port=0, limits=limits), Stage(FakeSession, limits), ASSETS
        )
        connection = _Closing()
        viewer = Viewer(connection, "a", None)  # type: ignore[arg-type]
        for _ in range(3):
            service._control(viewer, b"mesh")
        await asyncio.sleep(0)
        assert viewer.closing and len(viewer.control) == 2
        return connection

    connection = asyncio.run(scenario())
    assert connection.closed == (1008, "too many subscribe requests")
