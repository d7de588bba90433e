"""msgpack layouts of the viewer endpoint: mesh and frame messages.

Bandwidth matters (Tekalp and Ostermann 2000, section 3: MPEG-4's Simple Face level 2 shares
32 kbit/s between 4 faces at 60 Hz), so a frame carries only what is not
neutral:

* FAP frames list only the FAPs that are set, as uint8 FAP numbers with
  float32 values (a smile: a few dozen bytes);
* vertex frames are either every vertex as float32 (n x 12 bytes), or the
  vertices away from the neutral pose as int16 offsets from it in units of
  :data:`DELTA_STEP` metres (k x 10 bytes with their uint32 index).

Deltas are taken from the *neutral pose*, never from the previous frame: a
slow viewer is sent only the newest frame and skips the ones in between
(the service's bounded queues), and every frame must still decode on its
own. This is the lesson of Paul 2010, section 4.2.2, where Xface lost frames
sent quickly one after another and its users fell back to one upload per
250 ms: here a viewer that cannot keep up gets fewer frames, each complete.

All multi-byte numbers are little-endian. Messages are msgpack maps with
string keys; byte fields are msgpack ``bin``. This module is pure (numpy and
msgpack only), shared by the server, the Python client and the tests.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

import msgpack
import numpy as np
import numpy.typing as npt

from realizer.service.errors import BadMessage
from realizer.service.messages import (
    PROTOCOL_VERSION,
    DeltaPayload,
    FapPayload,
    FrameMessage,
    MeshMessage,
    SameMessage,
    ViewOptions,
)

#: Metres per unit of an int16 vertex delta: 10 micrometres, well under a
#: pixel for a face filling a 4K screen, with a range of +-0.33 m.
DELTA_STEP = 1e-5

#: Offsets under half a step quantise to 0 and the vertex is left out.
_INT16_MAX = np.iinfo(np.int16).max

FloatArray = npt.NDArray[np.floating[Any]]


def _fap_tables() -> tuple[bytes, bytes]:
    from realizer.face.faps import FAP_COUNT, FAP_TABLE

    numbers = range(1, FAP_COUNT + 1)
    steps = np.array([FAP_TABLE[n].quant_step for n in numbers], dtype="<u2")
    groups = np.array([FAP_TABLE[n].group for n in numbers], dtype=np.uint8)
    return steps.tobytes(), groups.tobytes()


#: Table 7 steps and Table 2 groups, for decoders of coded FAP frames.
_FAP_STEPS, _FAP_GROUPS = _fap_tables()


def pack(message: Mapping[str, Any]) -> bytes:
    """msgpack bytes of a message (bytes fields as ``bin``)."""
    return cast(bytes, msgpack.packb(message, use_bin_type=True))


def unpack(data: bytes) -> dict[str, Any]:
    """A message from msgpack bytes; raises :class:`BadMessage` if it is none."""
    try:
        message = msgpack.unpackb(data, raw=False)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
        raise BadMessage(f"not a msgpack message: {exc}") from None
    if not isinstance(message, dict) or "type" not in message:
        raise BadMessage("a message is a msgpack map with a 'type'")
    return message


def mesh_message(
    character_id: str,
    neutral: FloatArray,
    faces: npt.NDArray[np.integer[Any]],
    colours: npt.NDArray[np.uint8] | None,
    fps: float,
) -> MeshMessage:
    """The mesh message: ``neutral`` (n, 3) metres, ``faces`` (m, 3) vertex
    indices, ``colours`` (n, 3) uint8 sRGB or None (grey)."""
    neutral32 = np.ascontiguousarray(neutral, dtype="<f4").reshape(-1, 3)
    faces32 = np.ascontiguousarray(faces, dtype="<u4").reshape(-1, 3)
    if colours is None:
        colours = np.full(neutral32.shape, 200, dtype=np.uint8)
    colours8 = np.ascontiguousarray(colours, dtype=np.uint8).reshape(-1, 3)
    return MeshMessage(
        type="mesh",
        v=PROTOCOL_VERSION,
        character=character_id,
        fps=float(fps),
        vertexCount=int(neutral32.shape[0]),
        faceCount=int(faces32.shape[0]),
        faces=faces32.tobytes(),
        neutral=neutral32.tobytes(),
        colours=colours8.tobytes(),
        step=DELTA_STEP,
        fapSteps=_FAP_STEPS,
        fapGroups=_FAP_GROUPS,
    )


def model_message(character_id: str, fields: Mapping[str, Any]) -> dict[str, Any]:
    """The ``model`` message: the deformation model's arrays
    (:func:`realizer.face.gpu_model.model_message_fields`)."""
    return {"type": "model", "v": PROTOCOL_VERSION, "character": character_id, **fields}


def fap_payload(values: FloatArray, mask: npt.NDArray[np.bool_]) -> FapPayload:
    """The set FAPs of a (68,) FAP vector and its (68,) mask."""
    (index,) = np.nonzero(mask)
    return FapPayload(
        ids=(index + 1).astype(np.uint8).tobytes(),
        values=np.asarray(values, dtype="<f4")[index].tobytes(),
    )


def delta_payload(
    vertices: FloatArray, neutral: FloatArray, step: float = DELTA_STEP
) -> DeltaPayload:
    """Quantised offsets of ``vertices`` (n, 3) from ``neutral`` (n, 3), metres."""
    q = np.rint((np.asarray(vertices, dtype=np.float64) - neutral) / step)
    np.clip(q, -_INT16_MAX, _INT16_MAX, out=q)
    moved = np.flatnonzero(np.any(q != 0, axis=1))
    return DeltaPayload(
        ids=moved.astype("<u4").tobytes(),
        q=q[moved].astype("<i2").tobytes(),
    )


def frame_message(
    character_id: str,
    number: int,
    time: float,
    options: ViewOptions,
    *,
    fap: FapPayload | None = None,
    vertices: bytes | None = None,
    delta: DeltaPayload | None = None,
    coded: tuple[bytes, int | None] | None = None,
    arkit: bytes | None = None,
) -> FrameMessage:
    """A frame message with the payloads ``options`` asks for."""
    message = FrameMessage(
        type="frame", v=PROTOCOL_VERSION, character=character_id, n=number, t=time
    )
    if options.fap and fap is not None:
        message["fap"] = fap
    if options.vertices == "float32" and vertices is not None:
        message["vertices"] = vertices
    elif options.vertices == "int16" and delta is not None:
        message["delta"] = delta
    if options.coded and coded is not None:
        message["coded"] = coded[0]
        if coded[1] is not None:
            message["codedRef"] = coded[1]
    if options.arkit and arkit is not None:
        message["arkit"] = arkit
    return message


def same_message(number: int) -> bytes:
    """The packed ``same`` message of frame ``number`` (21 bytes or fewer)."""
    return pack(SameMessage(type="same", v=PROTOCOL_VERSION, n=number))


# -- decoding (clients, tests) ------------------------------------------------


def decode_faps(payload: Mapping[str, bytes]) -> dict[int, float]:
    """{FAP number: value} of a frame's ``fap`` payload."""
    ids = np.frombuffer(payload["ids"], dtype=np.uint8)
    values = np.frombuffer(payload["values"], dtype="<f4")
    return {int(i): float(v) for i, v in zip(ids, values, strict=True)}


def decode_vertices(frame: Mapping[str, Any], mesh: Mapping[str, Any]) -> npt.NDArray[np.float32]:
    """(n, 3) float32 vertex positions of a frame, given its mesh message.

    A frame without vertices or deltas decodes to the neutral pose.
    """
    neutral = np.frombuffer(mesh["neutral"], dtype="<f4").reshape(-1, 3)
    if "vertices" in frame:
        return np.frombuffer(frame["vertices"], dtype="<f4").reshape(-1, 3).copy()
    out = neutral.copy()
    if "delta" in frame:
        ids = np.frombuffer(frame["delta"]["ids"], dtype="<u4")
        q = np.frombuffer(frame["delta"]["q"], dtype="<i2").reshape(-1, 3)
        out[ids] += q.astype(np.float32) * np.float32(mesh["step"])
    return out
