"""The ActiveMQ (STOMP) bridge end to end, with a real broker (issue 12).

One ActiveMQ broker (Debian's, Java) is started per module on a free
loopback port (tests/service/activemq.py); each test runs the real service
with its bridge, a STOMP client (stomp.py, as a planner would use it)
publishes BML on the BML topic and reads the feedback topic, and a viewer
watches frames over the WebSocket. Waits are multiples of UNIT.
"""

from __future__ import annotations

import asyncio
import queue
import random
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from websockets.asyncio.client import connect

from realizer.service import codec
from realizer.service.errors import ConfigError
from tests.service.activemq import Broker, missing, start_broker
from tests.service.conftest import UNIT
from tests.service.harness import running_service
from tests.service.test_end_to_end import (
    MOUTH_CORNER_FAPS,
    real_assets,
    real_sessions,
    smile,
)

stomp = pytest.importorskip("stomp", reason="the stomp extra (stomp.py) is not installed")

from realizer.service.stomp import StompBridge, StompConfig  # noqa: E402

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    why = missing()
    if why is not None:
        pytest.skip(why)
    started = start_broker(tmp_path_factory.mktemp("activemq"))
    try:
        yield started
    finally:
        started.stop()


class Client:
    """A STOMP client of the broker: what it receives waits in a queue."""

    def __init__(self, port: int) -> None:
        self.received: queue.Queue[tuple[dict[str, str], str]] = queue.Queue()
        self.receipts: queue.Queue[str] = queue.Queue()
        self.connection = stomp.Connection12([("127.0.0.1", port)])
        self.connection.set_listener("test", self)
        self.connection.connect(wait=True)

    def on_message(self, frame: Any) -> None:
        self.received.put((dict(frame.headers), frame.body))

    def on_receipt(self, frame: Any) -> None:
        self.receipts.put(frame.headers["receipt-id"])

    def subscribe(self, destination: str, selector: str = "") -> None:
        receipt = f"r{random.getrandbits(32)}"
        headers = {"receipt": receipt, **({"selector": selector} if selector else {})}
        self.connection.subscribe(destination, id=receipt, headers=headers)
        assert self.receipts.get(timeout=10 * UNIT) == receipt

    def send(self, destination: str, body: str | bytes, **headers: str) -> None:
        self.connection.send(destination, body, headers=headers)

    async def next(self, timeout: float = 10 * UNIT) -> tuple[dict[str, str], str]:
        return await asyncio.to_thread(self.received.get, True, timeout)

    def close(self) -> None:
        self.connection.disconnect()


def feedback_id(xml: str) -> str:
    match = re.search(r'\sid="([^"]*)"', xml)
    return match.group(1) if match else ""


async def until_connected(bridge: StompBridge, timeout: float = 15 * UNIT) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not bridge.connected:
        assert loop.time() < deadline, "the bridge did not connect"
        await asyncio.sleep(0.02)


async def until_end(client: Client, block: str) -> list[tuple[dict[str, str], str]]:
    """Messages of the feedback topic up to the block's ``blockProgress`` end."""
    got = []
    while True:
        headers, body = await client.next()
        got.append((headers, body))
        if "blockProgress" in body and feedback_id(body) == f"{block}:end":
            return got


def corners(frame: dict[str, Any]) -> float:
    faps = codec.decode_faps(frame["fap"]) if "fap" in frame else {}
    return max((abs(v) for k, v in faps.items() if k in MOUTH_CORNER_FAPS), default=0.0)


