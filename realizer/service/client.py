"""A small blocking Python client for both endpoints (protocols/).

::

    from realizer.client import SubmitClient, ViewClient

    with SubmitClient("ws://127.0.0.1:8765", character="Alice") as client:
        state = client.run_block(open("smile.xml").read(), on_message=print)

    with ViewClient("ws://127.0.0.1:8765", character="Alice", vertices="int16") as view:
        mesh = view.mesh
        for frame in view.frames(count=60):
            print(frame["n"], frame["t"], view.vertices(frame).shape)

It uses websockets' threading client (``websockets.sync``), so it needs no
event loop; it lives in :mod:`realizer.service` because only the service
package may import websockets (the core is sans-I/O, docs/architecture.md), and
:mod:`realizer.client` re-exports it.
"""

from __future__ import annotations

import inspect
import json
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any, Self
from urllib.parse import urlencode

import numpy as np
import numpy.typing as npt
from websockets.sync.client import ClientConnection, connect

from realizer.service import codec
from realizer.service.errors import ServiceError

#: Seconds to wait for the opening handshake.
OPEN_TIMEOUT = 10.0


class ClientError(ServiceError):
    """The server refused or broke off the conversation."""


def _open(uri: str) -> ClientConnection:
    """A connected client; websockets >= 17.1 wants ``connect`` used as a
    context manager (``legacy=False``), older releases return the
    connection directly."""
    options: dict[str, Any] = {"open_timeout": OPEN_TIMEOUT, "max_size": None}
    options["compression"] = None
    if "legacy" in inspect.signature(connect).parameters:
        connecter: Any = connect(uri, legacy=False, **options)
        connection: ClientConnection = connecter.__enter__()
        return connection
    direct: ClientConnection = connect(uri, **options)
    return direct


def _url(base: str, path: str, params: dict[str, str | None]) -> str:
    base = base.rstrip("/")
    if base.startswith("http://"):
        base = "ws://" + base[len("http://") :]
    elif base.startswith("https://"):
        base = "wss://" + base[len("https://") :]
    query = urlencode({k: v for k, v in params.items() if v is not None})
    return f"{base}{path}?{query}" if query else f"{base}{path}"


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


class SubmitClient(_Connected):
    """The submitter endpoint in JSON mode: send BML, read feedback."""

    def __init__(self, url: str, *, character: str | None = None, token: str | None = None) -> None:
        endpoint = _url(url, "/bml", {"format": "json", "character": character, "token": token})
        self.connection: ClientConnection = _open(endpoint)
        self.welcome: dict[str, Any] = self.receive(OPEN_TIMEOUT)
        if self.welcome.get("type") != "welcome":
            raise ClientError(f"expected a welcome message, got {self.welcome!r}")

    def submit(self, bml: str, *, character: str | None = None) -> None:
        """Send one BML document (in a JSON envelope)."""
        message: dict[str, str] = {"type": "bml", "bml": bml}
        if character is not None:
            message["character"] = character
        self.connection.send(json.dumps(message))

    def interrupt(self, block_id: str, *, character: str | None = None) -> None:
        """Ask the server to interrupt ``block_id``."""
        message = {"type": "interrupt", "block": block_id}
        if character is not None:
            message["character"] = character
        self.connection.send(json.dumps(message))

    def receive(self, timeout: float | None = None) -> dict[str, Any]:
        """The next message (feedback or block state); TimeoutError after
        ``timeout`` seconds; :class:`websockets.exceptions.ConnectionClosed`
        when the server closed."""
        text = self.connection.recv(timeout)
        data = json.loads(text)
        if not isinstance(data, dict):
            raise ClientError("the server sent a message that is not a JSON object")
        return data

    def run_block(
        self,
        bml: str,
        *,
        block_id: str | None = None,
        character: str | None = None,
        on_message: Callable[[dict[str, Any]], None] | None = None,
        timeout: float | None = None,
    ) -> str:
        """Submit ``bml`` and read until its block is done, interrupted or
        rejected; returns that state. ``block_id`` (the block's ``id``) tells
        this block's messages from others'; when None the first block
        message after submitting names it. ``on_message`` sees every
        message of this block, in arrival order."""
        self.submit(bml, character=character)
        while True:
            message = self.receive(timeout)
            if block_id is None and message.get("type") == "block":
                block_id = str(message["block"])
            if block_id is not None and message.get("block") not in (block_id, ""):
                continue
            if on_message is not None:
                on_message(message)
            if message.get("type") == "block" and message["state"] != "accepted":
                return str(message["state"])


class ViewClient(_Connected):
    """The viewer endpoint: the mesh, then decoded frames."""

    def __init__(
        self,
        url: str,
        *,
        character: str | None = None,
        fap: bool = True,
        vertices: str = "none",
        token: str | None = None,
    ) -> None:
        params = {
            "character": character,
            "fap": "true" if fap else "false",
            "vertices": vertices,
            "token": token,
        }
        self.connection: ClientConnection = _open(_url(url, "/view", params))
        self.mesh = self.receive(OPEN_TIMEOUT)
        if self.mesh.get("type") != "mesh":
            raise ClientError(f"expected the mesh first, got a {self.mesh.get('type')!r} message")

    def receive(self, timeout: float | None = None) -> dict[str, Any]:
        data = self.connection.recv(timeout)
        if isinstance(data, str):
            raise ClientError("the viewer endpoint sent text; expected msgpack")
        message = codec.unpack(data)
        if message["type"] == "mesh":
            self.mesh = message
        return message

    def subscribe(self, **changes: Any) -> None:
        """Change character, ``fap`` or ``vertices``; a new mesh follows."""
        self.connection.send(json.dumps({"type": "subscribe", **changes}))

    def frames(
        self, count: int | None = None, timeout: float | None = None
    ) -> Iterator[dict[str, Any]]:
        """Frame messages as they arrive (``count`` of them, or forever)."""
        seen = 0
        while count is None or seen < count:
            message = self.receive(timeout)
            if message["type"] == "frame":
                seen += 1
                yield message

    def vertices(self, frame: dict[str, Any]) -> npt.NDArray[np.float32]:
        """(n, 3) float32 metres of a frame (the neutral pose if it has none)."""
        return codec.decode_vertices(frame, self.mesh)

    @staticmethod
    def faps(frame: dict[str, Any]) -> dict[int, float]:
        """{FAP number: value} of a frame's set FAPs."""
        return codec.decode_faps(frame["fap"]) if "fap" in frame else {}
