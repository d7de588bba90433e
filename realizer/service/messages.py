"""Every message of the two WebSocket endpoints, as typed dictionaries.

The wire protocol is specified in ``protocols/`` (everything on the wire is
documented there); this module is its Python mirror. As in uvicorn, each message is a
``TypedDict`` tagged by a ``Literal`` ``type`` field, so a reader sees every
field in one place and mypy checks the code that builds them.

Submitter endpoint ``/bml`` (text frames): a client sends plain BML, or a
JSON envelope (:class:`BmlRequest`, :class:`InterruptRequest`); the server
answers with BML feedback XML, or, when the client asked for ``format=json``,
with :class:`WelcomeMessage`, :class:`FeedbackMessage` and
:class:`BlockMessage`.

Viewer endpoint ``/view`` (binary msgpack frames from the server; text JSON
:class:`SubscribeRequest` from the client): :class:`MeshMessage` first, then
one :class:`FrameMessage` per clock tick (with ``same=true``: per tick whose
content changed, and a :class:`SameMessage` of a few bytes for each tick that
shows the same). The layouts of their byte fields are in :mod:`realizer.service.codec`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Literal, NotRequired, TypedDict

from realizer.feedback import warning
from realizer.service.errors import BadMessage

#: Version of both endpoints' messages; bumped on any incompatible change.
PROTOCOL_VERSION = 1

FeedbackFormat = Literal["xml", "json"]
VertexEncoding = Literal["none", "float32", "int16"]
BlockState = Literal["accepted", "rejected", "done", "interrupted", "failed"]


# -- submitter, client to server ---------------------------------------------


class BmlRequest(TypedDict):
    """Run a BML block. ``character`` overrides the block's ``characterId``."""

    type: Literal["bml"]
    bml: str
    character: NotRequired[str]


class InterruptRequest(TypedDict):
    """Interrupt a pending or running block by its id."""

    type: Literal["interrupt"]
    block: str
    character: NotRequired[str]


class TargetRequest(TypedDict):
    """Place or move a named scene target (realizer.scene) while blocks run."""

    type: Literal["target"]
    name: str
    position: list[float]  # [x, y, z] metres


# -- submitter, server to client (format=json) -------------------------------


class WelcomeMessage(TypedDict):
    type: Literal["welcome"]
    protocol: int
    server: str  # the realizer's version
    character: str  # the connection's default character
    fps: float  # frames per second of the clock
    limits: dict[str, int]


class FeedbackMessage(TypedDict):
    """One BML 1.0 feedback element. ``time``: session seconds."""

    type: Literal["feedback"]
    character: str
    kind: str  # prediction, blockProgress, syncPointProgress, warning
    block: str
    time: float
    xml: str


class BlockMessage(TypedDict):
    """A block's state changed: accepted, rejected, done or interrupted."""

    type: Literal["block"]
    character: str
    block: str
    state: BlockState
    time: float


# -- viewer, client to server -------------------------------------------------


class SubscribeRequest(TypedDict):
    """Switch the viewer to ``character`` and/or change what it receives."""

    type: Literal["subscribe"]
    character: NotRequired[str]
    fap: NotRequired[bool]
    vertices: NotRequired[VertexEncoding]
    coded: NotRequired[bool]
    arkit: NotRequired[bool]
    audio: NotRequired[Literal["pcm16", "none"]]
    scene: NotRequired[bool]
    same: NotRequired[bool]


# -- viewer, server to client (msgpack) ---------------------------------------


class MeshMessage(TypedDict):
    """Topology and neutral pose; sent first, and after every subscribe.

    ``faces``: (m, 3) uint32 little-endian; ``neutral``: (n, 3) float32
    little-endian metres; ``colours``: (n, 3) uint8 sRGB; ``step``: metres
    per unit of the int16 vertex deltas.
    """

    type: Literal["mesh"]
    v: int
    character: str
    fps: float
    vertexCount: int
    faceCount: int
    faces: bytes
    neutral: bytes
    colours: bytes
    step: float
    fapSteps: bytes  # 68 uint16: Table 7 quantisation steps, for coded FAPs
    fapGroups: bytes  # 68 uint8: Table 2 group of each FAP