def test_bml_from_the_broker_is_realized_with_its_feedback_on_the_feedback_topic(
    broker: Broker,
) -> None:
    bridge = StompBridge(StompConfig(broker.url))
    topics = bridge.layout

    async def scenario() -> dict[str, Any]:
        client = Client(broker.port)
        client.subscribe(topics.feedback_topic)
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/view?character=Alice") as viewer,
        ):
            await bridge.start(service)
            frames: list[dict[str, Any]] = []

            async def watch() -> None:
                async for data in viewer:
                    frames.append(codec.unpack(data))  # type: ignore[arg-type]

            watcher = asyncio.get_running_loop().create_task(watch())
            try:
                await until_connected(bridge)
                # the block names its character, as AsapRealizer's clients write it
                client.send(topics.bml_topic, smile("s1", 0.2, 0.8, "Alice"))
                first = await until_end(client, "s1")
                # hostile input: malformed XML, then a message over message_bytes
                client.send(topics.bml_topic, '<bml xmlns="x" id="bad"><gaze')
                malformed = await client.next()
                big = "<bml>" + " " * (service.limits.message_bytes + 10) + "</bml>"
                client.send(topics.bml_topic, big)
                oversized = await client.next()
                # ... and the bridge keeps working: a block for a character named by header
                client.send(topics.bml_topic, smile("s2", 0.0, 0.3), characterId="Bob")
                second = await until_end(client, "s2")
            finally:
                watcher.cancel()
                await bridge.stop()
                client.close()
            return {
                "first": first,
                "malformed": malformed,
                "oversized": oversized,
                "second": second,
                "frames": frames,
                "stats": bridge.stats,
            }

    got = asyncio.run(scenario())
    first = got["first"]
    bodies = [body for _, body in first]
    ids = [feedback_id(body) for body in bodies]
    # the prediction first, then the block's start, the smile's sync points in
    # order, and the block's end last
    assert bodies[0].lstrip().startswith("<predictionFeedback")
    assert ids[1] == "s1:start"
    syncs = [i for i, b in zip(ids, bodies, strict=True) if "syncPointProgress" in b]
    assert syncs == [
        "s1:smile:start",
        "s1:smile:attackPeak",
        "s1:smile:relax",
        "s1:smile:end",
    ]
    assert ids[-1] == "s1:end" and ids.index("s1:smile:end") < ids.index("s1:end")
    times = [float(m) for m in re.findall(r'globalTime="([0-9.eE+-]+)"', " ".join(bodies[1:]))]
    assert times == sorted(times)
    for headers, _ in first:
        assert headers["characterId"] == "Alice"
        assert headers["blockId"] == "s1"
    # the hostile messages are answered with warnings on the feedback topic
    headers, body = got["malformed"]
    assert headers["feedbackKind"] == "warning" and 'type="PARSING_FAILURE"' in body
    assert 'id="bad"' in body
    headers, body = got["oversized"]
    assert headers["feedbackKind"] == "warning" and "message_bytes" in body
    # the next block was realized for the character its header named
    assert feedback_id(got["second"][-1][1]) == "s2:end"
    assert all(h["characterId"] == "Bob" for h, _ in got["second"])
    assert got["stats"].refused == 1  # the oversized one (the malformed one: the stage)
    # meanwhile the viewer of Alice saw her smile, at its times
    start = float(
        re.search(r'globalTime="([0-9.]+)"', bodies[ids.index("s1:smile:start")]).group(1)  # type: ignore[union-attr]
    )
    end = float(
        re.search(r'globalTime="([0-9.]+)"', bodies[ids.index("s1:smile:end")]).group(1)  # type: ignore[union-attr]
    )
    frames = [f for f in got["frames"] if f.get("type") == "frame"]
    during = [f for f in frames if start + 0.1 <= f["t"] <= end - 0.1]
    before = [f for f in frames if f["t"] < start - 1e-6]
    assert during and before
    assert all(corners(f) > 0 for f in during)
    assert all(corners(f) == 0 for f in before)


class Proxy:
    """A TCP forwarder between the bridge and the broker, to cut the line."""

    def __init__(self, target: int) -> None:
        self.target = target
        self.writers: list[asyncio.StreamWriter] = []
        self.server: asyncio.Server | None = None

    async def start(self) -> int:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return int(self.server.sockets[0].getsockname()[1])

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.target)
        except OSError:
            writer.close()
            return
        self.writers += [writer, up_writer]

        async def pipe(src: asyncio.StreamReader, dst: asyncio.StreamWriter) -> None:
            try:
                while data := await src.read(65536):
                    dst.write(data)
                    await dst.drain()
            except (OSError, asyncio.CancelledError):
                pass
            finally:
                dst.close()

        await asyncio.gather(pipe(reader, up_writer), pipe(up_reader, writer))

    def cut(self) -> None:
        for writer in self.writers:
            writer.transport.abort()
        self.writers.clear()

    async def close(self) -> None:
        self.cut()
        if self.server is not None:
            self.server.close()


