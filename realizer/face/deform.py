"""Deformation: a FAP vector and a face -> deformed vertex positions.

Paul 2010, §4.3.3-4.3.4 (influence ellipsoids, easing, Bezier smoothing, vertex
masks; lower jaw, eyes and neck as rigid objects) and Tekalp and Ostermann 2000, §2.1.3.4
(FaceDefMesh, FaceDefTransform). :func:`deform` is a pure function of
(face, FAP vector); the work that depends only on the face is done once, in
a :class:`FaceRig` cached per face, so a frame costs O(affected vertices):

1. **Vertex displacements** (everything linear in one FAP value):
   influence deformers give, per vertex and FAP, a weight i in [0, 1] and a
   direction u; FaceDefMesh tables and pupil dilation give piecewise-linear
   displacements. Both are sparse matrices built once.
2. **Rigid transforms**, in file order: tongue roll, eyeballs (turn about
   their centre, then thrust), lower jaw and lower teeth (turn, thrust,
   shift), and last the head about feature point 7.1, which carries all the
   rest. Consecutive transforms of the same parts are composed into one 3x4
   affine map per frame and applied as one vectorised product.

How the displacements of several FAPs on one vertex combine
--------------------------------------------------------------
FaceEditor (Paul 2010, §4.3.1) *averages* the displacements a vertex gets. Then
a feature point whose neighbours' spheres reach it moves less than its FAP
says, and three raised upper-lip points give the w-shaped lip of Paul 2010
Figure 7.1; plain *summing* has the opposite fault (the overlap bulges
beyond any FAP's amplitude). Paul 2010, §7.1 suggests cancelling a vertex's
extra vectors that point the same way. We do that smoothly, per axis and
sign: the contributions i * a_f * u_f of the influence deformers are summed
separately for positive and negative components of each axis, and each sum
is capped at the largest single FAP amplitude |a_f * u_f| (weight 1) among
the deformers that reach the vertex::

    d_k = min(sum of positive parts, max positive amplitude)
        - min(sum of negative parts, max negative amplitude)

So: one FAP alone moves its vertices exactly i * a * u (the cap is never
reached, i <= 1); a feature point moves by exactly its own FAP when its
neighbours push the same way less strongly; between two equal pushes the lip
stays flat instead of dipping (w) or bulging; FAPs along different axes (jaw
down, corner sideways) add independently; opposite pushes cancel. The rule
is continuous in every FAP value. FaceDefMesh tables and pupil dilation are
added on top unchanged, as MPEG-4 prescribes for them.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field, replace

import numpy as np

from realizer.extras import missing_module
from realizer.face.errors import FaceError
from realizer.face.facedef import FaceDefMesh
from realizer.face.faps import FAP_COUNT, FAP_TABLE, as_fap_vector, clamp_unidirectional
from realizer.face.model import (
    CosineDeformer,
    DilateDeformer,
    EaseDeformer,
    Face,
    InfluenceDeformer,
    PointDeformer,
    RollDeformer,
    SmoothDeformer,
    TransformDeformer,
)

try:  # scipy comes with the [serve] and [render] extras, not with the core
    import scipy.sparse as sp
except ModuleNotFoundError as _error:
    raise missing_module(_error, "serve", "the face's mesh deformation") from _error

#: Influences below this are treated as zero (no entry in the sparse matrix).
MIN_INFLUENCE = 1e-9
#: Vertices closer than this (metres) to a point deformer's feature vertex move with it.
SAME_POSITION_M = 1e-7
#: How many sets of set FAPs a rig remembers the sparse entries of.
SELECTION_CACHE = 16


# -- falloff curves ---------------------------------------------------------------------


def ease_exponent(ease: float) -> float:
    """Paul 2010, §4.3.3: 1 + e/100 for e < 0, 1 + e/20 for e >= 0 (e in -100..100)."""
    if not -100.0 <= ease <= 100.0:
        raise FaceError(f"ease must be in -100..100, not {ease}")
    return 1.0 + ease / 100.0 if ease < 0 else 1.0 + ease / 20.0


def ease_falloff(r: np.ndarray, ease: float) -> np.ndarray:
    """Influence at normalised distance r: (1 - r)**p inside the ellipsoid, 0 outside."""
    p = ease_exponent(ease)
    inside = r < 1.0
    out = np.zeros_like(r, dtype=np.float64)
    out[inside] = (1.0 - r[inside]) ** p
    return out


def cosine_falloff(r: np.ndarray) -> np.ndarray:
    """Raised cosine (Xface): (1 + cos(pi r)) / 2 for r < 1, else 0."""
    out: np.ndarray = np.where(r < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(r, 1.0))), 0.0)
    return out


def smooth_falloff(r: np.ndarray, smooth_center: float, smooth_side: float) -> np.ndarray:
    """Bezier influence curve of Paul 2010, §4.3.4 (see :class:`SmoothDeformer`).

    ``smooth_center`` and ``smooth_side`` are percent (0..100) of the size.
    """
    c = smooth_center / 100.0
    s = smooth_side / 100.0
    if not (0.0 <= c <= 1.0 and 0.0 <= s <= 1.0):
        raise FaceError("smooth-center and smooth-side must be in 0..100")
    reach = 1.0 + (c + s) / 2.0
    x1, x2, x3 = c, reach - s, reach
    r = np.asarray(r, dtype=np.float64)
    out = np.zeros_like(r)
    inside = r < reach
    target = r[inside]
    # x(t) is non-decreasing (0 <= x1 <= x2 <= x3), so bisection finds t.
    lo = np.zeros_like(target)
    hi = np.ones_like(target)
    for _ in range(48):
        mid = 0.5 * (lo + hi)
        omt = 1.0 - mid
        x = 3 * x1 * mid * omt**2 + 3 * x2 * mid**2 * omt + x3 * mid**3
        below = x < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    t = 0.5 * (lo + hi)
    out[inside] = (1 - t) ** 3 + 3 * t * (1 - t) ** 2
    return out


# -- compiled pieces --------------------------------------------------------------------


def _unit(vector: tuple[float, float, float], what: str) -> np.ndarray:
    v = np.asarray(vector, dtype=np.float64)
    norm = float(np.linalg.norm(v))
    if not np.isfinite(norm) or norm < 1e-12:
        raise FaceError(f"{what}: the direction must not be zero")
    return v / norm


def fap_direction(fap_number: int, direction: tuple[float, float, float]) -> np.ndarray:
    """The per-unit displacement direction of an influence deformer.

    Rescaled so its component along the standard axis of the FAP (Table 7)
    is exactly 1; for FAPs without an axis, normalised. Raises
    :class:`FaceError` if the direction does not point the standard way.
    """
    d = np.asarray(direction, dtype=np.float64)
    axis = FAP_TABLE[fap_number].axis
    if axis is None:
        return _unit(direction, f"FAP {fap_number}")
    along = float(d @ np.asarray(axis))
    if not along > 1e-6 * max(1.0, float(np.linalg.norm(d))):
        raise FaceError(
            f"FAP {fap_number} ({FAP_TABLE[fap_number].name}): direction {tuple(direction)} "
            f"does not point {FAP_TABLE[fap_number].direction}"
        )
    return d / along


@dataclass(frozen=True, slots=True)
class _Transform:
    """One compiled rigid motion: a rotation or translation of some vertices."""

    fap_index: int
    kind: str  # "rotation", "translation", "roll"
    unit: float  # FAPU of the FAP times the setting's scale
    axis: np.ndarray  # (3,) unit vector
    pivot: np.ndarray  # (3,)
    key: tuple[object, ...]  # transforms with the same key move the same vertices
    axis_tuple: tuple[float, float, float] = (0.0, 0.0, 0.0)  # plain floats for _affine
    pivot_tuple: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "axis_tuple", tuple(float(c) for c in self.axis))
        object.__setattr__(self, "pivot_tuple", tuple(float(c) for c in self.pivot))


@dataclass(frozen=True, slots=True)
class _TransformGroup:
    indices: np.ndarray | slice | None  # moved rigidly; None = every vertex; slice = range
    members: tuple[_Transform, ...]
    blend: np.ndarray | None = None  # vertices moved part way (a neck below 7.1)
    weights: np.ndarray | None = None  # (k, 1) float32 weights of ``blend`` in (0, 1)
    # a faded group per frame: the vertex range it touches and each one's
    # weight there (1 rigid, 0 still), moved as p + w ((R - I) p + t)
    span: slice | None = None
    span_weights: np.ndarray | None = None  # (len(span),) float32


@dataclass(frozen=True, slots=True)
class _Entries:
    """Sparse (row, column) entries grouped by column, for picking the set FAPs."""

    rows: np.ndarray  # flat output row (vertex * 3 + axis) or a compact row id
    coef: np.ndarray  # influence x signed direction component
    mag: np.ndarray  # |direction component|
    column: np.ndarray
    pointer: np.ndarray  # entries of column j: pointer[j]:pointer[j + 1]
    # selections by set of active columns: an animation keeps the same FAPs set
    # for many frames, so most frames reuse one (a cache; results do not change)
    _chosen: dict[bytes, tuple[np.ndarray, ...]] = field(
        default_factory=dict, repr=False, compare=False
    )

    @classmethod
    def of(
        cls,
        rows: np.ndarray,
        column: np.ndarray,
        coef: np.ndarray,
        mag: np.ndarray,
        columns: int,
    ) -> _Entries:
        pointer = np.searchsorted(column, np.arange(columns + 1))
        return cls(rows, coef, mag, column, pointer)

    def select(self, active: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(rows, coef, mag, column) of the entries of the active columns."""
        if active.size == self.pointer.size - 1:
            return self.rows, self.coef, self.mag, self.column
        key = active.tobytes()
        chosen = self._chosen.get(key)
        if chosen is None:
            index = np.concatenate(
                [np.arange(self.pointer[j], self.pointer[j + 1]) for j in active]
            )
            chosen = (self.rows[index], self.coef[index], self.mag[index], self.column[index])
            if len(self._chosen) >= SELECTION_CACHE:
                self._chosen.clear()
            self._chosen[key] = chosen
        return chosen[0], chosen[1], chosen[2], chosen[3]


