"""The deformation model as flat arrays, for a GPU (or any other evaluator).

MPEG-4 face animation sends the face model once and then only parameters
("Face and 2-D mesh animation in MPEG-4", sections 2.1.3 and 2.2): the
decoder owns the deformation. This module turns the compiled
:class:`realizer.face.deform.FaceRig` of a face (the one model the server's
:func:`realizer.face.deform.deform` evaluates) into a handful of arrays that
a vertex shader evaluates per vertex with no branching on the face's
structure, and :meth:`GpuModel.evaluate` evaluates the same arrays with
numpy (the tests check it equals :func:`deform`, and that the browser's
shader and JavaScript equal it).

Per frame, from a (68,) FAP vector ``v`` (unidirectional FAPs clamped at 0,
FAPs 1 and 2 ignored):

1. **Column amounts** (metres): ``a_j = (clip(v[fap_j], low_j, high_j) -
   zero_j) * unit_j`` for every column j. Influence columns have
   ``low=-inf, high=+inf, zero=0``; FaceDefMesh intervals and pupil dilation
   columns their interval borders.
2. **Displacements**: every vertex owns a run of *entries*, texels of four
   floats ``(code, column, coef, mag)``, ``code = axis + 3 * kind``. Kind 0
   (influence deformers) adds ``push = coef * a`` to the axis' positive or
   negative sum and ``peak = mag * |a|`` to the same side's peak, and the
   axis moves ``min(pos sum, pos peak) - min(neg sum, neg peak)`` (the capped
   sums of :mod:`realizer.face.deform`); kind 1 (FaceDefMesh, dilation) adds
   ``coef * a`` linearly.
3. **Rigid groups**: per frame each group's members (rotations and
   translations in order) compose to one affine map ``M_g`` (a 4x4 matrix);
   every vertex owns a run of ``(group, weight)`` pairs, in group order, and
   moves ``p <- p + weight * (M_g p - p)`` for each.
4. **Pose**: the members of the head motion that moves every vertex compose
   to one matrix applied last.

The arrays are sent to viewers once (``/view?model=true``, the ``model``
message of ``protocols/viewer.md``); :func:`model_message_fields` lays them
out as little-endian bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from realizer.face.deform import FaceRig, _Transform, _TransformGroup, rig_for
from realizer.face.faps import FAP_COUNT, as_fap_vector, unidirectional_mask

#: Version of the model's layout (the ``model`` message's ``layout``).
MODEL_LAYOUT = 1

#: Member kinds in :attr:`GpuModel.members`.
TRANSLATION, ROTATION = 0, 1

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class GpuModel:
    """The arrays of the module docstring; shapes in the field comments.

    ``members``: (k, 9) float64 rows ``(group, kind, fap_index, unit, ax,
    ay, az, px, py, pz)`` minus nothing: see :data:`MEMBER_FIELDS`; groups
    ``0..group_count-1`` are per-vertex groups, group ``-1`` the pose.
    """

    neutral: npt.NDArray[np.float32]  # (n, 3) metres
    column_fap: npt.NDArray[np.int64]  # (c,) FAP index 0..67
    column_unit: FloatArray  # (c,) metres per FAP unit
    column_low: FloatArray  # (c,)
    column_high: FloatArray  # (c,)
    column_zero: FloatArray  # (c,)
    entries: npt.NDArray[np.float32]  # (e, 4) code, column, coef, mag; by vertex
    ranges: npt.NDArray[np.uint32]  # (n, 4) entry start, count, link start, count
    links: npt.NDArray[np.float32]  # (l, 2) group, weight; by vertex then group
    members: FloatArray  # (k, 10): MEMBER_FIELDS
    group_count: int
    unidirectional: npt.NDArray[np.bool_]  # (68,)

    # -- numpy evaluation of the arrays (the reference for the viewer) -----------

    def amounts(self, fap_vector: object) -> FloatArray:
        """(c,) column amounts, metres, for a (68,) FAP vector."""
        values = self.prepared(fap_vector)
        v = values[self.column_fap]
        out: FloatArray = (np.clip(v, self.column_low, self.column_high) - self.column_zero) * (
            self.column_unit
        )
        return out

    def prepared(self, fap_vector: object) -> FloatArray:
        values = np.array(as_fap_vector(fap_vector), dtype=np.float64)
        values[self.unidirectional] = np.maximum(values[self.unidirectional], 0.0)
        values[:2] = 0.0
        return values

    def group_matrices(self, fap_vector: object) -> tuple[FloatArray, FloatArray]:
        """((g, 4, 4) per-vertex group maps, (4, 4) pose) for a FAP vector."""
        values = self.prepared(fap_vector)
        groups = np.repeat(np.eye(4)[None], self.group_count, axis=0)
        pose = np.eye(4)
        for row in self.members:
            group, kind, fap_index = int(row[0]), int(row[1]), int(row[2])
            amount = float(values[fap_index]) * float(row[3])
            if amount == 0.0:
                continue
            step = np.eye(4)
            axis = row[4:7]
            if kind == TRANSLATION:
                step[:3, 3] = amount * axis
            else:
                turn = _rodrigues(axis, amount)
                pivot = row[7:10]
                step[:3, :3] = turn
                step[:3, 3] = pivot - turn @ pivot
            if group < 0:
                pose = step @ pose
            else:
                groups[group] = step @ groups[group]
        return groups, pose

    def evaluate(self, fap_vector: object) -> npt.NDArray[np.float32]:
        """(n, 3) float32 deformed vertices, metres: what the viewer's shader computes."""
        amount = self.amounts(fap_vector)
        n = self.neutral.shape[0]
        counts = self.ranges[:, 1].astype(np.int64)
        vertex = np.repeat(np.arange(n), counts)
        code = self.entries[:, 0].astype(np.int64)
        axis, kind = code % 3, code // 3
        value = amount[self.entries[:, 1].astype(np.int64)]
        coef = self.entries[:, 2].astype(np.float64)
        mag = self.entries[:, 3].astype(np.float64)
        row = vertex * 3 + axis
        linear = np.bincount(row[kind == 1], (coef * value)[kind == 1], minlength=3 * n)
        capped = kind == 0
        push = coef[capped] * value[capped]
        peak = mag[capped] * np.abs(value[capped])
        bucket = row[capped] * 2 + (push < 0)
        sums = np.bincount(bucket, np.abs(push), minlength=6 * n)
        peaks = np.zeros(6 * n)
        np.maximum.at(peaks, bucket, peak)
        side = np.minimum(sums, peaks).reshape(-1, 2)
        displacement = (side[:, 0] - side[:, 1] + linear).reshape(n, 3)
        points = self.neutral.astype(np.float64) + displacement
        groups, pose = self.group_matrices(fap_vector)
        link_vertex = np.repeat(np.arange(n), self.ranges[:, 3].astype(np.int64))
        link_group = self.links[:, 0].astype(np.int64)
        weight = self.links[:, 1].astype(np.float64)
        # links are ordered by group within each vertex and a vertex has at
        # most one link per group, so applying group by group keeps the order
        for g in range(self.group_count):
            chosen = link_group == g
            if not np.any(chosen):
                continue
            rows = link_vertex[chosen]
            p = points[rows]
            moved = p @ groups[g][:3, :3].T + groups[g][:3, 3]
            points[rows] = p + weight[chosen, None] * (moved - p)
        points = points @ pose[:3, :3].T + pose[:3, 3]
        return points.astype(np.float32)


