"""Python clients of the service's two endpoints (protocols/): blocking and asyncio.

Blocking (websockets' threading client, no event loop needed)::

    from realizer.client import SubmitClient, ViewClient

    with SubmitClient("ws://127.0.0.1:8765", character="Alice") as client:
        state = client.run_block(open("smile.xml").read(), on_event=print)

    with ViewClient("ws://127.0.0.1:8765", character="Alice", vertices="int16") as view:
        for frame in view.frames(count=60):
            print(frame["n"], frame["t"], view.vertices(frame).shape)

asyncio (the same calls, awaited)::

    async with AsyncSubmitClient("ws://127.0.0.1:8765", character="Alice") as client:
        await client.submit(bml)
        async for event in client.events():
            ...

Both read the submitter endpoint in JSON mode and hand out events:
:class:`FeedbackEvent` (one BML 1.0 feedback element, with the XML and its
parsed form from :mod:`realizer.bml_parser.feedback`: which block,
behaviour, sync point and time) and :class:`BlockEvent` (a block's state:
accepted, rejected, done, interrupted, failed). ``receive()`` still gives the
raw JSON object.

Errors are typed, so a caller can tell a wrong token from a dead server::

    ClientError
     ├── ServerUnavailable        nothing answers at the URL, or the opening
     │                            handshake timed out
     ├── HandshakeRefused         the server answered with an HTTP status
     │    ├── Unauthorized        401: a (submit or view) token is needed
     │    └── Forbidden           403: the token may not do this
     ├── ServerBusy               over the server's connection limits (1013)
     ├── ConnectionLost           the connection closed mid-conversation
     │                            (``code``, ``reason``; 1001 = server stopping)
     └── ProtocolError            a message that is not the protocol's

The clients live in :mod:`realizer.service` because only the service package
may import websockets (the core is sans-I/O, docs/architecture.md), and
:mod:`realizer.client` re-exports them. The message handling is shared and
sans-I/O (:class:`SubmitterProtocol`); each class only moves text.
"""

from __future__ import annotations

import asyncio
import inspect
import json
from abc import ABC, abstractmethod
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Self
from urllib.parse import urlencode

import numpy as np
import numpy.typing as npt
from websockets.asyncio.client import ClientConnection as AsyncConnection
from websockets.asyncio.client import connect as async_connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidStatus, InvalidURI
from websockets.sync.client import ClientConnection, connect

from realizer.bml_parser.errors import BmlError
from realizer.bml_parser.feedback import FeedbackMessage, parse_feedback
from realizer.service import codec
from realizer.service.errors import CloseCode, ServiceError

#: Seconds to wait for the opening handshake.
OPEN_TIMEOUT = 10.0

#: Block states after which a block sends nothing more.
FINAL_STATES = frozenset({"rejected", "done", "interrupted", "failed"})


# -- errors --------------------------------------------------------------------------


class ClientError(ServiceError):
    """The server refused or broke off the conversation (root of the client's errors)."""


class ServerUnavailable(ClientError):
    """Nothing answers at the URL (connection refused, unknown host, timeout)."""