Matrix3 = tuple[float, float, float, float, float, float, float, float, float]
IDENTITY3: Matrix3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def _rotation(axis: tuple[float, float, float], angle: float) -> Matrix3:
    """Row-major 3x3 rotation by ``angle`` radians about a unit axis (Rodrigues).

    Plain floats: a few per frame, where numpy's per-call cost would dominate.
    """
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return (
        c + t * x * x,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        c + t * y * y,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        c + t * z * z,
    )


def _mul(a: Matrix3, b: Matrix3) -> Matrix3:
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


def _apply3(a: Matrix3, v: tuple[float, float, float]) -> tuple[float, float, float]:
    return (
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
        a[6] * v[0] + a[7] * v[1] + a[8] * v[2],
    )


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` radians about the unit vector ``axis``."""
    x, y, z = (float(c) for c in axis)
    return np.asarray(_rotation((x, y, z), angle)).reshape(3, 3)


class FaceRig:
    """Everything about a face that does not depend on the FAP values.

    Build once per face (:func:`rig_for` caches it) and call :meth:`deform`
    per frame. Raises :class:`FaceError` when a setting cannot be compiled
    (a missing feature point or part, a direction against the standard).
    """

    def __init__(self, face: Face) -> None:
        self.face = face
        self.neutral = face.vertices
        # per frame the rig works on the coordinates as three rows (3, n):
        # offsets, products and blends along a row are 3-10x faster than on
        # (n, 3), whose inner loop is 3 long
        self._neutral_t = np.ascontiguousarray(np.asarray(face.vertices, dtype=np.float32).T)
        self.fapu_per_fap = face.fapu.per_fap()
        n = face.vertex_count
        params = face.params
        # influence columns
        col_fap: list[int] = []
        entry_vertex: list[np.ndarray] = []
        entry_col: list[np.ndarray] = []
        entry_weight: list[np.ndarray] = []
        col_dir: list[np.ndarray] = []
        # summed (FaceDefMesh-like) columns
        sum_rows: list[np.ndarray] = []
        sum_cols: list[np.ndarray] = []
        sum_vals: list[np.ndarray] = []
        sum_fap: list[int] = []
        sum_low: list[float] = []
        sum_high: list[float] = []
        transforms: list[tuple[_Transform, np.ndarray, np.ndarray | None]] = []

        for setting in params.deformers:
            if not 3 <= setting.fap <= FAP_COUNT:
                raise FaceError(f"deformers drive FAPs 3..68, not {setting.fap}")
            if isinstance(setting, InfluenceDeformer | PointDeformer):
                vertices, weights = self._influence(setting)
                if vertices.size == 0:
                    continue
                col_dir.append(fap_direction(setting.fap, setting.direction))
                entry_vertex.append(vertices)
                entry_col.append(np.full(vertices.size, len(col_fap)))
                entry_weight.append(weights)
                col_fap.append(setting.fap - 1)
            elif isinstance(setting, FaceDefMesh | DilateDeformer):
                if isinstance(setting, FaceDefMesh):
                    vertices = np.asarray(setting.vertices, dtype=np.int64)
                    if vertices.size and (vertices.min() < 0 or vertices.max() >= n):
                        raise FaceError(f"FaceDefMesh of FAP {setting.fap} names a missing vertex")
                    disp = setting.displacement_array()
                    borders = np.asarray(setting.intervals, dtype=np.float64)
                    lows = borders[:-1].copy()
                    highs = borders[1:].copy()
                    lows[0], highs[-1] = -np.inf, np.inf
                else:
                    vertices, radial = self._dilation(setting)
                    disp = radial[:, None, :] * setting.scale
                    lows, highs = np.array([-np.inf]), np.array([np.inf])
                base = len(sum_fap)
                for k in range(disp.shape[1]):
                    sum_fap.append(setting.fap - 1)
                    sum_low.append(float(lows[k]))
                    sum_high.append(float(highs[k]))
                    for axis in range(3):
                        sum_rows.append(vertices * 3 + axis)
                        sum_cols.append(np.full(vertices.size, base + k))
                        sum_vals.append(disp[:, k, axis])
            elif isinstance(setting, TransformDeformer | RollDeformer):
                transforms.extend(self._transforms(setting))
            else:  # pragma: no cover - the union is closed
                raise FaceError(f"unknown deformer {setting!r}")

        self._build_influence(n, col_fap, entry_vertex, entry_col, entry_weight, col_dir)
        self._build_summed(n, sum_rows, sum_cols, sum_vals, sum_fap, sum_low, sum_high)
        self._build_transforms(transforms)

    # -- compile settings -------------------------------------------------------------

    def _centre(self, fap_number: int, override: str | None) -> np.ndarray:
        point = override or FAP_TABLE[fap_number].feature_point
        if point is None:
            raise FaceError(f"FAP {fap_number} has no feature point; name one in the setting")
        return self.face.feature_position(point)

    def _candidates(self, setting: InfluenceDeformer | PointDeformer) -> np.ndarray:
        vertices = self.face.part(setting.part).astype(np.int64)
        if isinstance(setting, InfluenceDeformer) and setting.use_vertex_mask:
            mask = np.asarray(self.face.params.vertex_masks.get(setting.fap, ()), dtype=np.int64)
            keep = np.isin(vertices, mask)
            vertices = vertices[~keep] if setting.invert_vertex_mask else vertices[keep]
        return vertices

    def _influence(
        self, setting: InfluenceDeformer | PointDeformer
    ) -> tuple[np.ndarray, np.ndarray]:
        centre = self._centre(setting.fap, setting.feature_point)
        vertices = self._candidates(setting)
        positions = self.neutral[vertices].astype(np.float64)
        if isinstance(setting, PointDeformer):
            point = setting.feature_point or FAP_TABLE[setting.fap].feature_point
            assert point is not None
            anchor = self.neutral[self.face.feature_vertex(point)].astype(np.float64)
            near = np.linalg.norm(positions - anchor, axis=1) <= SAME_POSITION_M
            return vertices[near], np.ones(int(near.sum()))
        radii = setting.size * np.asarray(setting.scale, dtype=np.float64)
        if setting.size <= 0 or np.any(radii <= 0):
            raise FaceError(f"FAP {setting.fap}: size and scales must be positive")
        r = np.linalg.norm((positions - centre) / radii, axis=1)
        if isinstance(setting, EaseDeformer):
            weights = ease_falloff(r, setting.ease)
        elif isinstance(setting, SmoothDeformer):
            weights = smooth_falloff(r, setting.smooth_center, setting.smooth_side)
        elif isinstance(setting, CosineDeformer):
            weights = cosine_falloff(r)
        else:
            weights = ease_falloff(r, 0.0)
        keep = weights > MIN_INFLUENCE
        return vertices[keep], weights[keep]

    def _pivot(self, setting: TransformDeformer | RollDeformer | DilateDeformer) -> np.ndarray:
        if setting.pivot_fp is not None:
            return self.face.feature_position(setting.pivot_fp)
        if setting.pivot is not None:
            return np.asarray(setting.pivot, dtype=np.float64)
        if isinstance(setting, TransformDeformer) and setting.kind == "translation":
            return np.zeros(3)
        raise FaceError(f"FAP {setting.fap}: a rotation needs a pivot or pivot-fp")

    def _dilation(self, setting: DilateDeformer) -> tuple[np.ndarray, np.ndarray]:
        vertices = self.face.part(setting.part).astype(np.int64)
        pivot = self._pivot(setting)
        axis = _unit(setting.axis, f"FAP {setting.fap}")
        rel = self.neutral[vertices].astype(np.float64) - pivot
        radial = rel - np.outer(rel @ axis, axis)
        rim = float(np.linalg.norm(radial, axis=1).max()) if vertices.size else 0.0
        if rim <= 0:
            raise FaceError(f"FAP {setting.fap}: the pupil part has no extent")
        return vertices, radial / rim

    def _transforms(
        self, setting: TransformDeformer | RollDeformer
    ) -> list[tuple[_Transform, np.ndarray, np.ndarray | None]]:
        unit = self.fapu_per_fap[setting.fap - 1] * setting.scale
        axis = _unit(setting.axis, f"FAP {setting.fap}")
        pivot = self._pivot(setting)
        if isinstance(setting, RollDeformer):
            vertices = self.face.part(setting.part).astype(np.int64)
            # which side of the tongue's mid-plane (the plane through the pivot
            # containing the axis and the up vector) each vertex lies on
            side_normal = np.cross(np.array([0.0, 1.0, 0.0]), axis)
            if np.linalg.norm(side_normal) < 1e-9:
                raise FaceError(f"FAP {setting.fap}: the roll axis must not be vertical")
            side = (self.neutral[vertices].astype(np.float64) - pivot) @ side_normal
            plus, minus = vertices[side > 0], vertices[side < 0]
            # +x side of a +z axis turns up under a positive rotation
            sign = 1.0 if float(np.cross(axis, side_normal)[1]) > 0 else -1.0
            return [
                (
                    _Transform(
                        setting.fap - 1,
                        "rotation",
                        sign * unit,
                        axis,
                        pivot,
                        ("roll+", id(setting)),
                    ),
                    plus,
                    None,
                ),
                (
                    _Transform(
                        setting.fap - 1,
                        "rotation",
                        -sign * unit,
                        axis,
                        pivot,
                        ("roll-", id(setting)),
                    ),
                    minus,
                    None,
                ),
            ]
        vertices = self.face.parts_union(setting.parts).astype(np.int64)
        weights = None
        if setting.falloff > 0 and setting.kind == "rotation":
            drop = pivot[1] - self.neutral[vertices, 1].astype(np.float64)
            weights = np.clip(1.0 - drop / setting.falloff, 0.0, 1.0)
        key: tuple[object, ...] = (setting.parts, setting.falloff if weights is not None else 0.0)
        if weights is not None:
            key = (*key, tuple(pivot))
        return [
            (_Transform(setting.fap - 1, setting.kind, unit, axis, pivot, key), vertices, weights)
        ]

    # -- build matrices -----------------------------------------------------------------

    def _build_influence(
        self,
        n: int,
        col_fap: list[int],
        entry_vertex: list[np.ndarray],
        entry_col: list[np.ndarray],
        entry_weight: list[np.ndarray],
        col_dir: list[np.ndarray],
    ) -> None:
        columns = len(col_fap)
        self.influence_fap = np.asarray(col_fap, dtype=np.int64)
        self.influence_unit = self.fapu_per_fap[self.influence_fap] if columns else np.zeros(0)
        if columns == 0:
            self._has_influence = False
            return
        self._has_influence = True
        vertex = np.concatenate(entry_vertex)
        col = np.concatenate(entry_col)
        weight = np.concatenate(entry_weight)
        directions = np.asarray(col_dir)  # (columns, 3)
        rows_l, cols_l, signed_l, mag_l = [], [], [], []
        for axis in range(3):
            comp = directions[col, axis]
            nz = comp != 0
            rows_l.append(vertex[nz] * 3 + axis)
            cols_l.append(col[nz])
            signed_l.append(weight[nz] * comp[nz])
            mag_l.append(np.abs(comp[nz]))
        flat = np.concatenate(rows_l)
        column = np.concatenate(cols_l) % columns
        signed = np.concatenate(signed_l)
        mag = np.concatenate(mag_l)
        rows, counts = np.unique(flat, return_counts=True)
        reached = counts[np.searchsorted(rows, flat)]
        # entries are kept grouped by column, so a frame touches only the
        # entries of the FAPs that are set (O(affected vertices))
        single = reached == 1
        order = np.argsort(column[single], kind="stable")
        self._single = _Entries.of(
            flat[single][order],
            column[single][order],
            signed[single][order],
            mag[single][order],
            columns,
        )
        # rows reached by several deformers: the capped sums of the module docstring
        multi = ~single
        self._multi_rows = np.unique(flat[multi])
        local = np.searchsorted(self._multi_rows, flat[multi])
        order = np.argsort(column[multi], kind="stable")
        self._multi = _Entries.of(
            local[order], column[multi][order], signed[multi][order], mag[multi][order], columns
        )
        # the same entries addressing the (3, n) rows of a frame
        self._single_t = _Entries.of(
            _soa_rows(self._single.rows, n),
            self._single.column,
            self._single.coef,
            self._single.mag,
            columns,
        )
        self._multi_rows_t = _soa_rows(self._multi_rows, n)
        self._columns = columns

    def _build_summed(
        self,
        n: int,
        rows_l: list[np.ndarray],
        cols_l: list[np.ndarray],
        vals_l: list[np.ndarray],
        fap: list[int],
        low: list[float],
        high: list[float],
    ) -> None:
        self._has_summed = bool(fap)
        if not fap:
            return
        rows = np.concatenate(rows_l)
        cols = np.concatenate(cols_l)
        vals = np.concatenate(vals_l)
        keep = vals != 0
        rows, cols, vals = rows[keep], cols[keep], vals[keep]
        unique_rows = np.unique(rows)
        local = np.searchsorted(unique_rows, rows)
        self._summed_rows = unique_rows
        self._summed_matrix = sp.csr_matrix(
            (vals, (local, cols)), shape=(unique_rows.size, len(fap))
        )
        self._summed_csc = self._summed_matrix.tocsc()
        # per frame: float32, a row per (axis, vertex) of the (3, n) frame, by
        # column: a frame's product is one sparse axpy per set column (2x
        # faster than by rows) and adds to the whole frame without a gather
        self._summed_t = sp.csc_matrix(
            (vals.astype(np.float32), (_soa_rows(rows, n), cols)), shape=(3 * n, len(fap))
        )
        self._summed_t.sum_duplicates()
        self._summed_chosen: dict[bytes, sp.csc_matrix] = {}
        self._summed_fap = np.asarray(fap, dtype=np.int64)
        self._summed_low = np.asarray(low)
        self._summed_high = np.asarray(high)
        self._summed_zero = np.clip(0.0, self._summed_low, self._summed_high)

    def _summed_for(self, active: np.ndarray) -> sp.csc_matrix:
        """The summed columns ``active`` as a (3n, k) matrix: a frame costs
        what its set tables touch, not every table of the face (an animation
        keeps the same columns set for many frames: cached)."""
        key = active.tobytes()
        chosen = self._summed_chosen.get(key)
        if chosen is None:
            chosen = self._summed_t[:, active]
            if len(self._summed_chosen) >= SELECTION_CACHE:
                self._summed_chosen.clear()
            self._summed_chosen[key] = chosen
        return chosen

    def _build_transforms(
        self, transforms: list[tuple[_Transform, np.ndarray, np.ndarray | None]]
    ) -> None:
        n = self.face.vertex_count
        groups: list[_TransformGroup] = []
        last_key: object = None
        for transform, vertices, weights in transforms:
            if vertices.size == 0:
                continue
            if groups and transform.key == last_key:
                groups[-1] = replace(groups[-1], members=(*groups[-1].members, transform))
                continue
            blend = blend_weights = None
            span = span_weights = None
            if weights is not None:
                low, high = int(vertices.min()), int(vertices.max()) + 1
                span = slice(low, high)
                span_weights = np.zeros(high - low, dtype=np.float32)
                span_weights[vertices - low] = np.clip(weights, 0.0, 1.0)
                # split a faded motion: rigid where the weight is 1, blended where
                # it is between, nothing where it is 0
                partial = (weights > 0.0) & (weights < 1.0)
                blend = vertices[partial]
                blend_weights = weights[partial].astype(np.float32)[:, None]
                vertices = vertices[weights >= 1.0]
            indices: np.ndarray | slice | None = vertices
            if vertices.size == n:
                indices = None
            elif vertices.size and int(vertices[-1]) - int(vertices[0]) + 1 == vertices.size:
                # a contiguous part: a view instead of a gather and a scatter
                indices = slice(int(vertices[0]), int(vertices[-1]) + 1)
            groups.append(
                _TransformGroup(
                    indices,
                    (transform,),
                    blend,
                    blend_weights,
                    span,
                    span_weights,
                )
            )
            last_key = transform.key
        # the trailing rigid motions of every vertex (the head) form the pose
        split = len(groups)
        while split > 0 and groups[split - 1].indices is None and groups[split - 1].blend is None:
            split -= 1
        self._groups = tuple(groups[:split])
        self._pose_groups = tuple(groups[split:])

    # -- per frame ----------------------------------------------------------------------

    def deform(self, fap_vector: np.ndarray) -> np.ndarray:
        """(n, 3) float32 vertex positions (metres) for a FAP vector.

        ``fap_vector`` (68,) float64 in FAPU-scaled units; slots 0 and 1
        (FAPs 1 and 2) are ignored and negative values of unidirectional
        FAPs count as 0 (see :func:`realizer.face.faps.clamp_unidirectional`).
        """
        values = _values(fap_vector)
        if not values.any():
            return self._neutral_points()
        rows, pose = self._frame(values)
        if not np.array_equal(pose, np.eye(4)):
            rows = _moved_rows(rows, pose[:3, :3], pose[:3, 3])
        return _as_points(rows)

    def deform_posed(self, fap_vector: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The deformed face before the head motion, and that motion as a 4x4 matrix.

        ``deform(v)`` equals ``pose`` applied to the vertices. A renderer or a
        stream can send the (n, 3) float32 vertices and the (4, 4) float64
        head pose separately and let the GPU apply the pose (FAPs 48-50 then
        cost nothing per vertex).
        """
        values = _values(fap_vector)
        if not values.any():
            return self._neutral_points(), np.eye(4)
        rows, pose = self._frame(values)
        return _as_points(rows), pose

    def _neutral_points(self) -> np.ndarray:
        """A new (n, 3) float32 copy of the neutral face (no FAP set)."""
        return np.array(self.neutral, dtype=np.float32, order="C")

    def _frame(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(3, n) float32 coordinates before the pose, and the pose, for
        FAP ``values`` as :func:`_values` makes them."""
        out = self._neutral_t.copy()
        flat = out.reshape(-1)
        if self._has_influence:
            amount = values[self.influence_fap] * self.influence_unit  # metres per column
            active = np.flatnonzero(amount)
            if active.size:
                rows, coef, _, col = self._single_t.select(active)
                flat[rows] += (coef * amount[col]).astype(np.float32)
                if self._multi_rows_t.size:
                    flat[self._multi_rows_t] += self._capped(amount, active).astype(np.float32)
        if self._has_summed:
            coef = (
                np.clip(values[self._summed_fap], self._summed_low, self._summed_high)
                - self._summed_zero
            ) * self.fapu_per_fap[self._summed_fap]
            active = np.flatnonzero(coef)
            if active.size:
                flat += self._summed_for(active) @ coef[active].astype(np.float32)
        for group in self._groups:
            out = self._apply(group, values, out)
        pose = np.eye(4)
        for group in self._pose_groups:
            matrix, offset, moved = self._affine(group, values)
            if moved:
                step = np.eye(4)
                step[:3, :3], step[:3, 3] = matrix, offset
                pose = step @ pose
        return out, pose

    def _capped(self, amount: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Displacements of the rows reached by several deformers (module docstring)."""
        local, coef, mag, col = self._multi.select(active)
        rows = self._multi_rows.size
        value = amount[col]
        push = coef * value  # signed contribution of each entry, metres
        peak = mag * np.abs(value)  # what the entry's FAP alone would give at weight 1
        # bucket 2r: what pushes row r up, 2r + 1: what pushes it down
        bucket = local * 2 + (push < 0)
        sums = np.bincount(bucket, weights=np.abs(push), minlength=2 * rows)
        peaks = np.zeros(2 * rows)
        np.maximum.at(peaks, bucket, peak)
        capped = np.minimum(sums, peaks).reshape(rows, 2)
        result: np.ndarray = capped[:, 0] - capped[:, 1]
        return result

    def _affine(
        self, group: _TransformGroup, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        """The group's motion this frame: x -> matrix @ x + offset; moved=False if none."""
        matrix = IDENTITY3
        offset = (0.0, 0.0, 0.0)
        moved = False
        for member in group.members:
            amount = float(values[member.fap_index]) * member.unit
            if amount == 0.0:
                continue
            moved = True
            ax, ay, az = member.axis_tuple
            if member.kind == "translation":
                offset = (offset[0] + amount * ax, offset[1] + amount * ay, offset[2] + amount * az)
            else:
                rot = _rotation(member.axis_tuple, amount)
                matrix = _mul(rot, matrix)
                # x -> rot (x - pivot) + pivot, after the motion so far
                px, py, pz = member.pivot_tuple
                turned = _apply3(rot, (offset[0] - px, offset[1] - py, offset[2] - pz))
                offset = (turned[0] + px, turned[1] + py, turned[2] + pz)
        return np.asarray(matrix).reshape(3, 3), np.asarray(offset), moved

    def _apply(self, group: _TransformGroup, values: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The group's motion this frame on the (3, n) coordinates ``out``."""
        matrix, offset, moved = self._affine(group, values)
        if not moved:
            return out
        if group.span is not None and group.span_weights is not None:
            # faded (a neck below 7.1): p + w ((R - I) p + t), w = 1 where rigid
            part = out[:, group.span]
            step = _moved_rows(part, matrix - np.eye(3), offset)
            step *= group.span_weights
            part += step
            return out
        if group.indices is None:
            return _moved_rows(out, matrix, offset)
        if isinstance(group.indices, slice):
            part = out[:, group.indices]  # a view: transform in place
            part[...] = _moved_rows(part, matrix, offset)
            return out
        out[:, group.indices] = _moved_rows(np.take(out, group.indices, axis=1), matrix, offset)
        return out


def _values(fap_vector: np.ndarray) -> np.ndarray:
    """The FAP vector as deformation reads it: FAPs 1 and 2 and negative
    values of unidirectional FAPs count as 0."""
    values = clamp_unidirectional(as_fap_vector(fap_vector))
    values[:2] = 0.0
    return values


def _soa_rows(rows: np.ndarray, n: int) -> np.ndarray:
    """Flat rows ``vertex * 3 + axis`` of (n, 3) as rows ``axis * n + vertex`` of (3, n)."""
    converted: np.ndarray = (rows % 3) * n + rows // 3
    return converted


def _moved_rows(rows: np.ndarray, matrix: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``matrix @ p + offset`` for the columns p of (3, k) float32 ``rows``: a new array.

    The matrix is handed to matmul as a strided view on purpose: that keeps
    numpy off BLAS, whose threads cost 10-50x more than the work for a
    3-row product on a busy machine, and numpy's own loop is as fast.
    """
    holder = np.zeros((3, 6), dtype=np.float32)
    holder[:, ::2] = matrix
    result: np.ndarray = holder[:, ::2] @ rows
    result += np.asarray(offset, dtype=np.float32)[:, None]
    return result


def _as_points(rows: np.ndarray) -> np.ndarray:
    """(3, n) coordinates as a new C-contiguous (n, 3) float32 array (by
    column: 2-3x faster than copying the transpose)."""
    out = np.empty((rows.shape[1], 3), dtype=np.float32)
    for axis in range(3):
        out[:, axis] = rows[axis]
    return out


_RIGS: weakref.WeakKeyDictionary[Face, FaceRig] = weakref.WeakKeyDictionary()


def rig_for(face: Face) -> FaceRig:
    """The cached :class:`FaceRig` of a face (built on first use)."""
    rig = _RIGS.get(face)
    if rig is None:
        rig = FaceRig(face)
        _RIGS[face] = rig
    return rig


def deform(face: Face, fap_vector: np.ndarray) -> np.ndarray:
    """Deformed vertex positions, (n, 3) float32 metres: a pure function.

    ``fap_vector``: (68,) float64, FAP n at index n-1, FAPU-scaled units.
    Raises :class:`realizer.face.errors.FapValueError` for a malformed
    vector and :class:`FaceError` if the face's settings cannot be compiled.
    """
    return rig_for(face).deform(fap_vector)


def neutral_vector() -> np.ndarray:
    """A (68,) float64 zero FAP vector."""
    return np.zeros(FAP_COUNT)
