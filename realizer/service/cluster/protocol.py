"""The cluster's subjects and message layouts (protocols/cluster.md), sans-I/O.

Workers and gateways talk over NATS: core NATS request/reply for requests
to a character's owner, core NATS publish/subscribe for feedback, frames and
the gateways' interest, and a JetStream key-value bucket for leases. This
module names the subjects and reads and writes every message; it imports no
NATS client and does no I/O, so tests check the layouts without a broker.

Every message carries the cluster protocol version ``v``
(:data:`CLUSTER_VERSION`); a reader refuses another version with
:class:`ClusterMessageError` rather than misread it. Peers on the bus are
the cluster's own processes, but their messages are still read with named
limits (:class:`ClusterLimits`), so a bug or a stray publisher cannot make a
worker or a gateway hold unbounded state.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, fields
from typing import Any, Literal

import msgpack
import numpy as np
import numpy.typing as npt

from realizer.service.errors import PeerError
from realizer.service.limits import valid_character_id
from realizer.service.messages import BlockState, ViewOptions
from realizer.service.stage import BlockEvent, Outgoing, WireFeedback

#: 2: frames travel in a frame-tick envelope, whole or as a ``same`` of a
#: few bytes (protocols/cluster.md, "Frames"); 1 published whole frames only.
CLUSTER_VERSION = 2
PREFIX = f"realizer.v{CLUSTER_VERSION}"
#: The queue group of the workers on the claim subject: one of them answers.
WORKER_QUEUE = "realizer-workers"
#: The JetStream key-value bucket of leases: key = character token.
LEASE_BUCKET = f"realizer-v{CLUSTER_VERSION}-leases"
SUBJECT_CLAIM = f"{PREFIX}.claim"
SUBJECT_WANT = f"{PREFIX}.want"


class ClusterMessageError(ValueError):
    """A cluster message that cannot be read (wrong version, layout or limit)."""


@dataclass(frozen=True, slots=True)
class ClusterLimits:
    """Limits on what a cluster peer's message can make a process hold.

    ``request_bytes``: a request to an owner (the BML plus its envelope);
    ``want_characters``: characters in one gateway's interest message;
    ``want_formats``: viewer formats of one character in it;
    ``lease_blocks``: open block ids a lease records;
    ``id_chars``: a worker's, gateway's or block's id;
    ``frame_bytes``: a frame-tick message (a float32 vertex frame of the
    default face is 73 kB).
    """

    request_bytes: int = 256 * 1024 + 4096
    frame_bytes: int = 16 * 1024 * 1024
    want_characters: int = 1024
    want_formats: int = 16
    lease_blocks: int = 64
    id_chars: int = 200


CLUSTER_LIMITS = ClusterLimits()


# -- subjects ----------------------------------------------------------------------


def token(character: str) -> str:
    """A character id as one subject token and key-value key.

    Character ids may hold ``.``, NATS's token separator; ``=`` is outside
    their alphabet and allowed in subjects and keys, so the mapping is
    reversible.
    """
    return character.replace(".", "=")


def untoken(text: str) -> str:
    return text.replace("=", ".")


def request_subject(character: str) -> str:
    """Requests to the owner of ``character`` (only the owner subscribes)."""
    return f"{PREFIX}.req.{token(character)}"


def feedback_subject(character: str) -> str:
    return f"{PREFIX}.fb.{token(character)}"


FEEDBACK_WILDCARD = f"{PREFIX}.fb.*"


def frame_subject(character: str, options: ViewOptions) -> str:
    return f"{PREFIX}.frame.{token(character)}.{format_key(options)}"


def frame_wildcard(character: str) -> str:
    return f"{PREFIX}.frame.{token(character)}.*"


def format_key(options: ViewOptions) -> str:
    """One subject token per viewer format, e.g. ``true_none``: the values
    of the :class:`ViewOptions` fields in order, so a field a later version
    adds gets its own frames without a change here."""
    return "_".join(str(getattr(options, f.name)).lower() for f in fields(options))


def options_dict(options: ViewOptions) -> dict[str, Any]:
    return {f.name: getattr(options, f.name) for f in fields(options)}


def read_options(data: Any) -> ViewOptions:
    if not isinstance(data, dict):
        raise ClusterMessageError("a viewer format is a map")
    names = {f.name for f in fields(ViewOptions)}
    data = {k: v for k, v in data.items() if k != "every"}  # the want message's own key
    if not set(data) <= names:
        raise ClusterMessageError(f"unknown viewer format fields {sorted(set(data) - names)}")
    try:
        return ViewOptions(**data)
    except (TypeError, ValueError, PeerError) as exc:
        raise ClusterMessageError(f"bad viewer format: {exc}") from None


# -- reading helpers ---------------------------------------------------------------


def _pack(message: dict[str, Any], **options: Any) -> bytes:
    data: bytes = msgpack.packb(message, **options)
    return data


def _unpack(data: bytes, limit: int) -> dict[str, Any]:
    if len(data) > limit:
        raise ClusterMessageError(f"message of {len(data)} bytes over the limit of {limit}")
    try:
        message = msgpack.unpackb(data, raw=False)
    except Exception as exc:  # msgpack raises several types for bad input
        raise ClusterMessageError(f"not msgpack: {type(exc).__name__}") from None
    if not isinstance(message, dict):
        raise ClusterMessageError("expected a map")
    if message.get("v") != CLUSTER_VERSION:
        raise ClusterMessageError(
            f"cluster protocol version {message.get('v')!r}, expected {CLUSTER_VERSION}"
        )
    return message


def _text(message: dict[str, Any], key: str, limit: int, *, empty: bool = False) -> str:
    value = message.get(key)
    if not isinstance(value, str) or len(value) > limit or (not value and not empty):
        raise ClusterMessageError(f"{key!r} must be a string of at most {limit} characters")
    return value


def _character(message: dict[str, Any]) -> str:
    value = message.get("character")
    if not isinstance(value, str) or not valid_character_id(value):
        raise ClusterMessageError("'character' must be a valid character id")
    return value


# -- requests to an owner (gateway -> worker) -----------------------------------------

Op = Literal["bml", "interrupt", "view"]


@dataclass(frozen=True, slots=True)
class OwnerRequest:
    """What a gateway asks the owner of ``character``: realize ``bml``,
    interrupt ``block``, or make the character for a viewer (``view``).
    ``reply_to`` names the submitter (``gateway/number``) that gets the
    feedback of this request even if it does not follow the character."""

    op: Op
    character: str
    reply_to: str = ""
    bml: str = ""
    block: str = ""
    model: bool = False  # view: send the deformation model too
    intra: bool = False  # view: a coded-FAP viewer joined, code an intra frame next
    strict: bool = False  # bml: every warning is an error (the connection's strict mode)

    def pack(self) -> bytes:
        return _pack(
            {
                "v": CLUSTER_VERSION,
                "op": self.op,
                "character": self.character,
                "to": self.reply_to,
                "bml": self.bml,
                "block": self.block,
                "model": self.model,
                "intra": self.intra,
                "strict": self.strict,
            }
        )

    @classmethod
    def unpack(cls, data: bytes, limits: ClusterLimits = CLUSTER_LIMITS) -> OwnerRequest:
        message = _unpack(data, limits.request_bytes)
        op = message.get("op")
        if op not in ("bml", "interrupt", "view"):
            raise ClusterMessageError(f"unknown op {op!r}")
        return cls(
            op=op,
            character=_character(message),
            reply_to=_text(message, "to", limits.id_chars, empty=True),
            bml=_text(message, "bml", limits.request_bytes, empty=op != "bml"),
            block=_text(message, "block", limits.id_chars, empty=op != "interrupt"),
            model=message.get("model") is True,
            intra=message.get("intra") is True,
            strict=message.get("strict") is True,
        )


ReplyStatus = Literal["ok", "retry", "full", "none", "error"]


@dataclass(frozen=True, slots=True)
class OwnerReply:
    """The owner's answer. ``ok``: done (its feedback is on the feedback
    subject); ``retry``: ask again soon (no owner yet, or it is handing the
    character over); ``full``: this worker has no room for one more
    character; ``none``: there is no such character (an interrupt of a
    character nobody made); ``error``: refused with ``reason`` (a viewer
    limit). ``mesh``: the viewer's mesh message, for ``view``, and
    ``model`` the deformation model message when the request asked."""

    status: ReplyStatus
    worker: str = ""
    reason: str = ""
    mesh: bytes = b""
    model: bytes = b""

    def pack(self) -> bytes:
        return _pack(
            {
                "v": CLUSTER_VERSION,
                "status": self.status,
                "worker": self.worker,
                "reason": self.reason,
                "mesh": self.mesh,
                "model": self.model,
            },
            use_bin_type=True,
        )

    @classmethod
    def unpack(cls, data: bytes, limit: int = 16 * 1024 * 1024) -> OwnerReply:
        message = _unpack(data, limit)
        status = message.get("status")
        if status not in ("ok", "retry", "full", "none", "error"):
            raise ClusterMessageError(f"unknown status {status!r}")
        mesh, model = message.get("mesh", b""), message.get("model", b"")
        if not isinstance(mesh, bytes) or not isinstance(model, bytes):
            raise ClusterMessageError("'mesh' and 'model' must be bytes")
        return cls(
            status=status,
            worker=_text(message, "worker", CLUSTER_LIMITS.id_chars, empty=True),
            reason=_text(message, "reason", 4096, empty=True),
            mesh=mesh,
            model=model,
        )


# -- feedback (worker -> gateways) ----------------------------------------------------


def pack_feedback(message: Outgoing, reply_to: str = "", follow: bool = False) -> bytes:
    """One stage message for the gateways; ``reply_to`` names a submitter
    that gets it too, ``follow`` says that submitter follows the character
    from now on (as ``realizer serve`` adds a character to a submitter that
    sent it BML)."""
    body: dict[str, Any] = {
        "v": CLUSTER_VERSION,
        "character": message.character,
        "block": message.block_id,
        "time": message.time,
        "to": reply_to,
        "follow": follow,
    }
    if isinstance(message, WireFeedback):
        body.update(type="feedback", kind=message.kind, xml=message.xml)
    else:
        body.update(type="block", state=message.state)
    return _pack(body)


@dataclass(frozen=True, slots=True)
class FeedbackEnvelope:
    message: Outgoing
    reply_to: str
    follow: bool


_STATES: tuple[BlockState, ...] = ("accepted", "rejected", "done", "interrupted")


def unpack_feedback(data: bytes, limit: int = 1024 * 1024) -> FeedbackEnvelope:
    message = _unpack(data, limit)
    character = _character(message)
    block = _text(message, "block", CLUSTER_LIMITS.id_chars, empty=True)
    time = message.get("time")
    if not isinstance(time, int | float):
        raise ClusterMessageError("'time' must be a number")
    reply_to = _text(message, "to", CLUSTER_LIMITS.id_chars, empty=True)
    follow = message.get("follow") is True
    outgoing: Outgoing
    if message.get("type") == "feedback":
        kind = _text(message, "kind", 64)
        outgoing = WireFeedback(character, kind, block, float(time), _text(message, "xml", limit))
    elif message.get("type") == "block":
        state = message.get("state")
        if state not in _STATES:
            raise ClusterMessageError(f"unknown block state {state!r}")
        outgoing = BlockEvent(character, block, state, float(time))
    else:
        raise ClusterMessageError(f"unknown feedback type {message.get('type')!r}")
    return FeedbackEnvelope(outgoing, reply_to, follow)


# -- interest (gateway -> workers) ----------------------------------------------------


def pack_want(
    gateway: str,
    wants: dict[str, set[ViewOptions]],
    every: dict[str, set[ViewOptions]] | None = None,
) -> bytes:
    """A gateway's viewer formats per character (all of them, each time);
    ``every``: the formats of which some viewer here takes no ``same``
    message, so that it needs a whole frame every tick."""
    every = every or {}
    return _pack(
        {
            "v": CLUSTER_VERSION,
            "gateway": gateway,
            "characters": {
                character: [
                    {**options_dict(o), "every": o in every.get(character, ())}
                    for o in sorted(formats, key=format_key)
                ]
                for character, formats in wants.items()
            },
        }
    )


Formats = dict[str, frozenset[ViewOptions]]


def unpack_want(
    data: bytes, limits: ClusterLimits = CLUSTER_LIMITS
) -> tuple[str, Formats, Formats]:
    """(gateway, its formats per character, those of them wanted ``every`` tick whole)."""
    message = _unpack(data, 1024 * 1024)
    gateway = _text(message, "gateway", limits.id_chars)
    characters = message.get("characters")
    if not isinstance(characters, dict) or len(characters) > limits.want_characters:
        raise ClusterMessageError(
            f"'characters' must be a map of at most {limits.want_characters} characters"
        )
    wants: Formats = {}
    every: Formats = {}
    for character, formats in characters.items():
        if not isinstance(character, str) or not valid_character_id(character):
            raise ClusterMessageError("invalid character id in a want message")
        if not isinstance(formats, list) or len(formats) > limits.want_formats:
            raise ClusterMessageError(f"at most {limits.want_formats} formats per character")
        wants[character] = frozenset(read_options(f) for f in formats)
        whole = frozenset(read_options(f) for f in formats if f.get("every") is True)
        if whole:
            every[character] = whole
    return gateway, wants, every


# -- frames (owner -> gateways) ---------------------------------------------------------


def content_id(mask: npt.ArrayLike, values: npt.ArrayLike) -> int:
    """What a frame shows, as a 64-bit number: equal for two frames that set
    the same FAPs to the same values (so show the same vertices, coded FAPs
    and ARKit weights), different otherwise (a 64-bit BLAKE2b digest of the
    mask and the set values: a collision is as likely as 1 in 2**64)."""
    shown = np.asarray(mask, dtype=bool)
    set_values = np.where(shown, np.asarray(values, dtype="<f8"), 0.0)
    digest = hashlib.blake2b(shown.tobytes(), digest_size=8)
    digest.update(set_values.tobytes())
    return int.from_bytes(digest.digest(), "little")


@dataclass(frozen=True, slots=True)
class FrameTick:
    """One tick of one character in one viewer format, owner -> gateways.

    ``number`` and ``time``: the frame's ``n`` and ``t`` (the owner's clock);
    ``content``: :func:`content_id` of what it shows; ``frame``: the
    viewer's whole frame message as a viewer receives it, or None when the
    owner sends the tick as a ``same`` (the content is that of the last
    whole frame it published in this format)."""

    number: int
    time: float
    content: int
    frame: bytes | None = None

    def pack(self) -> bytes:
        message: dict[str, Any] = {
            "v": CLUSTER_VERSION,
            "n": self.number,
            "t": self.time,
            "k": self.content,
        }
        if self.frame is not None:
            message["frame"] = self.frame
        return _pack(message, use_bin_type=True)

    @classmethod
    def unpack(cls, data: bytes, limits: ClusterLimits = CLUSTER_LIMITS) -> FrameTick:
        message = _unpack(data, limits.frame_bytes)
        number, time, content = message.get("n"), message.get("t"), message.get("k")
        frame = message.get("frame")
        if not isinstance(number, int) or isinstance(number, bool) or number < 0:
            raise ClusterMessageError("'n' must be a frame number")
        if not isinstance(time, int | float) or isinstance(time, bool) or not math.isfinite(time):
            raise ClusterMessageError("'t' must be a finite number")
        if not isinstance(content, int) or isinstance(content, bool) or not 0 <= content < 2**64:
            raise ClusterMessageError("'k' must be a 64-bit content id")
        if frame is not None and not isinstance(frame, bytes):
            raise ClusterMessageError("'frame' must be bytes")
        return cls(number, float(time), content, frame)


def restamp(frame: bytes, number: int, time: float) -> bytes:
    """A whole frame message moved to frame ``number`` at ``time``: the bytes
    its owner would have encoded for a tick showing the same content (a
    gateway makes it for a viewer that needs a whole frame on a tick the
    owner sent as a ``same``: one that just joined). Decodes and encodes
    once: msgpack keeps the keys' order and every field's type."""
    message = msgpack.unpackb(frame, raw=False)
    if not isinstance(message, dict) or message.get("type") != "frame":
        raise ClusterMessageError("not a frame message")
    message["n"], message["t"] = number, time
    data: bytes = msgpack.packb(message, use_bin_type=True)
    return data


# -- leases (the key-value bucket) ------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LeaseValue:
    """A lease's value: the owning worker and the blocks it had open when it
    last wrote the lease (a taker-over ends those with a warning); the
    owner's host name and its clock's frame 0 on that host's monotonic
    clock (seconds), with which a gateway on the same host times frames
    from their due time (``/health``; ignored on another host)."""

    owner: str
    blocks: tuple[str, ...] = ()
    host: str = ""
    clock: float = 0.0

    def pack(self) -> bytes:
        # JSON, so `nats kv get` shows it as it is.
        message = {"v": CLUSTER_VERSION, "owner": self.owner, "blocks": self.blocks}
        if self.host:
            message.update(host=self.host, clock=self.clock)
        return json.dumps(message).encode()

    @classmethod
    def unpack(cls, data: bytes, limits: ClusterLimits = CLUSTER_LIMITS) -> LeaseValue:
        if len(data) > 64 * 1024:
            raise ClusterMessageError("lease value over 64 KiB")
        try:
            message = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            raise ClusterMessageError("lease value is not JSON") from None
        if not isinstance(message, dict) or message.get("v") != CLUSTER_VERSION:
            raise ClusterMessageError("lease value of another version")
        owner = _text(message, "owner", limits.id_chars)
        blocks = message.get("blocks", [])
        if (
            not isinstance(blocks, list)
            or len(blocks) > limits.lease_blocks
            or not all(isinstance(b, str) and len(b) <= limits.id_chars for b in blocks)
        ):
            raise ClusterMessageError(f"'blocks' must be at most {limits.lease_blocks} block ids")
        host = message.get("host", "")
        clock = message.get("clock", 0.0)
        if not isinstance(host, str) or len(host) > limits.id_chars:
            raise ClusterMessageError(
                f"'host' must be text of at most {limits.id_chars} characters"
            )
        if (
            not isinstance(clock, (int, float))
            or isinstance(clock, bool)
            or not math.isfinite(clock)
        ):
            raise ClusterMessageError("'clock' must be a finite number")
        return cls(owner, tuple(blocks), host, float(clock))
