"""MPEG-4 face animation tables: FaceDefMesh and FaceDefTransform.

Tekalp and Ostermann 2000, §2.1.3.4.

A **FaceDefMesh** gives, for one FAP, interval borders I_1 < ... < I_max of the
FAP value and, for each affected vertex, one 3D displacement D_k per interval
(in FAPU, i.e. metres = FAPU x D). The vertex moves along a continuous
piecewise-linear path: slope D_k while the FAP value runs through interval k,
starting from the neutral position at FAP = 0 (Tekalp and Ostermann 2000, Figure 5). Values
beyond the outermost borders continue the outermost slopes. One interval is
the linear case P' = P + FAPU * FAP * D.

Sign of negative values: Tekalp and Ostermann 2000 prints the rule for FAP < 0 as
``P' = P + FAPU * ((I_j+1 - FAP) * D_j + ... + (0 - I_k-1) * D_k-1)``, which
moves a vertex the *same* way for -100 as for +100 and breaks the linear case
``P' = P + FAPU * FAP * D`` it states next. We keep the continuous path of
Figure 5 (negative values move along -D), which agrees with the linear case,
and test both.

A **FaceDefTransform** animates a transform node: a rotation about an axis
(angle = FAP x FAPU x scale), a translation along an axis (distance = FAP x
FAPU x scale) or a scale. Tekalp and Ostermann 2000, Table 5: FAP 23 rotates the node LeftEyeX
about (0, -1, 0) with scale 1. Here the node is a set of named parts of the
face, turning about a pivot: :class:`realizer.face.model.FaceDefTransform`
(the same class as ``TransformDeformer``; rotations and translations --
no face part needs a scale transform).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from realizer.face.errors import FaceError

Vec3 = tuple[float, float, float]

#: The encodings a face parameter file may store a FaceDefMesh in.
ENCODINGS = ("text", "float16")


@dataclass(frozen=True, slots=True)
class FaceDefMesh:
    """Piecewise-linear displacements of vertices for one FAP.

    ``intervals``: the borders, increasing (k+1 borders for k intervals);
    ``vertices``: vertex indices into the face mesh; ``displacements``: per
    vertex, one (dx, dy, dz) per interval, in FAPU. ``target`` names the
    mesh (IndexedFaceSet) the table was written for; vertex indices are
    indices of the whole face mesh.
    """

    fap: int
    intervals: tuple[float, ...]
    vertices: tuple[int, ...]
    displacements: tuple[tuple[Vec3, ...], ...]
    target: str = "Face"
    #: How a face parameter file stores the table: "text" (one element per
    #: vertex, decimal) or "float16" (two base64 arrays; the displacements
    #: must then be float16 values, so the file reads back exactly).
    encoding: str = "text"

    def __post_init__(self) -> None:
        borders = np.asarray(self.intervals, dtype=np.float64)
        if borders.size < 2 or np.any(np.diff(borders) <= 0):
            raise FaceError(f"FaceDefMesh of FAP {self.fap}: interval borders must increase")
        if self.encoding not in ENCODINGS:
            raise FaceError(f"FaceDefMesh of FAP {self.fap}: encoding must be one of {ENCODINGS}")
        if len(self.vertices) != len(self.displacements):
            raise FaceError(f"FaceDefMesh of FAP {self.fap}: one displacement list per vertex")
        for row in self.displacements:
            if len(row) != borders.size - 1:
                raise FaceError(
                    f"FaceDefMesh of FAP {self.fap}: {borders.size - 1} intervals need "
                    f"{borders.size - 1} displacements per vertex, not {len(row)}"
                )

    @property
    def interval_count(self) -> int:
        return len(self.intervals) - 1

    def displacement_array(self) -> np.ndarray:
        """(vertices, intervals, 3) float64 displacements in FAPU."""
        return np.asarray(self.displacements, dtype=np.float64).reshape(
            len(self.vertices), self.interval_count, 3
        )

    def offsets(self, value: float, fapu: float) -> np.ndarray:
        """(vertices, 3) displacement in metres at FAP ``value`` (one FAP unit = ``fapu``)."""
        weights = interval_weights(np.asarray(self.intervals, dtype=np.float64), value)
        offsets: np.ndarray = fapu * np.einsum("k,vkc->vc", weights, self.displacement_array())
        return offsets


def interval_weights(borders: np.ndarray, value: float | np.ndarray) -> np.ndarray:
    """How far the path from 0 to ``value`` runs through each interval (signed).

    For borders (-1000, 0, 500, 1000) and value 600 this is (0, 500, 100): the
    coefficients of D_1, D_2, D_3 in Tekalp and Ostermann 2000's formula. The first interval
    extends to -inf and the last to +inf (values beyond the table continue
    the outer slopes). ``value`` may be an array: the result has shape
    ``value.shape + (intervals,)``.
    """
    low = borders[:-1].copy()
    high = borders[1:].copy()
    low[0] = -np.inf
    high[-1] = np.inf
    value_arr = np.asarray(value, dtype=np.float64)[..., None]
    weights: np.ndarray = np.clip(value_arr, low, high) - np.clip(0.0, low, high)
    return weights


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_facedef_mesh_text(text: str) -> FaceDefMesh:
    """Read the plain textual FaceDefMesh of Tekalp and Ostermann 2000, Table 5.

    Example::

        FAP 6 (stretch left corner lip)
        IndexedFaceSet: Face
        interval borders: -1000, 0, 500, 1000
        displacements:
        vertex 50 1 0 0, 0.9 0 0, 1.5 0 4
        vertex 51 0.8 0 0, 0.7 0 0, 2 0 0
    """
    fap_match = re.search(r"FAP\s+(\d+)", text)
    borders_match = re.search(r"interval borders:\s*([^\n]+)", text)
    if fap_match is None or borders_match is None:
        raise FaceError("a FaceDefMesh table needs 'FAP n' and 'interval borders:'")
    target_match = re.search(r"IndexedFaceSet:\s*(\S+)", text)
    borders = tuple(float(x) for x in re.findall(_NUMBER, borders_match.group(1)))
    vertices: list[int] = []
    displacements: list[tuple[Vec3, ...]] = []
    for line in text.splitlines():
        match = re.match(r"\s*vertex\s+(\d+)\s+(.*)$", line)
        if match is None:
            continue
        numbers = [float(x) for x in re.findall(_NUMBER, match.group(2))]
        if len(numbers) % 3:
            raise FaceError(f"vertex {match.group(1)}: displacements come in threes")
        triples = tuple(
            (numbers[i], numbers[i + 1], numbers[i + 2]) for i in range(0, len(numbers), 3)
        )
        vertices.append(int(match.group(1)))
        displacements.append(triples)
    return FaceDefMesh(
        fap=int(fap_match.group(1)),
        intervals=borders,
        vertices=tuple(vertices),
        displacements=tuple(displacements),
        target=target_match.group(1) if target_match else "Face",
    )
