"""The face model: neutral mesh, named parts, feature points and FAP settings.

A :class:`Face` is what :func:`realizer.face.deform.deform` animates (Tekalp and Ostermann 2000
§2.1.3.1: a face model with feature points placed on it and rules for every
FAP; Paul 2010, §4.3: FaceEditor's head with its deformers, vertex masks, lower
jaw, eyes and neck). It holds

* ``vertices`` (n, 3) float32, metres, neutral pose, in the frame of
  :mod:`realizer.face.faps` (+x the face's left, +y up, +z the gaze);
* ``faces`` (m, 3) int32 triangles (``triangles`` is the same array);
* ``parts``: name -> sorted int32 vertex indices. Known names: ``skin``,
  ``left_eye``, ``right_eye``, ``left_pupil``, ``right_pupil`` (subsets of the
  eyes), ``upper_teeth``, ``lower_teeth``, ``tongue``; any other name may be
  used by settings. ``eyes`` and ``teeth`` are the unions; ``all`` is every
  vertex;
* ``params``: a :class:`FaceParameters` -- the content of the face parameter
  file of Paul 2010, Appendix C (feature point positions, keep-syncs, deformers,
  vertex masks), see :mod:`realizer.face.paramfile`;
* ``attributes``: further per-vertex or per-face arrays (uv, normals, colours)
  carried along unchanged for the renderer.

The deformer settings are frozen dataclasses, one per element of the
parameter file: :class:`PointDeformer` (``deformer``), :class:`EaseDeformer`
(``ease-deformer``), :class:`SmoothDeformer` (``smooth-deformer``),
:class:`CosineDeformer` (``cosine-deformer``, Xface's raised cosine),
:class:`TransformDeformer` (``transform-deformer``, a FaceDefTransform),
:class:`DilateDeformer`, :class:`RollDeformer` and
:class:`realizer.face.facedef.FaceDefMesh` (``facedef-mesh``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from realizer.face.errors import FaceError
from realizer.face.facedef import FaceDefMesh
from realizer.face.faps import FAP_TABLE
from realizer.face.fapu import Fapu

Vec3 = tuple[float, float, float]

#: Neutral coordinates smaller than this (metres) are stored as exactly 0.
TINY_COORDINATE_M = 1e-12


@dataclass(frozen=True, slots=True)
class InfluenceDeformer:
    """Moves the vertices inside an influence ellipsoid around a feature point.

    Paul 2010, §4.3.3: each vertex in the part moves along ``direction`` by
    FAP x FAPU x influence, where the influence falls from 1 at the feature
    point to 0 at the surface of the ellipsoid with radius ``size`` (metres)
    scaled by ``scale`` per axis. ``direction`` is the face's own 3D
    direction for the FAP (e.g. a lip corner that also moves back); it is
    rescaled so that its component along the standard's axis (Table 7) is 1,
    so the feature point moves exactly FAP x FAPU along that axis. For FAPs
    without an axis (e.g. the tongue roll) it is normalised to length 1.

    Vertex masks (Paul 2010, §4.3.2, Figure 4.9): with ``use_vertex_mask`` only
    the vertices listed in the FAP's mask can move; with
    ``invert_vertex_mask`` as well, the listed vertices are the ones that
    stay still. ``feature_point`` overrides the FAP's own feature point
    (Table 7) as the centre; ``part`` names the vertices that can move.
    """

    fap: int
    direction: Vec3
    size: float
    scale: Vec3 = (1.0, 1.0, 1.0)
    use_vertex_mask: bool = False
    invert_vertex_mask: bool = False
    part: str = "skin"
    feature_point: str | None = None


@dataclass(frozen=True, slots=True)
class EaseDeformer(InfluenceDeformer):
    """Linear falloff raised to an easing exponent (Paul 2010, §4.3.3, Figure 4.12).

    ``ease`` e runs from -100 to 100; the influence i becomes i**p with
    p = 1 + e/100 for e < 0 and p = 1 + e/20 for e > 0. Negative e thus
    widens the influence (p in [0, 1): the curve bulges above the line),
    positive e narrows it (p in (1, 6]). The thesis's words "easing in" and
    "easing out" are used both ways round in §4.3.3 and §4.3.5; the formulas
    and the order of the curves in Figure 4.12 (e = -80 on top) are
    unambiguous, and they are what is implemented. e = 0 is plain linear.
    """

    ease: float = 0.0


@dataclass(frozen=True, slots=True)
class SmoothDeformer(InfluenceDeformer):
    """Bezier smoothing instead of easing (Paul 2010, §4.3.4, Figure 4.16).

    The influence over the normalised distance r (1 = the ellipsoid's
    surface) follows the cubic Bezier curve with control points (0, 1),
    (c, 1), (R - s, 0), (R, 0), where c = ``smooth_center``/100 and
    s = ``smooth_side``/100 (percent of the influence size, 0..100) and the
    sphere is enlarged to R = 1 + (c + s)/2. The slope is 0 at the centre
    when c > 0 and at the rim when s > 0; c = s = 0 gives exactly the
    linear falloff.
    """

    smooth_center: float = 0.0
    smooth_side: float = 0.0


@dataclass(frozen=True, slots=True)
class CosineDeformer(InfluenceDeformer):
    """Raised-cosine falloff, Xface's choice: i = (1 + cos(pi r)) / 2 for r < 1."""