def test_a_lost_broker_connection_is_retried_and_the_service_keeps_serving(
    broker: Broker,
) -> None:
    async def scenario() -> tuple[Any, list[str], list[str]]:
        proxy = Proxy(broker.port)
        port = await proxy.start()
        bridge = StompBridge(
            StompConfig(f"stomp://127.0.0.1:{port}", reconnect_min=0.1, heartbeats=(500, 500))
        )
        client = Client(broker.port)
        client.subscribe(bridge.layout.feedback_topic)
        async with (
            running_service(real_sessions(), real_assets()) as service,
            connect(f"ws://127.0.0.1:{service.port}/bml") as submitter,
        ):
            await bridge.start(service)
            try:
                await until_connected(bridge)
                client.send(bridge.layout.bml_topic, smile("a1", 0.0, 0.2, "Carol"))
                before = [feedback_id(b) for _, b in await until_end(client, "a1")]
                proxy.cut()  # the broker is gone, as far as the bridge can tell
                loop = asyncio.get_running_loop()
                deadline = loop.time() + 10 * UNIT
                # the service goes on serving its WebSocket clients meanwhile
                await submitter.send(smile("w1", 0, 0.05))
                while "predictionFeedback" not in await asyncio.wait_for(
                    submitter.recv(), 5 * UNIT
                ):
                    pass
                while bridge.stats.connections < 2:
                    assert loop.time() < deadline, "the bridge did not reconnect"
                    await asyncio.sleep(0.05)
                await until_connected(bridge)
                client.send(bridge.layout.bml_topic, smile("a2", 0.0, 0.2, "Carol"))
                after = [feedback_id(b) for _, b in await until_end(client, "a2")]
            finally:
                await bridge.stop()
                await proxy.close()
                client.close()
        return bridge.stats, before, after

    stats, before, after = asyncio.run(scenario())
    assert stats.connections >= 2
    assert "a1:start" in before and after[-1] == "a2:end"


def test_without_a_broker_the_bridge_retries_and_the_service_runs() -> None:
    from tests.service.activemq import free_port

    async def scenario() -> tuple[int, bool, int]:
        bridge = StompBridge(
            StompConfig(
                f"stomp://127.0.0.1:{free_port()}",
                reconnect_min=0.05,
                reconnect_max=0.2,
                queued_messages=2,
            )
        )
        async with running_service(real_sessions(), real_assets()) as service:
            await bridge.start(service)
            async with connect(f"ws://127.0.0.1:{service.port}/bml") as submitter:
                await asyncio.sleep(1.0 * UNIT)
                await submitter.send(smile("x", 0, 0.05))
                answered = "predictionFeedback" in await asyncio.wait_for(
                    submitter.recv(), 5 * UNIT
                )
            # five messages arrive at once (as stomp.py's thread hands them
            # over): two wait, three are over queued_messages and refused
            for n in range(5):
                bridge._arrived({}, smile(f"q{n}", 0, 0.05).encode())
            refused = bridge.stats.refused
            await bridge.stop()
            return bridge.stats.connection_failures, answered, refused

    failures, answered, refused = asyncio.run(scenario())
    assert failures >= 2 and answered
    assert refused == 3


