"""The ActiveMQ (STOMP) bridge: BML from a broker topic, feedback to another.

``realizer serve --stomp stomp://HOST:PORT`` also takes BML from a topic of
an ActiveMQ broker (or any STOMP 1.2 broker) and publishes the feedback on
a feedback topic, as the BML realizers of the field do: AsapRealizer's
ActiveMQ realizer-port adapter (topics ``asap.bml.request`` and
``asap.bml.feedback``, the BML and the feedback XML as text bodies), Greta's
ActiveMQ BML receiver and BML callback sender (``greta.BML`` and
``greta.output.feedback.BML``, callbacks as ``feedback-type``,
``feedback-id`` and ``feedback-time`` message properties) and the Virtual
Human messaging that SmartBody speaks (topic ``DEFAULT_SCOPE``,
``vrSpeak AGENT RECIPIENT MSGID XML`` in, ``vrAgentBML AGENT RECIPIENT
MSGID start`` and ``... end complete`` out). protocols/stomp.md is the
specification of each layout.

The bridge is one more submitter of the service (the same
:class:`realizer.service.server.Submitter` the WebSocket ``/bml`` endpoint
makes for each connection): its messages go through the same planner
threads, the same stage, the same named limits and the same listener model
(it hears the feedback of every character it has sent a block to), and its
feedback leaves through the same bounded outbox. What the broker hands it
has limits of its own (:class:`StompConfig`): a message over
``limits.message_bytes``, one that is not UTF-8, or one that arrives while
``queued_messages`` are waiting is answered with a ``warningFeedback`` on
the feedback topic and the bridge goes on. A lost broker connection is
logged and retried with exponential backoff (``reconnect_min`` to
``reconnect_max`` seconds); the service keeps serving meanwhile.

The STOMP client is stomp.py (the ``stomp`` extra), imported only here. It
reads frames on its own thread; each message is handed to the event loop
with ``call_soon_threadsafe``, and the blocking calls (connect, send) run on
one thread of the bridge's own, in order.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import random
import threading
import time
import urllib.parse
from collections import OrderedDict, deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

from realizer.service.errors import ConfigError
from realizer.service.limits import valid_character_id
from realizer.service.messages import FeedbackMessage, warning_feedback_xml

if TYPE_CHECKING:
    from websockets.asyncio.server import ServerConnection

    from realizer.service.server import RealizerService, Submitter

logger = logging.getLogger("realizer.service.stomp")

#: Environment variables with the broker's credentials (never on the command line).
LOGIN_VARIABLE = "REALIZER_STOMP_LOGIN"
PASSCODE_VARIABLE = "REALIZER_STOMP_PASSCODE"


@dataclass(frozen=True, slots=True)
class Layout:
    """Where BML and feedback travel and how they are written (protocols/stomp.md)."""

    name: str
    bml_topic: str
    feedback_topic: str
    #: a STOMP ``selector`` for the subscription (the broker filters), or ""
    selector: str = ""


LAYOUTS: dict[str, Layout] = {
    "asap": Layout("asap", "/topic/asap.bml.request", "/topic/asap.bml.feedback"),
    "greta": Layout("greta", "/topic/greta.BML", "/topic/greta.output.feedback.BML"),
    "vhmsg": Layout(
        "vhmsg", "/topic/DEFAULT_SCOPE", "/topic/DEFAULT_SCOPE", "MESSAGE_PREFIX = 'vrSpeak'"
    ),
}


@dataclass(frozen=True, slots=True)
class StompConfig:
    """How the bridge reaches its broker, and its limits.

    ``url``: ``stomp://HOST:PORT``; ``layout``: a key of :data:`LAYOUTS`;
    ``bml_topic``/``feedback_topic`` override the layout's; ``character``:
    the character of BML that names none (the server's default when None).
    """

    url: str
    layout: str = "asap"
    bml_topic: str | None = None
    feedback_topic: str | None = None
    login: str | None = None
    passcode: str | None = None
    character: str | None = None
    #: messages received from the broker and not yet handed to the stage;
    #: one more is refused with a warning
    queued_messages: int = 64
    #: seconds before the first reconnection attempt, doubled up to ``reconnect_max``
    reconnect_min: float = 0.5
    reconnect_max: float = 30.0
    #: seconds a connection attempt may take (TCP and the STOMP CONNECTED frame)
    connect_timeout: float = 10.0
    #: STOMP heart-beats, milliseconds (send, receive): a silent broker is noticed
    heartbeats: tuple[int, int] = (4000, 4000)
    #: vhmsg: message ids remembered to address ``vrAgentBML`` (oldest go first)
    remembered_requests: int = 1024

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ConfigError(
                f"--stomp-layout must be one of {sorted(LAYOUTS)}, not {self.layout!r}"
            )
        self.address()  # raises for a bad URL
        if not 1 <= self.queued_messages <= 100_000:
            raise ConfigError(f"queued_messages must be 1 to 100000, not {self.queued_messages}")
        if not 0 < self.reconnect_min <= self.reconnect_max:
            raise ConfigError("reconnect_min must be positive and at most reconnect_max")
        if self.character is not None and not valid_character_id(self.character):
            raise ConfigError(f"invalid character id {self.character!r}")
        for topic in (self.bml_topic, self.feedback_topic):
            if topic is not None and not topic.startswith(("/topic/", "/queue/")):
                raise ConfigError(f"a destination starts with /topic/ or /queue/, not {topic!r}")

    def address(self) -> tuple[str, int]:
        """(host, port) of :attr:`url`; raises :class:`ConfigError` for a bad one."""
        parts = urllib.parse.urlsplit(self.url)
        if parts.scheme not in ("stomp", "tcp") or not parts.hostname:
            raise ConfigError(f"--stomp takes stomp://HOST:PORT, not {self.url!r}")
        if parts.username or parts.password:
            raise ConfigError(
                f"put the broker's login in ${LOGIN_VARIABLE} and ${PASSCODE_VARIABLE}, "
                "not in the URL"
            )
        try:
            port = parts.port or 61613
        except ValueError as exc:
            raise ConfigError(f"bad port in {self.url!r}") from exc
        return parts.hostname, port

    @property
    def topics(self) -> Layout:
        """The layout with this configuration's topic overrides."""
        base = LAYOUTS[self.layout]
        return Layout(
            base.name,
            self.bml_topic or base.bml_topic,
            self.feedback_topic or base.feedback_topic,
            base.selector,
        )


@dataclass(frozen=True, slots=True)
class Publication:
    """One STOMP SEND the bridge makes."""

    destination: str
    body: str
    headers: dict[str, str]


@dataclass(slots=True)
class _Request:
    """A vhmsg ``vrSpeak`` the bridge handed on: who to answer, by block id."""

    agent: str
    recipient: str
    message_id: str


@dataclass(slots=True)
class BridgeStats:
    """What the bridge did, for logs and tests."""

    received: int = 0
    refused: int = 0  # over a limit or unreadable: answered with a warning
    ignored: int = 0  # not for a realizer (vhmsg: another message type)
    published: int = 0
    dropped: int = 0  # feedback not published: no broker connection
    connections: int = 0
    connection_failures: int = 0


class _Outbox:
    """Stands where a submitter's WebSocket stands: the service's pump awaits
    :meth:`send` for each feedback message (JSON, as ``/bml?format=json``
    writes it), and the bridge publishes it."""

    def __init__(self, bridge: StompBridge) -> None:
        self.bridge = bridge

    async def send(self, text: str) -> None:
        await self.bridge.publish_feedback(text)

    async def close(self, code: int = 1000, reason: str = "") -> None:
        # The service closes a submitter whose feedback backlog is over its
        # limit. The bridge cannot be closed: it loses what was queued (the
        # service already cleared it) and goes on.
        logger.warning("stomp bridge: feedback dropped (%s)", reason)
        self.bridge.reopen()


class StompBridge:
    """Connects a running :class:`RealizerService` to a broker; see the module docstring."""

    def __init__(self, config: StompConfig, clock: Callable[[], float] = time.monotonic) -> None:
        self.config = config
        self.layout = config.topics
        self.stats = BridgeStats()
        self._service: RealizerService | None = None
        self._submitter: Submitter | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._queue: deque[tuple[dict[str, str], bytes]] = deque()
        self._wake = asyncio.Event()
        self._lost = asyncio.Event()
        self._connected = threading.Event()
        self._tasks: list[asyncio.Task[None]] = []
        self._io = ThreadPoolExecutor(max_workers=1, thread_name_prefix="realizer-stomp")
        self._connection: Any = None
        self._stopping = False
        self._requests: OrderedDict[str, _Request] = OrderedDict()
        self._clock = clock

    # -- life cycle ---------------------------------------------------------------

    async def start(self, service: RealizerService) -> None:
        """Join ``service`` as a submitter and connect (retrying in the background)."""
        from realizer.service.server import Submitter

        self._service = service
        self._loop = asyncio.get_running_loop()
        character = self.config.character or service.stage.default_character
        self._submitter = Submitter(cast("ServerConnection", _Outbox(self)), "json", character)
        if self.config.character is not None:
            self._submitter.characters.add(character)
        service.submitters.add(self._submitter)
        # the service's own pump sends the bridge's feedback, in order
        self._tasks.append(service._spawn(service._pump_submitter(self._submitter)))
        self._tasks.append(self._loop.create_task(self._supervise(), name="realizer-stomp"))
        self._tasks.append(self._loop.create_task(self._work(), name="realizer-stomp-work"))

    async def stop(self) -> None:
        """Disconnect from the broker (after the service's shutdown has sent
        the last feedback)."""
        self._stopping = True
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        if self._service is not None and self._submitter is not None:
            self._service.submitters.discard(self._submitter)
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(self._io, self._disconnect)
        self._io.shutdown(wait=False)

    def reopen(self) -> None:
        """The service gave up on the bridge's backlog: take feedback again."""
        if self._submitter is not None:
            self._submitter.closing = False

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    # -- the broker connection ---------------------------------------------------------

    async def _supervise(self) -> None:
        """Connect, wait until the connection is lost, retry with backoff."""
        loop = asyncio.get_running_loop()
        host, port = self.config.address()
        delay = self.config.reconnect_min
        while not self._stopping:
            self._lost.clear()
            try:
                await loop.run_in_executor(self._io, self._connect)
            except Exception as exc:  # refused, timed out, bad login: all retried
                self.stats.connection_failures += 1
                logger.warning(
                    "stomp bridge: cannot connect to %s:%d (%s); retrying in %.1f s",
                    host,
                    port,
                    _reason(exc),
                    delay,
                )
            else:
                self.stats.connections += 1
                logger.info(
                    "stomp bridge: connected to %s:%d, BML from %s, feedback to %s (%s layout)",
                    host,
                    port,
                    self.layout.bml_topic,
                    self.layout.feedback_topic,
                    self.layout.name,
                )
                delay = self.config.reconnect_min
                await self._lost.wait()
                if self._stopping:
                    return
                logger.warning(
                    "stomp bridge: lost the connection to %s:%d; reconnecting in %.1f s",
                    host,
                    port,
                    delay,
                )
            await asyncio.sleep(delay * (1 + 0.2 * random.random()))
            delay = min(delay * 2, self.config.reconnect_max)

    def _connect(self) -> None:
        """On the bridge's thread: a fresh connection, subscribed; raises on failure."""
        import stomp

        self._disconnect()
        host, port = self.config.address()
        connection = stomp.Connection12(
            [(host, port)],
            heartbeats=self.config.heartbeats,
            reconnect_attempts_max=1,
            timeout=self.config.connect_timeout,
            auto_decode=False,  # bytes: the bridge checks size and UTF-8 itself
        )
        listener = _Listener(self, connection)
        connection.set_listener("realizer", listener)
        connection.connect(self.config.login, self.config.passcode, wait=False)
        deadline = time.monotonic() + self.config.connect_timeout
        while not connection.is_connected():
            if time.monotonic() > deadline or not connection.transport.running:
                _close(connection)
                raise TimeoutError("no CONNECTED frame from the broker")
            time.sleep(0.01)
        # subscribed means the broker said so (a receipt): nothing sent after
        # the bridge reports itself connected is missed
        listener.receipt = f"realizer-subscribed-{random.getrandbits(32):08x}"
        headers = {"receipt": listener.receipt}
        if self.layout.selector:
            headers["selector"] = self.layout.selector
        connection.subscribe(self.layout.bml_topic, id="realizer-bml", ack="auto", headers=headers)
        if not listener.subscribed.wait(max(0.0, deadline - time.monotonic())):
            _close(connection)
            raise TimeoutError("no receipt for the subscription")
        self._connection = connection
        self._connected.set()

    def _disconnect(self) -> None:
        connection, self._connection = self._connection, None
        self._connected.clear()
        if connection is not None:
            _close(connection)

    def _connection_lost(self, connection: Any) -> None:
        """From stomp.py's thread: the connection ``connection`` is gone."""
        if connection is not self._connection:
            return  # an older one, already replaced
        self._connected.clear()
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(Exception):
                loop.call_soon_threadsafe(self._lost.set)

    # -- BML in ---------------------------------------------------------------------

    def _received(self, headers: dict[str, str], body: bytes) -> None:
        """From stomp.py's thread: hand the message to the event loop."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(Exception):
                loop.call_soon_threadsafe(self._arrived, headers, body)

    def _arrived(self, headers: dict[str, str], body: bytes) -> None:
        """On the event loop: queue the message, or refuse it over the bound."""
        self.stats.received += 1
        if len(self._queue) >= self.config.queued_messages:
            self._refuse(
                "",
                "CANNOT_CREATE_BEHAVIOR",
                f"limit of {self.config.queued_messages} queued broker messages reached; "
                "message dropped",
            )
            return
        self._queue.append((headers, body))
        self._wake.set()

    async def _work(self) -> None:
        """Hand queued messages to the service one at a time, in order."""
        while True:
            while not self._queue:
                self._wake.clear()
                await self._wake.wait()
            headers, body = self._queue.popleft()
            try:
                await self._handle(headers, body)
            except Exception:  # a bug of the bridge: the next message still goes
                logger.exception("stomp bridge: internal error on a broker message")
                self._refuse("", "CANNOT_CREATE_BEHAVIOR", "internal error")

    async def _handle(self, headers: dict[str, str], body: bytes) -> None:
        assert self._service is not None and self._submitter is not None
        limit = self._service.limits.message_bytes
        if len(body) > limit:
            self._refuse(
                "",
                "PARSING_FAILURE",
                f"message of {len(body)} bytes is over the limit of {limit} bytes "
                "(message_bytes); message dropped",
            )
            return
        try:
            text = body.decode("utf-8")
        except UnicodeDecodeError as exc:
            self._refuse("", "PARSING_FAILURE", f"message is not UTF-8 (byte {exc.start})")
            return
        character = headers.get("characterId") or None
        if self.layout.name == "vhmsg":
            request = self._read_vrspeak(text)
            if request is None:
                return
            text, character = request
        elif self.layout.name == "greta" and text.lstrip()[:1] == "<":
            text = _with_block_id(text, headers.get("content-id", ""))
        if character is not None and not valid_character_id(character):
            self._refuse("", "PARSING_FAILURE", f"invalid characterId header {character[:80]!r}")
            return
        if character is not None and text.lstrip()[:1] == "<":
            text = json.dumps({"type": "bml", "bml": text, "character": character})
        await self._service._on_submit(self._submitter, text)

    def _read_vrspeak(self, text: str) -> tuple[str, str] | None:
        """A vhmsg ``vrSpeak AGENT RECIPIENT MSGID XML``: (the BML, the agent)."""
        op, _, rest = text.partition(" ")
        if op != "vrSpeak":  # other virtual-human traffic on the scope
            self.stats.ignored += 1
            return None
        if "<" not in rest:  # vhmsg URL-encodes the arguments
            rest = urllib.parse.unquote_plus(rest)
        parts = rest.split(None, 3)
        if len(parts) < 4:
            self._refuse("", "PARSING_FAILURE", "vrSpeak needs AGENT RECIPIENT MSGID XML")
            return None
        agent, recipient, message_id, xml = parts
        if not valid_character_id(agent):
            self._refuse("", "PARSING_FAILURE", f"invalid vrSpeak agent {agent[:80]!r}")
            return None
        bml = _bml_of_act(xml)
        if bml is None:
            self._refuse(
                message_id[:200], "PARSING_FAILURE", "vrSpeak XML has no readable <bml> element"
            )
            return None
        bml = _with_block_id(bml, message_id)
        block_id = _root_id(bml) or message_id
        self._requests[block_id] = _Request(agent, recipient, message_id)
        self._requests.move_to_end(block_id)
        while len(self._requests) > self.config.remembered_requests:
            self._requests.popitem(last=False)
        return bml, agent

    def _refuse(self, block_id: str, kind: str, text: str) -> None:
        """A warning about one broker message, to the feedback topic only."""
        assert self._service is not None and self._submitter is not None
        self.stats.refused += 1
        character = self._submitter.default_character
        xml = warning_feedback_xml(block_id, character, kind, text)
        message = FeedbackMessage(
            type="feedback",
            character=character,
            kind="warning",
            block=block_id,
            time=self._service.now(),
            xml=xml,
        )
        self._service._push(self._submitter, json.dumps(message))

    # -- feedback out ---------------------------------------------------------------

    async def publish_feedback(self, text: str) -> None:
        """One message of the service (JSON) as the layout's publications."""
        message = json.loads(text)
        publications = self.render(message)
        if not publications:
            return
        loop = asyncio.get_running_loop()
        try:
            await loop.run_in_executor(self._io, self._publish, publications)
        except RuntimeError:  # the bridge's thread is shut down: stopping
            return

    def render(self, message: dict[str, Any]) -> list[Publication]:
        """What the layout publishes for one service message (protocols/stomp.md)."""
        kind = message.get("type")
        topic = self.layout.feedback_topic
        if self.layout.name == "vhmsg":
            return self._render_vhmsg(message)
        if kind != "feedback":
            return []
        headers = {
            "content-type": "application/xml",
            "characterId": message["character"],
            "feedbackKind": message["kind"],
            "blockId": message["block"],
        }
        if self.layout.name == "greta" and message["kind"] == "blockProgress":
            xml = message["xml"]
            ended = ':end"' in xml or ":end'" in xml
            stopped = "INTERRUPTED" in xml or "REVOKED" in xml
            headers["feedback-type"] = ("stopped" if stopped else "end") if ended else "start"
            headers["feedback-id"] = message["block"]
            headers["feedback-time"] = str(round(message["time"] * 1000))
        return [Publication(topic, message["xml"], headers)]

    def _render_vhmsg(self, message: dict[str, Any]) -> list[Publication]:
        block = message.get("block", "")
        request = self._requests.get(block)
        if message.get("type") == "feedback" and message["kind"] == "blockProgress":
            if request is None or f'"{block}:start"' not in message["xml"]:
                return []
            return [self._vh("vrAgentBML", f"{_vh_ids(request)} start")]
        if message.get("type") == "feedback" and message["kind"] == "warning":
            who = request.agent if request else message["character"]
            return [self._vh("vrRealizerWarning", f"{who} {block or '-'} {message['xml']}")]
        if message.get("type") != "block" or request is None:
            return []
        state = message["state"]
        if state in ("accepted",):
            return []
        self._requests.pop(block, None)
        end = {"done": "complete", "interrupted": "interrupted"}.get(state, "error")
        return [self._vh("vrAgentBML", f"{_vh_ids(request)} end {end}")]

    def _vh(self, prefix: str, arguments: str) -> Publication:
        body = f"{prefix} {urllib.parse.quote_plus(arguments, safe='')}"
        headers = {"ELVISH_SCOPE": "DEFAULT_SCOPE", "MESSAGE_PREFIX": prefix, "VHMSG": "VHMSG"}
        return Publication(self.layout.feedback_topic, body, headers)

    def _publish(self, publications: list[Publication]) -> None:
        """On the bridge's thread: send, or count as dropped without a connection."""
        connection = self._connection
        for item in publications:
            if connection is None or not self._connected.is_set():
                self.stats.dropped += 1
                continue
            try:
                connection.send(item.destination, item.body, headers=item.headers)
                self.stats.published += 1
            except Exception as exc:  # the connection broke under us
                self.stats.dropped += 1
                logger.debug("stomp bridge: send failed: %s", _reason(exc))
                self._connection_lost(connection)


class _Listener:
    """stomp.py's callbacks (on its receiver thread), for one connection."""

    def __init__(self, bridge: StompBridge, connection: Any) -> None:
        self.bridge = bridge
        self.connection = connection
        self.receipt = ""
        self.subscribed = threading.Event()

    def on_receipt(self, frame: Any) -> None:
        if self.receipt and frame.headers.get("receipt-id") == self.receipt:
            self.subscribed.set()

    def on_message(self, frame: Any) -> None:
        body = frame.body if isinstance(frame.body, bytes) else str(frame.body).encode()
        self.bridge._received(dict(frame.headers), body)

    def on_disconnected(self) -> None:
        self.bridge._connection_lost(self.connection)

    def on_heartbeat_timeout(self) -> None:
        self.bridge._connection_lost(self.connection)

    def on_error(self, frame: Any) -> None:
        message = frame.headers.get("message", "") if hasattr(frame, "headers") else ""
        logger.warning("stomp bridge: the broker sent an ERROR frame: %s", str(message)[:200])


# -- helpers -------------------------------------------------------------------------


def _close(connection: Any) -> None:
    """Say goodbye if still connected, then close the socket in any case, so
    that stomp.py's receiver thread ends even when the broker never answers."""
    with contextlib.suppress(Exception):
        connection.disconnect()
    with contextlib.suppress(Exception):
        connection.transport.disconnect_socket()


def _reason(exc: BaseException) -> str:
    return str(exc)[:200] or type(exc).__name__


def _vh_ids(request: _Request) -> str:
    return f"{request.agent} {request.recipient} {request.message_id}"


def _root_id(text: str) -> str:
    from realizer.service.stage import _guess_block_id

    return _guess_block_id(text)


def _with_block_id(text: str, block_id: str) -> str:
    """``text`` (a ``<bml>`` document) with ``id="block_id"`` on its root when
    it has none (Greta's ``content-id``, vhmsg's message id)."""
    if not block_id or _root_id(text) or not valid_character_id(block_id):
        return text
    start = text.find("<bml")
    while start >= 0 and text[start + 4 : start + 5] not in (" ", ">", "/", "\t", "\n", "\r"):
        start = text.find("<bml", start + 1)
    if start < 0:
        return text
    return f'{text[: start + 4]} id="{block_id}"{text[start + 4 :]}'


def _bml_of_act(xml: str) -> str | None:
    """The ``<bml>`` element of a vhmsg ``<act>`` (or the document itself when it
    is a ``<bml>``), as text; None when there is none or the XML does not parse."""
    from lxml import etree

    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False
    )
    try:
        root = etree.fromstring(xml.strip().encode("utf-8"), parser)
    except etree.XMLSyntaxError:
        return None
    if root is None:
        return None
    found = root if etree.QName(root).localname == "bml" else None
    if found is None:
        for element in root.iter():
            if isinstance(element.tag, str) and etree.QName(element).localname == "bml":
                found = element
                break
    if found is None:
        return None
    return str(etree.tostring(found, encoding="unicode"))


__all__ = ["LAYOUTS", "BridgeStats", "Layout", "Publication", "StompBridge", "StompConfig"]