@dataclass(frozen=True, slots=True)
class PointDeformer:
    """The plain ``deformer`` element of Appendix C (only ``x y z fap``).

    With no influence sphere in the DTD, it moves the feature point's own
    vertex (and any vertex at the same position, e.g. a texture seam) along
    ``direction``, rescaled like :class:`InfluenceDeformer`'s.
    """

    fap: int
    direction: Vec3
    part: str = "skin"
    feature_point: str | None = None


@dataclass(frozen=True, slots=True)
class TransformDeformer:
    """A rigid motion of whole parts (a FaceDefTransform of Tekalp and Ostermann 2000).

    ``kind`` "rotation": the parts turn about ``axis`` through ``pivot`` by
    FAP x FAPU x ``scale`` radians (for an angular FAP scale is 1; for the
    jaw, whose FAP 3 is in MNS, scale is radians per metre). "translation":
    they move along ``axis`` by FAP x FAPU x ``scale`` metres. ``pivot`` is a
    point (metres) or, with ``pivot_fp``, a feature point's position.

    ``falloff`` (metres, rotations only): 0 moves every vertex of the parts
    rigidly; > 0 fades the motion out below the pivot over that distance, so
    a neck below the top of the spine (feature point 7.1) bends instead of
    turning as a block. Transforms apply after all vertex displacements, in
    the order of the file: local parts first (eyes, jaw, tongue), then the
    head, which carries them along.
    """

    fap: int
    parts: tuple[str, ...]
    kind: Literal["rotation", "translation"]
    axis: Vec3
    scale: float = 1.0
    pivot: Vec3 | None = None
    pivot_fp: str | None = None
    falloff: float = 0.0


#: Tekalp and Ostermann 2000's name for a transform-node animation table.
FaceDefTransform = TransformDeformer


@dataclass(frozen=True, slots=True)
class DilateDeformer:
    """Pupil dilation (FAPs 29, 30): the pupil's rim grows by FAP x IRISD x scale.

    Each vertex of ``part`` moves away from the line through the pivot along
    ``axis`` (the gaze), in proportion to its distance from that line, so
    the pupil keeps its shape and its rim (the farthest vertices) moves by
    exactly FAP x FAPU x scale. Applied before the eye turns.
    """

    fap: int
    part: str
    axis: Vec3 = (0.0, 0.0, 1.0)
    scale: float = 1.0
    pivot: Vec3 | None = None
    pivot_fp: str | None = None