def test_the_greta_layout_carries_its_callback_properties(broker: Broker) -> None:
    bridge = StompBridge(StompConfig(broker.url, layout="greta"))

    async def scenario() -> list[tuple[dict[str, str], str]]:
        client = Client(broker.port)
        client.subscribe(bridge.layout.feedback_topic)
        async with running_service(real_sessions(), real_assets()) as service:
            await bridge.start(service)
            try:
                await until_connected(bridge)
                # Greta's senders may leave the id to the content-id property
                document = smile("unused", 0.0, 0.2).replace(' id="unused"', "", 1)
                client.send(bridge.layout.bml_topic, document, **{"content-id": "g1"})
                return await until_end(client, "g1")
            finally:
                await bridge.stop()
                client.close()

    got = asyncio.run(scenario())
    assert bridge.layout.bml_topic == "/topic/greta.BML"
    progress = [(h["feedback-type"], h["feedback-id"]) for h, _ in got if "feedback-type" in h]
    assert progress == [("start", "g1"), ("end", "g1")]
    assert all(int(h["feedback-time"]) >= 0 for h, _ in got if "feedback-type" in h)


def test_the_vhmsg_layout_answers_vrspeak_with_vragentbml(broker: Broker) -> None:
    bridge = StompBridge(StompConfig(broker.url, layout="vhmsg"))
    scope = bridge.layout.bml_topic

    async def scenario() -> list[str]:
        client = Client(broker.port)
        client.subscribe(scope, "MESSAGE_PREFIX = 'vrAgentBML'")
        vh = {"ELVISH_SCOPE": "DEFAULT_SCOPE"}
        async with running_service(real_sessions(), real_assets()) as service:
            await bridge.start(service)
            try:
                await until_connected(bridge)
                # other virtual-human traffic on the scope is not for the realizer
                client.send(scope, "vrAllCall", MESSAGE_PREFIX="vrAllCall", **vh)
                act = (
                    '<?xml version="1.0" encoding="UTF-8"?><act>'
                    '<participant id="Brad" role="actor"/>'
                    '<bml><head id="h1" type="NOD" start="0" end="0.4"/></bml></act>'
                )
                client.send(
                    scope, f"vrSpeak Brad user 1000037 {act}", MESSAGE_PREFIX="vrSpeak", **vh
                )
                bodies = []
                while not bodies or " end " not in bodies[-1].replace("+", " "):
                    bodies.append((await client.next())[1])
                return bodies
            finally:
                await bridge.stop()
                client.close()

    bodies = asyncio.run(scenario())
    from urllib.parse import unquote_plus

    decoded = [b.split(" ", 1)[0] + " " + unquote_plus(b.split(" ", 1)[1]) for b in bodies]
    assert decoded == [
        "vrAgentBML Brad user 1000037 start",
        "vrAgentBML Brad user 1000037 end complete",
    ]


def test_credentials_are_refused_in_the_url_and_bad_settings_are_named() -> None:
    with pytest.raises(ConfigError, match="REALIZER_STOMP_LOGIN"):
        StompConfig("stomp://user:secret@127.0.0.1:61613")
    with pytest.raises(ConfigError, match="stomp://HOST:PORT"):
        StompConfig("http://127.0.0.1:61613")
    with pytest.raises(ConfigError, match="layout"):
        StompConfig("stomp://127.0.0.1:61613", layout="jms")
    with pytest.raises(ConfigError, match="/topic/"):
        StompConfig("stomp://127.0.0.1:61613", bml_topic="bml")


def test_realizer_serve_with_stomp_bridges_the_broker(broker: Broker) -> None:
    from tests.service.process import serve_process

    client = Client(broker.port)
    client.subscribe("/topic/asap.bml.feedback")
    try:
        # credentials come from the environment (ActiveMQ without users ignores them)
        env = {"REALIZER_STOMP_LOGIN": "planner", "REALIZER_STOMP_PASSCODE": "secret"}
        with serve_process("--stomp", broker.url, env=env) as server:
            loop_deadline = 30 * UNIT
            waited = 0.0
            while not any("stomp bridge: connected" in line for line in server.stderr):
                assert waited < loop_deadline, "".join(server.stderr)
                time.sleep(0.05)
                waited += 0.05
            client.send("/topic/asap.bml.request", smile("c1", 0.0, 0.2))
            got = asyncio.run(until_end(client, "c1"))
        assert server.process.returncode == 0
        assert feedback_id(got[-1][1]) == "c1:end"
        assert not any("secret" in line for line in server.stderr)
    finally:
        client.close()