class HandshakeRefused(ClientError):
    """The server answered the WebSocket handshake with an HTTP error status."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(f"the server refused the connection: {status} {reason}".rstrip())
        self.status = status
        self.reason = reason


class Unauthorized(HandshakeRefused):
    """401: the endpoint needs a token (``token=``) and none or a wrong one was given."""


class Forbidden(HandshakeRefused):
    """403: the token is valid but may not do this (a view token on ``/bml``)."""


class ConnectionLost(ClientError):
    """The connection closed during the conversation.

    ``code`` and ``reason`` are the close frame's (``code`` None when the
    connection broke without one); 1001 means the server is shutting down.
    """

    def __init__(self, code: int | None, reason: str) -> None:
        detail = f"{code} {reason}".strip() if code is not None else "no close frame"
        super().__init__(f"the connection closed: {detail}")
        self.code = code
        self.reason = reason


class ServerBusy(ConnectionLost):
    """The server is at a connection limit (close code 1013); try again later."""


class ProtocolError(ClientError):
    """The server sent something that is not a message of the protocol."""


def _refused(error: InvalidStatus) -> HandshakeRefused:
    response = error.response
    body = bytes(response.body or b"").decode("utf-8", "replace").strip()
    reason = body or response.reason_phrase
    if response.status_code == 401:
        return Unauthorized(401, reason)
    if response.status_code == 403:
        return Forbidden(403, reason)
    return HandshakeRefused(response.status_code, reason)


def _lost(error: ConnectionClosed) -> ConnectionLost:
    frame = error.rcvd
    if frame is None:
        return ConnectionLost(None, "")
    if frame.code == CloseCode.TRY_AGAIN_LATER:
        return ServerBusy(frame.code, frame.reason)
    return ConnectionLost(frame.code, frame.reason)


def _opening_error(error: BaseException, uri: str) -> ClientError | None:
    """The client error for an exception raised while connecting to ``uri``, or None."""
    if isinstance(error, InvalidStatus):
        return _refused(error)
    if isinstance(error, InvalidURI):
        return ServerUnavailable(f"not a WebSocket URL: {error}")
    if isinstance(error, ConnectionClosed):
        return _lost(error)
    if isinstance(error, InvalidHandshake):
        return ProtocolError(f"the opening handshake failed: {error}")
    if isinstance(error, TimeoutError):
        return ServerUnavailable(f"{uri}: no answer within {OPEN_TIMEOUT} s")
    if isinstance(error, OSError):
        return ServerUnavailable(f"cannot connect to {uri}: {error.strerror or error}")
    return None


# -- events ----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class FeedbackEvent:
    """One BML 1.0 feedback element for a block.

    ``kind``: ``prediction``, ``blockProgress``, ``syncPointProgress`` or
    ``warning``; ``time``: session seconds; ``xml``: the element as sent;
    ``feedback``: the element parsed (a
    :class:`~realizer.bml_parser.feedback.BlockProgress`,
    :class:`~realizer.bml_parser.feedback.SyncPointProgress`,
    :class:`~realizer.bml_parser.feedback.WarningFeedback` or
    :class:`~realizer.bml_parser.feedback.PredictionFeedback`).
    """

    character: str
    kind: str
    block_id: str
    time: float
    xml: str
    feedback: FeedbackMessage


@dataclass(frozen=True, slots=True)
class BlockEvent:
    """A block's state changed: ``accepted``, ``rejected``, ``done``,
    ``interrupted`` or ``failed`` (the last four are final)."""

    character: str
    block_id: str
    state: str
    time: float

    @property
    def final(self) -> bool:
        return self.state in FINAL_STATES


Event = FeedbackEvent | BlockEvent


def event_from(message: dict[str, Any]) -> Event:
    """The event of one JSON message of the submitter endpoint (``format=json``).

    Raises :class:`ProtocolError` for a message that is not feedback or a
    block state, or whose feedback XML is not BML 1.0 feedback.
    """
    kind = message.get("type")
    try:
        if kind == "feedback":
            xml = str(message["xml"])
            try:
                parsed = parse_feedback(xml)
            except BmlError as error:
                raise ProtocolError(f"feedback that is not BML 1.0 feedback: {error}") from None
            return FeedbackEvent(
                character=str(message["character"]),
                kind=str(message["kind"]),
                block_id=str(message["block"]),
                time=float(message["time"]),
                xml=xml,
                feedback=parsed,
            )
        if kind == "block":
            return BlockEvent(
                character=str(message["character"]),
                block_id=str(message["block"]),
                state=str(message["state"]),
                time=float(message["time"]),
            )
    except (KeyError, TypeError, ValueError) as error:
        raise ProtocolError(f"a {kind!r} message without a valid {error}") from None
    raise ProtocolError(f"unexpected message type {kind!r}")


# -- the sans-I/O part ----------------------------------------------------------------------


def endpoint_url(base: str, path: str, params: dict[str, str | None]) -> str:
    """``base`` (ws://, wss://, http:// or https://) with ``path`` and a query."""
    base = base.rstrip("/")
    if base.startswith("http://"):
        base = "ws://" + base[len("http://") :]
    elif base.startswith("https://"):
        base = "wss://" + base[len("https://") :]
    query = urlencode({k: v for k, v in params.items() if v is not None})
    return f"{base}{path}?{query}" if query else f"{base}{path}"


class SubmitterProtocol:
    """What a submitter client says and how it reads the answers; no I/O.

    :meth:`bml`, :meth:`interrupt` and :meth:`target` give the text to send; :meth:`read`
    turns a received text into a JSON object, and :meth:`follows` tells
    whether a message belongs to the block being run.
    """

    @staticmethod
    def bml(bml: str, character: str | None = None) -> str:
        message: dict[str, str] = {"type": "bml", "bml": bml}
        if character is not None:
            message["character"] = character
        return json.dumps(message)

    @staticmethod
    def interrupt(block_id: str, character: str | None = None) -> str:
        message = {"type": "interrupt", "block": block_id}
        if character is not None:
            message["character"] = character
        return json.dumps(message)

    @staticmethod
    def target(name: str, position: tuple[float, float, float]) -> str:
        """Add or move the scene target ``name`` to ``position`` (x, y, z in
        metres; protocols/scene.md): the scene is the server's, shared by
        every character, and behaviours aimed at it follow from now on."""
        x, y, z = (float(v) for v in position)
        return json.dumps({"type": "target", "name": name, "position": [x, y, z]})

    @staticmethod
    def read(data: str | bytes) -> dict[str, Any]:
        if isinstance(data, bytes):
            raise ProtocolError("the submitter endpoint sent binary data; expected JSON text")
        try:
            message = json.loads(data)
        except json.JSONDecodeError:
            raise ProtocolError("the server sent text that is not JSON") from None
        if not isinstance(message, dict):
            raise ProtocolError("the server sent a message that is not a JSON object")
        return message

    @staticmethod
    def welcome(message: dict[str, Any]) -> dict[str, Any]:
        if message.get("type") != "welcome":
            raise ProtocolError(f"expected a welcome message, got {message.get('type')!r}")
        return message

    @staticmethod
    def follows(message: dict[str, Any], block_id: str | None) -> tuple[bool, str | None]:
        """Whether ``message`` is about the block being run, and that block's id.

        With ``block_id`` None the first block message names the block.
        Warnings about no block in particular (``block`` empty) count too.
        """
        if block_id is None and message.get("type") == "block":
            block_id = str(message.get("block", ""))
        if block_id is not None and message.get("block") not in (block_id, ""):
            return False, block_id
        return True, block_id


def _is_final(message: dict[str, Any]) -> bool:
    return message.get("type") == "block" and message.get("state") in FINAL_STATES


# -- blocking clients --------------------------------------------------------------------------


def _open(uri: str) -> ClientConnection:
    """A connected blocking client, or the :class:`ClientError` that says why not."""
    options: dict[str, Any] = {"open_timeout": OPEN_TIMEOUT, "max_size": None}
    options["compression"] = None
    try:
        # websockets >= 17.1 wants ``connect`` used as a context manager
        # (``legacy=False``); older releases return the connection directly
        if "legacy" in inspect.signature(connect).parameters:
            connecter: Any = connect(uri, legacy=False, **options)
            connection: ClientConnection = connecter.__enter__()
            return connection
        direct: ClientConnection = connect(uri, **options)
        return direct
    except Exception as error:
        translated = _opening_error(error, uri)
        if translated is None:
            raise
        raise translated from None


class _Connected:
    """A client holding one WebSocket connection; use it in a ``with`` block."""

    connection: ClientConnection

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        self.connection.close()

    def _recv(self, timeout: float | None) -> str | bytes:
        try:
            return self.connection.recv(timeout)
        except ConnectionClosed as error:
            raise _lost(error) from None

    def _send(self, text: str) -> None:
        try:
            self.connection.send(text)
        except ConnectionClosed as error:
            raise _lost(error) from None


class SubmitClient(_Connected):
    """The submitter endpoint in JSON mode: send BML, read feedback (blocking).

    ``welcome`` is the server's first message (protocol version, the
    server's version, fps, limits). Raises :class:`Unauthorized`,
    :class:`Forbidden`, :class:`ServerBusy` or :class:`ServerUnavailable`
    when the connection cannot be made.
    """

    def __init__(self, url: str, *, character: str | None = None, token: str | None = None) -> None:
        params = {"format": "json", "character": character, "token": token}
        self.connection: ClientConnection = _open(endpoint_url(url, "/bml", params))
        self.welcome: dict[str, Any] = SubmitterProtocol.welcome(self.receive(OPEN_TIMEOUT))

    def submit(self, bml: str, *, character: str | None = None) -> None:
        """Send one BML document (in a JSON envelope)."""
        self._send(SubmitterProtocol.bml(bml, character))

    def interrupt(self, block_id: str, *, character: str | None = None) -> None:
        """Ask the server to interrupt ``block_id``; its ``interrupted`` state follows."""
        self._send(SubmitterProtocol.interrupt(block_id, character))

    def target(self, name: str, position: tuple[float, float, float]) -> None:
        """Add or move the scene target ``name`` (x, y, z metres); gaze and
        pointing aimed at it follow it from now on (a bad one is answered
        with a ``NO_SUCH_TARGET`` warning)."""
        self._send(SubmitterProtocol.target(name, position))

    def receive(self, timeout: float | None = None) -> dict[str, Any]:
        """The next message as its JSON object; TimeoutError after ``timeout``
        seconds, :class:`ConnectionLost` when the server closed."""
        return SubmitterProtocol.read(self._recv(timeout))

    def receive_event(self, timeout: float | None = None) -> Event:
        """The next message as a :class:`FeedbackEvent` or :class:`BlockEvent`."""
        return event_from(self.receive(timeout))

    def events(self, timeout: float | None = None) -> Iterator[Event]:
        """Events as they arrive, until the connection closes (then
        :class:`ConnectionLost`) or ``timeout`` quiet seconds pass (TimeoutError)."""
        while True:
            yield self.receive_event(timeout)

    def run_block(
        self,
        bml: str,
        *,
        block_id: str | None = None,
        character: str | None = None,
        on_message: Callable[[dict[str, Any]], None] | None = None,
        on_event: Callable[[Event], None] | None = None,
        timeout: float | None = None,
    ) -> str:
        """Submit ``bml`` and read until its block is done, interrupted,
        failed or rejected; return that state.

        ``block_id`` (the block's ``id``) tells this block's messages from
        others'; when None the first block message after submitting names
        it. ``on_message`` sees every message of this block as its JSON
        object, ``on_event`` as an event, in arrival order.
        """
        self.submit(bml, character=character)
        while True:
            message = self.receive(timeout)
            mine, block_id = SubmitterProtocol.follows(message, block_id)
            if not mine:
                continue
            if on_message is not None:
                on_message(message)
            if on_event is not None:
                on_event(event_from(message))
            if _is_final(message):
                return str(message["state"])


class ViewClient(_Connected):
    """The viewer endpoint: the mesh, then decoded frames (blocking)."""

    def __init__(
        self,
        url: str,
        *,
        character: str | None = None,
        fap: bool = True,
        vertices: str = "none",
        token: str | None = None,
        coded: bool = False,
        arkit: bool = False,
        same: bool = True,
    ) -> None:
        from realizer.face.fapcoding import FapStreamDecoder

        self._decoder = FapStreamDecoder()
        self._decoded: dict[int, float] | None = None  # the last frame's decoded FAPs
        self._last_frame: dict[str, Any] | None = None  # the last frame received
        params = _view_params(character, fap, vertices, token, same)
        params.update(coded="true" if coded else None, arkit="true" if arkit else None)
        self.connection: ClientConnection = _open(endpoint_url(url, "/view", params))
        self.mesh = self.receive(OPEN_TIMEOUT)
        if self.mesh.get("type") != "mesh":
            raise ProtocolError(f"expected the mesh first, got a {self.mesh.get('type')!r} message")

    def receive(self, timeout: float | None = None) -> dict[str, Any]:
        return self.decode(self._recv(timeout))

    def decode(self, data: str | bytes) -> dict[str, Any]:
        """A received message (a new mesh also starts a new coded stream)."""
        message = _read_view(data)
        if message["type"] == "mesh":
            from realizer.face.fapcoding import FapStreamDecoder

            self.mesh = message
            self._decoder = FapStreamDecoder()  # a new subscription: a new coded stream
            self._last_frame = None  # its first frame comes whole
        elif message["type"] == "frame":
            self._last_frame = message  # what a `same` repeats
        return message

    def subscribe(self, **changes: Any) -> None:
        """Change character, ``fap`` or ``vertices``; a new mesh follows."""
        self._send(json.dumps({"type": "subscribe", **changes}))

    def frames(
        self, count: int | None = None, timeout: float | None = None
    ) -> Iterator[dict[str, Any]]:
        """Frame messages as they arrive (``count`` of them, or forever).

        A ``same`` message (frame ``n`` shows what the last frame showed) is
        given as that last frame with its ``n`` and ``t`` moved on and
        ``"same": True``, so a caller sees one frame per tick either way.
        """
        seen = 0
        while count is None or seen < count:
            message = self.receive(timeout)
            if message["type"] == "frame":
                seen += 1
                yield message
            elif message["type"] == "same" and self._last_frame is not None:
                seen += 1
                yield _same_as(self._last_frame, message, self.mesh)

    def vertices(self, frame: dict[str, Any]) -> npt.NDArray[np.float32]:
        """(n, 3) float32 metres of a frame (the neutral pose if it has none)."""
        return codec.decode_vertices(frame, self.mesh)

    @staticmethod
    def faps(frame: dict[str, Any]) -> dict[int, float]:
        """{FAP number: value} of a frame's set FAPs."""
        return codec.decode_faps(frame["fap"]) if "fap" in frame else {}

    def decoded_faps(self, frame: dict[str, Any]) -> dict[int, float] | None:
        """{FAP number: value} of a frame, from its ``fap`` payload or its
        MPEG-4 coded FAPs (``coded=True``); None for a coded frame that cannot
        be decoded yet (frames arrive in order, so call this for every frame:
        it decodes from the first intra frame on)."""
        if "coded" in frame:
            if frame.get("same"):  # a `same`: what the last frame decoded to
                return self._decoded
            decoded = self._decoder.decode(frame["coded"], frame["n"], frame.get("codedRef"))
            if decoded is None:
                self._decoded = None
                return None
            values, mask = decoded
            self._decoded = {int(i) + 1: float(values[i]) for i in np.flatnonzero(mask)}
            return self._decoded
        return self.faps(frame)

    @staticmethod
    def arkit(frame: dict[str, Any]) -> Any:
        """The frame's ARKit weights and pose (:class:`realizer.face.arkit.ArkitFrame`),
        or None when it has none (``arkit=True`` asks for them)."""
        if "arkit" not in frame:
            return None
        from realizer.face.arkit import decode_payload

        return decode_payload(frame["arkit"])


def _view_params(
    character: str | None, fap: bool, vertices: str, token: str | None, same: bool
) -> dict[str, str | None]:
    return {
        "character": character,
        "fap": "true" if fap else "false",
        "vertices": vertices,
        "token": token,
        "same": "true" if same else "false",
    }


def _read_view(data: str | bytes) -> dict[str, Any]:
    if isinstance(data, str):
        raise ProtocolError("the viewer endpoint sent text; expected msgpack")
    try:
        message = codec.unpack(data)
    except Exception:
        raise ProtocolError("the viewer endpoint sent bytes that are not msgpack") from None
    if not isinstance(message, dict) or "type" not in message:
        raise ProtocolError("the viewer endpoint sent a message without a type")
    return message


# -- asyncio clients -----------------------------------------------------------------------


async def _async_open(uri: str) -> AsyncConnection:
    try:
        return await async_connect(uri, open_timeout=OPEN_TIMEOUT, max_size=None, compression=None)
    except Exception as error:
        translated = _opening_error(error, uri)
        if translated is None:
            raise
        raise translated from None


class _AsyncConnected(ABC):
    connection: AsyncConnection

    async def __aenter__(self) -> Self:
        await self.open()
        return self

    async def __aexit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.close()

    @abstractmethod
    async def open(self) -> None:
        """Connect, and take the endpoint's first message(s)."""

    async def close(self) -> None:
        if hasattr(self, "connection"):
            await self.connection.close()

    async def _recv(self, timeout: float | None) -> str | bytes:
        try:
            return await asyncio.wait_for(self.connection.recv(), timeout)
        except ConnectionClosed as error:
            raise _lost(error) from None

    async def _send(self, text: str) -> None:
        try:
            await self.connection.send(text)
        except ConnectionClosed as error:
            raise _lost(error) from None


class AsyncSubmitClient(_AsyncConnected):
    """The submitter endpoint for asyncio programs; the calls of
    :class:`SubmitClient`, awaited. Connect with ``async with`` (or
    ``await client.open()``); the same errors are raised."""

    def __init__(self, url: str, *, character: str | None = None, token: str | None = None) -> None:
        self._url = endpoint_url(
            url, "/bml", {"format": "json", "character": character, "token": token}
        )
        self.welcome: dict[str, Any] = {}

    async def open(self) -> None:
        self.connection = await _async_open(self._url)
        self.welcome = SubmitterProtocol.welcome(await self.receive(OPEN_TIMEOUT))

    async def submit(self, bml: str, *, character: str | None = None) -> None:
        await self._send(SubmitterProtocol.bml(bml, character))

    async def interrupt(self, block_id: str, *, character: str | None = None) -> None:
        await self._send(SubmitterProtocol.interrupt(block_id, character))

    async def target(self, name: str, position: tuple[float, float, float]) -> None:
        await self._send(SubmitterProtocol.target(name, position))

    async def receive(self, timeout: float | None = None) -> dict[str, Any]:
        return SubmitterProtocol.read(await self._recv(timeout))

    async def receive_event(self, timeout: float | None = None) -> Event:
        return event_from(await self.receive(timeout))

    async def events(self, timeout: float | None = None) -> AsyncIterator[Event]:
        """Events as they arrive (``async for``), until the connection closes."""
        while True:
            yield await self.receive_event(timeout)

    async def run_block(
        self,
        bml: str,
        *,
        block_id: str | None = None,
        character: str | None = None,
        on_event: Callable[[Event], Awaitable[None] | None] | None = None,
        timeout: float | None = None,
    ) -> str:
        """Submit ``bml`` and read until its block ends; return its final state.

        ``on_event`` may be a plain function or a coroutine function.
        """
        await self.submit(bml, character=character)
        while True:
            message = await self.receive(timeout)
            mine, block_id = SubmitterProtocol.follows(message, block_id)
            if not mine:
                continue
            if on_event is not None:
                result = on_event(event_from(message))
                if inspect.isawaitable(result):
                    await result
            if _is_final(message):
                return str(message["state"])


class AsyncViewClient(_AsyncConnected):
    """The viewer endpoint for asyncio programs (see :class:`ViewClient`)."""

    def __init__(
        self,
        url: str,
        *,
        character: str | None = None,
        fap: bool = True,
        vertices: str = "none",
        token: str | None = None,
        same: bool = True,
    ) -> None:
        self._url = endpoint_url(url, "/view", _view_params(character, fap, vertices, token, same))
        self.mesh: dict[str, Any] = {}
        self._last_frame: dict[str, Any] | None = None

    async def open(self) -> None:
        self.connection = await _async_open(self._url)
        mesh = await self.receive(OPEN_TIMEOUT)
        if mesh.get("type") != "mesh":
            raise ProtocolError(f"expected the mesh first, got a {mesh.get('type')!r} message")

    async def receive(self, timeout: float | None = None) -> dict[str, Any]:
        message = _read_view(await self._recv(timeout))
        if message["type"] == "mesh":
            self.mesh = message
            self._last_frame = None  # a new subscription: its first frame comes whole
        elif message["type"] == "frame":
            self._last_frame = message  # what a `same` repeats
        return message

    async def subscribe(self, **changes: Any) -> None:
        await self._send(json.dumps({"type": "subscribe", **changes}))

    async def frames(
        self, count: int | None = None, timeout: float | None = None
    ) -> AsyncIterator[dict[str, Any]]:
        """Frames as they arrive; a ``same`` is the last frame again (see the
        blocking client's :meth:`frames`)."""
        seen = 0
        while count is None or seen < count:
            message = await self.receive(timeout)
            if message["type"] == "frame":
                seen += 1
                yield message
            elif message["type"] == "same" and self._last_frame is not None:
                seen += 1
                yield _same_as(self._last_frame, message, self.mesh)

    def vertices(self, frame: dict[str, Any]) -> npt.NDArray[np.float32]:
        return codec.decode_vertices(frame, self.mesh)

    @staticmethod
    def faps(frame: dict[str, Any]) -> dict[int, float]:
        return codec.decode_faps(frame["fap"]) if "fap" in frame else {}


def _same_as(last: dict[str, Any], same: dict[str, Any], mesh: dict[str, Any]) -> dict[str, Any]:
    """The frame a ``same`` message stands for: ``last`` with ``n`` and ``t`` moved on."""
    fps = float(mesh.get("fps", 0.0)) or 1.0
    moved = last["t"] + (same["n"] - last["n"]) / fps
    return {**last, "n": same["n"], "t": moved, "same": True}
