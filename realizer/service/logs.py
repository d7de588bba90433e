"""The service's log: one line per connection, refused handshake and block state.

``realizer serve --log-level info --log-format text|json`` calls
:func:`configure`. At INFO the log has one line

* per connection opened and closed (peer address, endpoint), from websockets'
  own ``websockets.server`` logger, given the peer and the path here;
* per refused handshake, with the HTTP status and the reason the peer was
  told (``connection refused (401 Unauthorized): a submit token is required``);
* per block state (accepted, rejected, done, interrupted, failed), with the
  character and the block id (:func:`log_block`).

Nothing a peer does puts a traceback in the log: exceptions websockets logs
for a peer's broken handshake or connection become one line with the
exception's message (as websockets says, such details "may be
security-sensitive" and tell an operator nothing a line would not). Tracebacks
remain only for the realizer's own errors (``logger.exception`` in the
service), which are bugs. Query strings are logged without their ``token``.

JSON lines carry ``time`` (ISO 8601, UTC), ``level``, ``logger``,
``message`` and, where known, ``event``, ``peer``, ``path``, ``status``,
``character``, ``block`` and ``state``.
"""

from __future__ import annotations

import json
import logging
import sys
from datetime import UTC, datetime
from typing import IO, Any, Literal

LogFormat = Literal["text", "json"]
LEVELS = ("debug", "info", "warning", "error")

#: The logger of the service's own lines (blocks, errors).
logger = logging.getLogger("realizer.service")

#: Fields a record may carry for the JSON format (set with ``extra=``).
FIELDS = ("event", "peer", "path", "status", "character", "block", "state")

#: Exceptions that a peer causes (a broken handshake, a dropped connection);
#: websockets' own exceptions count too, known by their module (this module
#: does not import websockets: only the server and the client do).
_PEER_EXCEPTIONS: tuple[type[BaseException], ...] = (EOFError, OSError, TimeoutError)


def caused_by_peer(error: BaseException) -> bool:
    """Whether ``error`` is something a peer did, not a bug of the realizer."""
    return isinstance(error, _PEER_EXCEPTIONS) or type(error).__module__.startswith("websockets")


def without_token(path: str) -> str:
    """``path`` with the value of any ``token`` query parameter masked."""
    base, sep, query = path.partition("?")
    if not sep:
        return path
    parts = []
    for item in query.split("&"):
        name, eq, _ = item.partition("=")
        parts.append(f"{name}=***" if name == "token" and eq else item)
    return f"{base}?{'&'.join(parts)}"


class PeerLines(logging.Filter):
    """Rewrites websockets' records: peer and path added, tracebacks of a
    peer's doing dropped, plain-HTTP responses (health checks) moved to DEBUG."""

    def filter(self, record: logging.LogRecord) -> bool:
        if not record.name.startswith("websockets"):
            return True
        connection = getattr(record, "websocket", None)
        if connection is not None:
            self._describe(record, connection)
        if record.exc_info and record.exc_info[1] is not None:
            error = record.exc_info[1]
            if caused_by_peer(error):
                record.msg = f"{record.getMessage()}: {type(error).__name__}: {error}"
                record.args = None
                record.exc_info = None
                record.exc_text = None
                record.levelno, record.levelname = logging.INFO, "INFO"
        return record.levelno >= logging.getLogger().getEffectiveLevel()

    @staticmethod
    def _describe(record: logging.LogRecord, connection: Any) -> None:
        message = record.getMessage()
        request = getattr(connection, "request", None)
        path = without_token(str(getattr(request, "path", "") or ""))
        address = getattr(connection, "remote_address", None)
        peer = f"{address[0]}:{address[1]}" if isinstance(address, tuple) else ""
        record.peer, record.path = peer, path
        response = getattr(connection, "response", None)
        status = getattr(response, "status_code", None)
        # get_all: a peer may repeat a header (answered 400), and a log line
        # must not fail on it (get() raises MultipleValuesError)
        upgrade = " ".join(request.headers.get_all("Upgrade")) if request is not None else ""
        wanted_websocket = path.partition("?")[0] in ("/bml", "/view") or (
            "websocket" in upgrade.lower()
        )
        if message.startswith(("HTTP response sent", "connection rejected")):
            if status is not None and status >= 400 and wanted_websocket:
                body = bytes(getattr(response, "body", b"") or b"")[:200]
                reason = body.decode("utf-8", "replace").strip()
                phrase = getattr(response, "reason_phrase", "")
                record.event, record.status = "refused", status
                record.msg = f"connection refused ({status} {phrase})"
                record.msg += f": {reason}" if reason else ""
                record.msg += f" {peer} {path}".rstrip()
                record.args = None
            else:  # plain HTTP: /health, /version, the viewer's files
                record.levelno, record.levelname = logging.DEBUG, "DEBUG"
                record.event, record.status = "http", status
        elif message == "connection open":
            record.event = "open"
        elif message == "connection closed":
            if status != 101:  # a plain HTTP exchange or a refused handshake
                record.levelno, record.levelname = logging.DEBUG, "DEBUG"
            record.event = "close"
        if peer and getattr(record, "event", None) in ("open", "close"):
            record.msg = f"{message} {peer} {path}".rstrip()
            record.args = None


class JsonFormatter(logging.Formatter):
    """One JSON object per line."""

    def format(self, record: logging.LogRecord) -> str:
        data: dict[str, Any] = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        for name in FIELDS:
            value = getattr(record, name, None)
            if value is not None and value != "":
                data[name] = value
        if record.exc_info:
            data["traceback"] = self.formatException(record.exc_info)
        return json.dumps(data, ensure_ascii=False)


def configure(level: str = "info", fmt: LogFormat = "text", stream: IO[str] | None = None) -> None:
    """Send the service's and websockets' records to ``stream`` (stderr) as text or JSON."""
    if level not in LEVELS:
        raise ValueError(f"log level must be one of {', '.join(LEVELS)}, not {level!r}")
    handler = logging.StreamHandler(stream or sys.stderr)
    handler.addFilter(PeerLines())
    if fmt == "json":
        handler.setFormatter(JsonFormatter())
    else:
        handler.setFormatter(
            logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s", "%H:%M:%S")
        )
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level.upper())
    # websockets builds its per-frame DEBUG lines only when its logger wants
    # them: INFO unless debugging was asked for (PeerLines then decides)
    logging.getLogger("websockets").setLevel(logging.DEBUG if level == "debug" else logging.INFO)


def log_block(character: str, block_id: str, state: str, time: float) -> None:
    """One INFO line for a block's state change."""
    logger.info(
        "block %s of %s %s at %.3f s",
        block_id or "(no id)",
        character,
        state,
        time,
        extra={"event": "block", "character": character, "block": block_id, "state": state},
    )
