"""Errors of the service, and the one place that maps them to wire answers.

::

    RealizerError
     └── ServiceError                   the service refuses something
          ├── ConfigError               a configuration that must not run
          │                             (e.g. no tokens on a public address)
          └── PeerError                 the peer broke the protocol (remote)
               ├── LimitExceeded        over a named limit (limits.py)
               └── BadMessage           a message the endpoint cannot read

A peer error becomes a BML ``warningFeedback`` when the connection can go on
(a block over a limit, a malformed envelope) and a WebSocket close code when
it cannot (a binary message where text is expected, a backlog the peer never
reads). As in websockets, the reason sent to a peer is written for that peer
and never carries internal details (tracebacks, paths).
"""

from __future__ import annotations

from enum import IntEnum

from realizer.errors import RealizerError


class CloseCode(IntEnum):
    """WebSocket close codes the service sends (RFC 6455 section 7.4.1)."""

    NORMAL = 1000
    GOING_AWAY = 1001  # the server shuts down
    UNSUPPORTED_DATA = 1003  # binary where text is expected, or the reverse
    INVALID_PAYLOAD = 1007  # text that is not UTF-8
    POLICY_VIOLATION = 1008  # a backlog over its limit, a forbidden action
    MESSAGE_TOO_BIG = 1009  # over limits.message_bytes (sent by websockets)
    INTERNAL_ERROR = 1011
    TRY_AGAIN_LATER = 1013  # over the connection limits


class ServiceError(RealizerError):
    """Base class of the service's errors."""


class ConfigError(ServiceError):
    """A configuration the service refuses to run with."""


class PeerError(ServiceError):
    """The peer sent something the service does not accept.

    ``warning_type`` is the BML 1.0 warning type used when the answer is a
    ``warningFeedback``; ``close_code`` the code used when it is a close.
    """

    warning_type: str = "PARSING_FAILURE"
    close_code: CloseCode = CloseCode.POLICY_VIOLATION

    def __init__(self, message: str, *, block_id: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.block_id = block_id


class LimitExceeded(PeerError):
    """Over a named limit of :class:`~realizer.service.limits.ServiceLimits`."""

    warning_type = "CANNOT_CREATE_BEHAVIOR"
    close_code = CloseCode.TRY_AGAIN_LATER


class BadMessage(PeerError):
    """A message that is not one of the endpoint's messages."""

    warning_type = "PARSING_FAILURE"
    close_code = CloseCode.UNSUPPORTED_DATA
