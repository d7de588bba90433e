"""The Python clients of the realizer service: see :mod:`realizer.service.client`.

Re-exported here so users write ``from realizer.client import SubmitClient``;
the implementation stays under :mod:`realizer.service`, the only package that
may import websockets (the core is sans-I/O, see docs/architecture.md).
docs/tutorial.md shows them at work.
"""

from __future__ import annotations

from realizer.service.client import (
    AsyncSubmitClient,
    AsyncViewClient,
    BlockEvent,
    ClientError,
    ConnectionLost,
    Event,
    FeedbackEvent,
    Forbidden,
    HandshakeRefused,
    ProtocolError,
    ServerBusy,
    ServerUnavailable,
    SubmitClient,
    Unauthorized,
    ViewClient,
)

__all__ = [
    "AsyncSubmitClient",
    "AsyncViewClient",
    "BlockEvent",
    "ClientError",
    "ConnectionLost",
    "Event",
    "FeedbackEvent",
    "Forbidden",
    "HandshakeRefused",
    "ProtocolError",
    "ServerBusy",
    "ServerUnavailable",
    "SubmitClient",
    "Unauthorized",
    "ViewClient",
]