class FapPayload(TypedDict):
    """The FAPs that are set: ``ids`` uint8 FAP numbers 1..68, ``values``
    float32 little-endian in FAPU-scaled units, same order."""

    ids: bytes
    values: bytes


class DeltaPayload(TypedDict):
    """Vertices away from the neutral pose: ``ids`` uint32 little-endian
    vertex indices, ``q`` (k, 3) int16 little-endian offsets in units of the
    mesh's ``step``. Vertices not listed are at the neutral pose."""

    ids: bytes
    q: bytes


class FrameMessage(TypedDict):
    """One tick of the clock for one character. ``n``: frame number (frame n
    is due at n / fps seconds after the clock started); ``t``: session
    seconds the frame shows."""

    type: Literal["frame"]
    v: int
    character: str
    n: int
    t: float
    fap: NotRequired[FapPayload]
    vertices: NotRequired[bytes]  # (n, 3) float32 little-endian, metres
    delta: NotRequired[DeltaPayload]
    coded: NotRequired[bytes]  # one MPEG-4 low-delay coded FAP frame
    codedRef: NotRequired[int]  # frame number it is predicted from (absent: intra)
    arkit: NotRequired[bytes]  # 52 uint8 ARKit weights (x / 255)


class AudioMessage(TypedDict):
    """Speech audio: ``count`` mono int16 little-endian ``samples`` at
    ``rate`` Hz; the first plays at ``t`` seconds of the server clock
    (protocols/viewer.md, "audio")."""

    type: Literal["audio"]
    v: int
    character: str
    t: float
    rate: int
    channels: int
    format: Literal["pcm16"]
    count: int
    samples: bytes


class AudioCutMessage(TypedDict):
    """Audio already sent that plays at or after ``t`` must not play (an interruption)."""

    type: Literal["audioCut"]
    v: int
    character: str
    t: float


class SameMessage(TypedDict):
    """Frame ``n`` shows exactly what the last frame sent to this viewer
    showed: nothing to say, so nearly nothing is sent (protocols/viewer.md)."""

    type: Literal["same"]
    v: int
    n: int


# -- reading client messages ---------------------------------------------------


@dataclass(frozen=True, slots=True)
class ViewOptions:
    """What one viewer receives each tick."""

    fap: bool = True
    vertices: VertexEncoding = "none"
    coded: bool = False  # MPEG-4 low-delay coded FAPs (realizer.face.fapcoding)
    arkit: bool = False  # the 52 ARKit blendshape weights

    def __post_init__(self) -> None:
        if self.vertices not in ("none", "float32", "int16"):
            raise BadMessage(f"vertices must be none, float32 or int16, not {self.vertices!r}")


SubmitterRequest = BmlRequest | InterruptRequest | TargetRequest

#: Digits of the longest integer a JSON message may hold (Python refuses to
#: convert more than 4,300 and spends quadratic time getting there).
MAX_JSON_INT_DIGITS = 20


def _refuse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_JSON_INT_DIGITS:
        raise BadMessage(f"an integer of more than {MAX_JSON_INT_DIGITS} digits")
    return int(text)


def _refuse_constant(name: str) -> float:
    raise BadMessage(f"{name} is not JSON")


def _load_json(text: str, what: str) -> object:
    """``text`` as JSON, or :class:`BadMessage` (never another exception).

    Linear in the text's length; deep nesting is refused by the decoder's
    recursion limit (it answers like any malformed message), long integers
    and the non-standard ``NaN``/``Infinity`` are refused.
    """
    try:
        return json.loads(text, parse_int=_refuse_int, parse_constant=_refuse_constant)
    except json.JSONDecodeError as exc:
        raise BadMessage(
            f"malformed JSON in the {what} at line {exc.lineno}, column {exc.colno}"
        ) from None
    except RecursionError:
        raise BadMessage(f"the {what} is nested too deeply") from None
    except ValueError as exc:  # a number the decoder cannot convert
        raise BadMessage(f"a number in the {what} cannot be read") from exc