@dataclass(frozen=True, slots=True)
class RollDeformer:
    """Tongue roll (FAP 47, "concave upward"): each side of the part turns up.

    The vertices on the +x side of the pivot turn about ``axis`` (the
    tongue's length, +z) by +FAP x AU x scale, those on the -x side by the
    opposite angle, so both borders (feature points 6.3 and 6.4) rise.
    """

    fap: int
    part: str = "tongue"
    axis: Vec3 = (0.0, 0.0, 1.0)
    scale: float = 1.0
    pivot: Vec3 | None = None
    pivot_fp: str | None = None


DeformerSetting = (
    PointDeformer
    | EaseDeformer
    | SmoothDeformer
    | CosineDeformer
    | TransformDeformer
    | DilateDeformer
    | RollDeformer
    | FaceDefMesh
)


@dataclass(frozen=True, slots=True)
class FaceParameters:
    """The face parameter file of Paul 2010, Appendix C, read into values.

    ``feature_points``: name -> position (metres); ``keep_syncs``: FAP
    numbers whose settings FaceEditor keeps in step with the other side;
    ``deformers`` in file order; ``vertex_masks``: FAP number -> vertex
    indices. ``source`` is the XML text the parameters were read from, if
    any: saving merges the values back into it so that unknown elements,
    attributes and comments survive (see :mod:`realizer.face.paramfile`).
    """

    feature_points: Mapping[str, Vec3]
    keep_syncs: tuple[int, ...] = ()
    deformers: tuple[DeformerSetting, ...] = ()
    vertex_masks: Mapping[int, tuple[int, ...]] = field(default_factory=dict)
    source: bytes | None = None

    def deformers_for(self, fap: int) -> tuple[DeformerSetting, ...]:
        """The deformers of one FAP, in file order."""
        return tuple(d for d in self.deformers if d.fap == fap)


#: Part name -> the part names it unites.
PART_GROUPS: dict[str, tuple[str, ...]] = {
    "eyes": ("left_eye", "right_eye"),
    "teeth": ("upper_teeth", "lower_teeth"),
}


def natural_part(feature_point: str) -> tuple[str, ...]:
    """The parts a feature point lies on (pupils on the eyes, 6.x on the tongue, ...)."""
    special: dict[str, tuple[str, ...]] = {
        "3.5": ("left_eye",),
        "3.6": ("right_eye",),
        "9.8": ("upper_teeth",),
        "9.10": ("upper_teeth",),
        "9.9": ("lower_teeth",),
        "9.11": ("lower_teeth",),
    }
    if feature_point in special:
        return special[feature_point]
    if feature_point.startswith("6."):
        return ("tongue",)
    return ("skin",)