#: Columns of :attr:`GpuModel.members`.
MEMBER_FIELDS = ("group", "kind", "fap", "unit", "ax", "ay", "az", "px", "py", "pz")


def _rodrigues(axis: FloatArray, angle: float) -> FloatArray:
    x, y, z = (float(c) for c in axis)
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return np.array(
        [
            [c + t * x * x, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, c + t * y * y, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, c + t * z * z],
        ]
    )


def _member_rows(group: int, members: tuple[_Transform, ...]) -> list[list[float]]:
    rows = []
    for m in members:
        kind = TRANSLATION if m.kind == "translation" else ROTATION
        rows.append([group, kind, m.fap_index, m.unit, *m.axis_tuple, *m.pivot_tuple])
    return rows


def _group_vertices(group: _TransformGroup, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, weights) a per-vertex group moves (weight 1 = rigidly)."""
    if group.indices is None:
        rigid = np.arange(n)
    elif isinstance(group.indices, slice):
        rigid = np.arange(n)[group.indices]
    else:
        rigid = np.asarray(group.indices, dtype=np.int64)
    vertices = [rigid]
    weights = [np.ones(rigid.size)]
    if group.blend is not None and group.weights is not None and group.blend.size:
        vertices.append(np.asarray(group.blend, dtype=np.int64))
        weights.append(np.asarray(group.weights, dtype=np.float64).reshape(-1))
    return np.concatenate(vertices), np.concatenate(weights)


def build_gpu_model(rig: FaceRig) -> GpuModel:
    """The arrays of a compiled rig (see the module docstring)."""
    n = rig.face.vertex_count
    neutral = np.ascontiguousarray(rig.neutral, dtype=np.float32)
    col_fap: list[np.ndarray] = []
    col_unit: list[np.ndarray] = []
    col_low: list[np.ndarray] = []
    col_high: list[np.ndarray] = []
    col_zero: list[np.ndarray] = []
    # entries as (flat row, kind, column, coef, mag)
    e_row: list[np.ndarray] = []
    e_kind: list[np.ndarray] = []
    e_col: list[np.ndarray] = []
    e_coef: list[np.ndarray] = []
    e_mag: list[np.ndarray] = []
    offset = 0
    if rig._has_influence:
        c = rig._columns
        col_fap.append(rig.influence_fap)
        col_unit.append(np.asarray(rig.influence_unit, dtype=np.float64))
        col_low.append(np.full(c, -np.inf))
        col_high.append(np.full(c, np.inf))
        col_zero.append(np.zeros(c))
        single, multi = rig._single, rig._multi
        e_row += [single.rows, rig._multi_rows[multi.rows]]
        e_col += [single.column, multi.column]
        e_coef += [single.coef, multi.coef]
        e_mag += [single.mag, multi.mag]
        e_kind += [np.zeros(single.rows.size), np.zeros(multi.rows.size)]
        offset = c
    if rig._has_summed:
        col_fap.append(rig._summed_fap)
        col_unit.append(rig.fapu_per_fap[rig._summed_fap])
        col_low.append(rig._summed_low)
        col_high.append(rig._summed_high)
        col_zero.append(rig._summed_zero)
        coo = rig._summed_matrix.tocoo()
        e_row.append(rig._summed_rows[coo.row])
        e_col.append(coo.col + offset)
        e_coef.append(coo.data)
        e_mag.append(np.zeros(coo.data.size))
        e_kind.append(np.ones(coo.data.size))
    if e_row:
        rows = np.concatenate(e_row).astype(np.int64)
        order = np.argsort(rows // 3, kind="stable")
        rows = rows[order]
        code = rows % 3 + 3 * np.concatenate(e_kind)[order]
        entries = np.stack(
            [
                code,
                np.concatenate(e_col)[order],
                np.concatenate(e_coef)[order],
                np.concatenate(e_mag)[order],
            ],
            axis=1,
        ).astype(np.float32)
        entry_counts = np.bincount(rows // 3, minlength=n)
    else:
        entries = np.zeros((0, 4), dtype=np.float32)
        entry_counts = np.zeros(n, dtype=np.int64)
    members: list[list[float]] = []
    l_vertex: list[np.ndarray] = []
    l_group: list[np.ndarray] = []
    l_weight: list[np.ndarray] = []
    for g, group in enumerate(rig._groups):
        members += _member_rows(g, group.members)
        vertices, weights = _group_vertices(group, n)
        l_vertex.append(vertices)
        l_group.append(np.full(vertices.size, g))
        l_weight.append(weights)
    for group in rig._pose_groups:
        members += _member_rows(-1, group.members)
    if l_vertex:
        lv = np.concatenate(l_vertex)
        lg = np.concatenate(l_group)
        order = np.lexsort((lg, lv))
        links = np.stack([lg[order], np.concatenate(l_weight)[order]], axis=1).astype(np.float32)
        link_counts = np.bincount(lv, minlength=n)
    else:
        links = np.zeros((0, 2), dtype=np.float32)
        link_counts = np.zeros(n, dtype=np.int64)
    ranges = np.stack(
        [
            np.concatenate([[0], np.cumsum(entry_counts)[:-1]]),
            entry_counts,
            np.concatenate([[0], np.cumsum(link_counts)[:-1]]),
            link_counts,
        ],
        axis=1,
    ).astype(np.uint32)

    def cat(parts: list[np.ndarray], dtype: Any) -> Any:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype=dtype)

    return GpuModel(
        neutral=neutral,
        column_fap=cat(col_fap, np.int64),
        column_unit=cat(col_unit, np.float64),
        column_low=cat(col_low, np.float64),
        column_high=cat(col_high, np.float64),
        column_zero=cat(col_zero, np.float64),
        entries=entries,
        ranges=ranges,
        links=links,
        members=np.asarray(members, dtype=np.float64).reshape(-1, len(MEMBER_FIELDS)),
        group_count=len(rig._groups),
        unidirectional=unidirectional_mask().copy(),
    )


def gpu_model_for(face: Any) -> GpuModel:
    """The :class:`GpuModel` of a face (its rig compiled once, cached)."""
    return build_gpu_model(rig_for(face))


def model_message_fields(model: GpuModel) -> dict[str, Any]:
    """The ``model`` message's fields (protocols/viewer.md), bytes little-endian.

    Infinite interval borders are sent as float32 +-inf, which msgpack and
    JavaScript carry exactly.
    """
    return {
        "layout": MODEL_LAYOUT,
        "fapCount": FAP_COUNT,
        "columnCount": int(model.column_fap.size),
        "entryCount": int(model.entries.shape[0]),
        "linkCount": int(model.links.shape[0]),
        "groupCount": int(model.group_count),
        "columnFap": model.column_fap.astype("<u1").tobytes(),
        "columnUnit": model.column_unit.astype("<f8").tobytes(),
        "columnLow": model.column_low.astype("<f8").tobytes(),
        "columnHigh": model.column_high.astype("<f8").tobytes(),
        "columnZero": model.column_zero.astype("<f8").tobytes(),
        "entries": np.ascontiguousarray(model.entries, dtype="<f4").tobytes(),
        "ranges": np.ascontiguousarray(model.ranges, dtype="<u4").tobytes(),
        "links": np.ascontiguousarray(model.links, dtype="<f4").tobytes(),
        "members": np.ascontiguousarray(model.members, dtype="<f8").tobytes(),
        "unidirectional": (np.flatnonzero(model.unidirectional) + 1).astype("<u1").tobytes(),
    }
