"""glTF 2.0 binary (GLB) avatars: what the browser viewer needs of one, and a test avatar.

An avatar for ``realizer serve --avatar model.glb`` (glTF 2.0 binary; VRM
files are glTF too) has morph targets named after Apple's 52 ARKit
blendshapes (``mesh.extras.targetNames``, the convention of Blender's and
three.js' glTF tools), and optionally nodes (bones) named ``head``,
``leftEye`` and ``rightEye`` (or the Mixamo and VRM names the viewer also
looks for) that the head and eye angles turn. :func:`avatar_report` reads a
GLB's JSON chunk and lists the ARKit targets it lacks; the service warns
once with that list and the rest still animate.

:func:`default_face_glb` writes the default face as such an avatar, with
its CC0 ARKit targets as sparse morph targets: the test avatar, made when
needed (it is about 1.5 MB, so it is never committed).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from realizer.face.errors import FaceError

GLB_MAGIC = 0x46546C67  # "glTF"
JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942
#: A GLB's JSON chunk larger than this is refused (names are all we read).
MAX_JSON_BYTES = 16 * 1024 * 1024


@dataclass(frozen=True, slots=True)
class AvatarReport:
    """What an avatar offers the viewer: its ARKit morph targets, the ones missing, its bones."""

    targets: tuple[str, ...]
    missing: tuple[str, ...]
    bones: tuple[str, ...]


HEAD_BONES = ("head", "Head", "mixamorigHead", "J_Bip_C_Head")
EYE_BONES = (
    "leftEye", "LeftEye", "eye_L", "J_Adj_L_FaceEye", "mixamorigLeftEye",
    "rightEye", "RightEye", "eye_R", "J_Adj_R_FaceEye", "mixamorigRightEye",
)  # fmt: skip


def glb_json(data: bytes) -> dict[str, Any]:
    """The JSON chunk of a GLB file; raises :class:`FaceError` if it is not one."""
    if len(data) < 20:
        raise FaceError("not a glTF binary: too short")
    magic, version, _ = struct.unpack_from("<III", data, 0)
    if magic != GLB_MAGIC or version != 2:
        raise FaceError("not a glTF 2.0 binary (.glb)")
    chunk_length, chunk_type = struct.unpack_from("<II", data, 12)
    if chunk_type != JSON_CHUNK or chunk_length > min(MAX_JSON_BYTES, len(data) - 20):
        raise FaceError("a glTF binary starts with its JSON chunk")
    try:
        parsed = json.loads(data[20 : 20 + chunk_length].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FaceError(f"the glTF JSON chunk is malformed: {exc}") from None
    if not isinstance(parsed, dict):
        raise FaceError("the glTF JSON chunk is not an object")
    return parsed


def avatar_report(data: bytes) -> AvatarReport:
    """The ARKit targets and bones of a GLB avatar (see the module docstring)."""
    from realizer.face.arkit import ARKIT_NAMES

    document = glb_json(data)
    names: set[str] = set()
    for mesh in document.get("meshes", []) or []:
        extras = mesh.get("extras") if isinstance(mesh, dict) else None
        for name in (extras or {}).get("targetNames", []) or []:
            if isinstance(name, str):
                names.add(name)
    nodes = {n.get("name") for n in document.get("nodes", []) or [] if isinstance(n, dict)}
    bones = tuple(b for b in (*HEAD_BONES, *EYE_BONES) if b in nodes)
    targets = tuple(n for n in ARKIT_NAMES if n in names)
    missing = tuple(n for n in ARKIT_NAMES if n not in names)
    return AvatarReport(targets, missing, bones)


# -- writing the test avatar -----------------------------------------------------------


class _Buffer:
    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def view(self, array: np.ndarray, target: int | None = None) -> int:
        while len(self.data) % 4:
            self.data.append(0)
        raw = np.ascontiguousarray(array).tobytes()
        entry: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target is not None:
            entry["target"] = target
        self.data.extend(raw)
        self.views.append(entry)
        return len(self.views) - 1

    def accessor(self, array: np.ndarray, kind: str, target: int | None = None) -> int:
        component = {np.dtype("<f4"): 5126, np.dtype("<u4"): 5125, np.dtype("<u2"): 5123}
        entry: dict[str, Any] = {
            "bufferView": self.view(array, target),
            "componentType": component[array.dtype],
            "count": int(array.shape[0]),
            "type": kind,
        }
        if kind == "VEC3" and array.dtype == np.dtype("<f4"):
            entry["min"] = [float(x) for x in array.min(axis=0)]
            entry["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(entry)
        return len(self.accessors) - 1

    def sparse(self, count: int, index: np.ndarray, values: np.ndarray) -> int:
        entry: dict[str, Any] = {
            "componentType": 5126,
            "count": count,
            "type": "VEC3",
            "min": [float(x) for x in values.min(axis=0)] if values.size else [0.0] * 3,
            "max": [float(x) for x in values.max(axis=0)] if values.size else [0.0] * 3,
            "sparse": {
                "count": int(index.size),
                "indices": {"bufferView": self.view(index.astype("<u4")), "componentType": 5125},
                "values": {"bufferView": self.view(values.astype("<f4"))},
            },
        }
        self.accessors.append(entry)
        return len(self.accessors) - 1


def default_face_glb(omit: tuple[str, ...] = ()) -> bytes:
    """The default face as a GLB avatar: the skin with the ARKit targets as
    sparse morph targets (minus ``omit``), eyes, teeth and tongue as plain
    meshes, under nodes ``head`` (pivot at the neck), ``leftEye`` and
    ``rightEye`` (pivots at the eyeball centres)."""
    from realizer.face.arkit import ARKIT_NAMES, arkit_targets
    from realizer.face.default import load_default_face
    from realizer.face.render import vertex_colours

    face = load_default_face()
    vertices = np.asarray(face.vertices, dtype=np.float64)
    # glTF's COLOR_0 is linear, as the renderer's part colours are
    colours = np.clip(np.asarray(vertex_colours(face), dtype=np.float32), 0.0, 1.0)
    moved, offsets = arkit_targets(face)
    buffer = _Buffer()
    meshes: list[dict[str, Any]] = []
    materials = [{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.6}}]

    def part_mesh(name: str, parts: tuple[str, ...], pivot: np.ndarray, morphs: bool) -> int:
        chosen = np.unique(np.concatenate([face.part(p) for p in parts])).astype(np.int64)
        remap = np.full(face.vertex_count, -1, dtype=np.int64)
        remap[chosen] = np.arange(chosen.size)
        tri = np.asarray(face.faces, dtype=np.int64)
        keep = np.all(remap[tri] >= 0, axis=1)
        triangles = remap[tri[keep]].astype("<u4").reshape(-1)
        primitive: dict[str, Any] = {
            "attributes": {
                "POSITION": buffer.accessor(
                    (vertices[chosen] - pivot).astype("<f4"), "VEC3", 34962
                ),
                "COLOR_0": buffer.accessor(colours[chosen].astype("<f4"), "VEC3", 34962),
            },
            "indices": buffer.accessor(triangles, "SCALAR", 34963),
            "material": 0,
        }
        mesh: dict[str, Any] = {"name": name, "primitives": [primitive]}
        if morphs:
            names, targets = [], []
            local = remap[moved]
            inside = local >= 0
            for t, target_name in enumerate(ARKIT_NAMES):
                if target_name in omit:
                    continue
                nonzero = inside & np.any(offsets[t] != 0, axis=1)
                index = local[nonzero]
                order = np.argsort(index)
                targets.append(
                    {
                        "POSITION": buffer.sparse(
                            chosen.size, index[order], offsets[t][nonzero][order]
                        )
                    }
                )
                names.append(target_name)
            primitive["targets"] = targets
            mesh["weights"] = [0.0] * len(names)
            mesh["extras"] = {"targetNames": names}
        meshes.append(mesh)
        return len(meshes) - 1

    neck = vertices[face.part("skin")].min(axis=0) * [0, 1, 0] + vertices.mean(axis=0) * [1, 0, 1]
    left_centre = vertices[face.part("left_eye")].mean(axis=0)
    right_centre = vertices[face.part("right_eye")].mean(axis=0)
    inner = tuple(
        p for p in ("upper_teeth", "lower_teeth", "tongue", "mouth_inside") if p in face.parts
    )
    skin = part_mesh("skin", ("skin",), neck, True)
    mouth = part_mesh("mouth", inner, neck, False) if inner else None
    left = part_mesh("leftEyeball", ("left_eye", "left_pupil"), left_centre, False)
    right = part_mesh("rightEyeball", ("right_eye", "right_pupil"), right_centre, False)
    nodes: list[dict[str, Any]] = [
        {"name": "head", "translation": [float(x) for x in neck], "children": [1, 2, 3]},
        {"name": "face", "mesh": skin},
        {"name": "leftEye", "translation": [float(x) for x in left_centre - neck], "children": [4]},
        {
            "name": "rightEye",
            "translation": [float(x) for x in right_centre - neck],
            "children": [5],
        },
        {"name": "leftEyeball", "mesh": left},
        {"name": "rightEyeball", "mesh": right},
    ]
    if mouth is not None:
        nodes[0]["children"].append(6)
        nodes.append({"name": "mouth", "mesh": mouth})
    document = {
        "asset": {"version": "2.0", "generator": "realizer default_face_glb",
                  "copyright": "CC0 1.0: MakeHuman hm08 and Face Units targets"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": buffer.accessors,
        "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(buffer.data)}],
    }  # fmt: skip
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    binary = bytes(buffer.data) + b"\0" * (-len(buffer.data) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (
        struct.pack("<III", GLB_MAGIC, 2, total)
        + struct.pack("<II", len(text), JSON_CHUNK)
        + text
        + struct.pack("<II", len(binary), BIN_CHUNK)
        + binary
    )