@dataclass(frozen=True, slots=True, eq=False, weakref_slot=True)
class Face:
    """A neutral face mesh with parts, feature points and FAP settings.

    Arrays are copied, checked and made read-only. Raises :class:`FaceError`
    for inconsistent input (bad shapes, indices out of range).
    """

    vertices: np.ndarray
    faces: np.ndarray
    parts: Mapping[str, np.ndarray]
    params: FaceParameters
    name: str = "face"
    attributes: Mapping[str, np.ndarray] = field(default_factory=dict)
    _feature_vertices: dict[str, int] = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=np.float32)
        faces = np.array(self.faces, dtype=np.int32)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.all(np.isfinite(vertices)):
            raise FaceError(f"vertices must be finite (n, 3), not {vertices.shape}")
        # Coordinates below a picometre (e.g. 1e-18 from sin(pi)) are stored as 0:
        # products with such values run 20-100x slower on x86 (subnormal assists).
        vertices[np.abs(vertices) < TINY_COORDINATE_M] = 0.0
        n = vertices.shape[0]
        if faces.size == 0:
            faces = faces.reshape(0, 3)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise FaceError(f"faces must be (m, 3), not {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= n):
            raise FaceError("a triangle refers to a vertex that does not exist")
        parts: dict[str, np.ndarray] = {}
        for part_name, indices in self.parts.items():
            idx = np.unique(np.asarray(indices, dtype=np.int64)).astype(np.int32)
            if idx.size and (idx[0] < 0 or idx[-1] >= n):
                raise FaceError(f"part {part_name!r} refers to a vertex that does not exist")
            idx.setflags(write=False)
            parts[part_name] = idx
        attributes: dict[str, np.ndarray] = {}
        for key, array in self.attributes.items():
            copy = np.array(array)
            copy.setflags(write=False)
            attributes[key] = copy
        vertices.setflags(write=False)
        faces.setflags(write=False)
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "parts", parts)
        object.__setattr__(self, "attributes", attributes)
        for fap_number, mask in self.params.vertex_masks.items():
            if mask and (min(mask) < 0 or max(mask) >= n):
                raise FaceError(f"the vertex mask of FAP {fap_number} names a missing vertex")
        for point in self.params.feature_points:
            object.__getattribute__(self, "_feature_vertices")[point] = self._nearest(point)

    # -- parts ---------------------------------------------------------------

    @property
    def triangles(self) -> np.ndarray:
        """The (m, 3) int32 triangles (the same array as ``faces``)."""
        return self.faces

    @property
    def vertex_count(self) -> int:
        return int(self.vertices.shape[0])

    def has_part(self, name: str) -> bool:
        if name == "all":
            return True
        if name in PART_GROUPS:
            return any(p in self.parts for p in PART_GROUPS[name])
        return name in self.parts

    def part(self, name: str) -> np.ndarray:
        """Sorted int32 vertex indices of a part, a group ("eyes", "teeth") or "all"."""
        if name == "all":
            return np.arange(self.vertex_count, dtype=np.int32)
        if name in self.parts:
            return self.parts[name]
        if name in PART_GROUPS:
            members = [self.parts[p] for p in PART_GROUPS[name] if p in self.parts]
            if members:
                return np.unique(np.concatenate(members)).astype(np.int32)
        raise FaceError(f"the face {self.name!r} has no part {name!r}")

    def parts_union(self, names: tuple[str, ...]) -> np.ndarray:
        """Sorted vertex indices of several parts together."""
        if not names:
            return np.zeros(0, dtype=np.int32)
        return np.unique(np.concatenate([self.part(n) for n in names])).astype(np.int32)

    # -- feature points ----------------------------------------------------------

    def feature_position(self, name: str) -> np.ndarray:
        """(3,) float64 position of a feature point (metres); FaceError if unset."""
        try:
            return np.asarray(self.params.feature_points[name], dtype=np.float64)
        except KeyError:
            raise FaceError(f"feature point {name} is not placed on {self.name!r}") from None

    def feature_vertex(self, name: str) -> int:
        """Index of the vertex nearest to a feature point, on the part it belongs to."""
        try:
            return self._feature_vertices[name]
        except KeyError:
            raise FaceError(f"feature point {name} is not placed on {self.name!r}") from None

    def _nearest(self, point: str) -> int:
        position = np.asarray(self.params.feature_points[point], dtype=np.float64)
        names = [p for p in natural_part(point) if p in self.parts]
        candidates = self.parts_union(tuple(names)) if names else np.arange(self.vertex_count)
        if candidates.size == 0:
            candidates = np.arange(self.vertex_count)
        distances = np.linalg.norm(self.vertices[candidates] - position, axis=1)
        return int(candidates[int(np.argmin(distances))])

    @property
    def fapu(self) -> Fapu:
        """The FAPU of this face, from its feature points (Tekalp and Ostermann 2000, Table 1)."""
        return Fapu.from_feature_points(self.params.feature_points)

    def fap_feature_point(self, fap: int) -> str | None:
        """The feature point a FAP moves, per Table 7."""
        return FAP_TABLE[fap].feature_point