def _text_field(value: object, name: str) -> str:
    """A JSON string field that is text: lone surrogates (``"\\udc80"``) are not."""
    if not isinstance(value, str):
        raise BadMessage(f"{name} must be a string")
    if not value.isascii():
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            raise BadMessage(f"{name} holds a lone surrogate, which is not text") from None
    return value


def read_submitter_message(text: str) -> SubmitterRequest:
    """A submitter's text message as a request: plain BML or a JSON envelope.

    Raises :class:`BadMessage` for anything else; the caller answers it with
    a ``warningFeedback`` and the connection goes on.
    """
    head = text.lstrip()[:1]
    if head == "<":
        return BmlRequest(type="bml", bml=text)
    if head != "{":
        raise BadMessage("expected a BML document or a JSON object")
    data = _load_json(text, "message")
    if not isinstance(data, dict):
        raise BadMessage("expected a JSON object")
    kind = data.get("type")
    character = data.get("character")
    if character is not None:
        character = _text_field(character, "character")
    if kind == "bml":
        bml = data.get("bml")
        if not isinstance(bml, str):
            raise BadMessage("a bml message needs the BML text in its 'bml' field")
        bml = _text_field(bml, "bml")
        request = BmlRequest(type="bml", bml=bml)
        if character is not None:
            request["character"] = character
        return request
    if kind == "interrupt":
        block = data.get("block")
        if not isinstance(block, str) or not block:
            raise BadMessage("an interrupt message needs the block id in its 'block' field")
        block = _text_field(block, "block")
        interrupt = InterruptRequest(type="interrupt", block=block)
        if character is not None:
            interrupt["character"] = character
        return interrupt
    if kind == "target":
        name = data.get("name")
        position = data.get("position")
        if not isinstance(name, str) or not name:
            raise BadMessage("a target message needs the target's name in its 'name' field")
        if (
            not isinstance(position, list)
            or len(position) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in position)
        ):
            raise BadMessage("a target message needs 'position': [x, y, z] in metres")
        return TargetRequest(
            type="target", name=_text_field(name, "name"), position=[float(v) for v in position]
        )
    raise BadMessage(
        f"unknown message type {str(kind)[:40]!r}; expected 'bml', 'interrupt' or 'target'"
    )


def read_subscribe_message(text: str) -> SubscribeRequest:
    """A viewer's text message; raises :class:`BadMessage` when it is not one."""
    data = _load_json(text, "subscribe message")
    if not isinstance(data, dict) or data.get("type") != "subscribe":
        raise BadMessage("expected a JSON object with type 'subscribe'")
    request = SubscribeRequest(type="subscribe")
    if "character" in data:
        request["character"] = _text_field(data["character"], "character")
    if "fap" in data:
        if not isinstance(data["fap"], bool):
            raise BadMessage("fap must be true or false")
        request["fap"] = data["fap"]
    for name in ("coded", "arkit", "scene", "same"):
        if name in data:
            if not isinstance(data[name], bool):
                raise BadMessage(f"{name} must be true or false")
            request[name] = data[name]
    if "vertices" in data:
        vertices = data["vertices"]
        if vertices == "none" or vertices == "float32" or vertices == "int16":
            request["vertices"] = vertices
        else:
            raise BadMessage("vertices must be none, float32 or int16")
    if "audio" in data:
        audio = data["audio"]
        if audio == "pcm16" or audio == "none":
            request["audio"] = audio
        else:
            raise BadMessage("audio must be pcm16 or none")
    return request


def warning_feedback_xml(block_id: str, character_id: str, warning_type: str, text: str) -> str:
    """A BML 1.0 ``warningFeedback`` element for a warning the service makes
    (the same element the session writes, :func:`realizer.feedback.warning`)."""
    return warning(block_id, block_id, warning_type, text, 0.0, character_id).xml
