"""An automated audit of every FAP displacement of a face.

Section 4.4 of "Realization and high level specification of facial
expressions for embodied agents" scores each of the 127 displacements of
FAPs 3..68 (each direction of a bidirectional FAP on its own) by eye. This
module checks, for each displacement at the value ``realizer fap-sheet``
shows (``data/fap_sheet.csv``), what can be measured on the mesh:

* **folds**: skin triangles whose normal turns by more than 90 degrees (a
  crease or a tear; the jaw-open base pose of the tongue FAPs is the
  reference where the sheet opens the jaw);
* **direction**: a probe point moves along the FAP's positive motion
  ("Face and 2-D mesh animation in MPEG-4", Table 7: up, down, left =
  the face's left, +x, right, forward) times the value's sign. The probe is
  the FAP's feature point; for the eyeballs (23..28, "na" in Table 7) the
  pupil 3.5/3.6, for the head the nose tip 9.3 (48, 49) and the top of
  the head 11.1 (50); the pupils (29,
  30) are probed by their ring's radius, the tongue roll (47) by its borders
  rising above its middle;
* **side**: a one-sided FAP moves its own side: the probe's mirror point
  (the feature point nearest the probe mirrored through x = 0) moves less
  than a quarter as far;
* **visible**: the probe moves at least ``VISIBLE_M`` (0.5 mm; radius or
  roll 0.2 mm) along that direction.

:func:`audit_range` measures the same over the practical range of the jaw,
lip, cheek and nose FAPs (:data:`PRACTICAL_RANGE`), where tables that are
fold-free at the sheet's value folded the lips at 800 MNS.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from realizer.face.deform import deform
from realizer.face.faps import FAP_TABLE
from realizer.face.model import Face

#: Least motion of the probe along the FAP's direction that counts as seen.
VISIBLE_M = 0.0005
#: The same for the pupil's radius (29, 30) and the tongue's roll (47).
VISIBLE_SMALL_M = 0.0002
#: A one-sided FAP may move the mirror point at most this share of its own.
MIRROR_SHARE = 0.25

#: The largest value (FAPU-scaled) at which the default face's jaw, lip,
#: cheek and nose FAPs (3..18, 39..42, 51..62) must not fold the skin, each
#: direction on its own: the emotion profiles of "Parameterized Facial
#: Expression Synthesis Based on MPEG-4" reach 1252 on open_jaw, 792 on the
#: lower lip and 332 on the corners' stretch; beyond these a real face
#: cannot go either (a lip 14 mm from rest, a corner stretched 14 mm, a
#: nostril wing flared 7 mm). ``scripts/extract_default_face.py`` makes its
#: tables fold-free up to them (``fold_free_table``), ``realizer fap-audit
#: --range`` checks them. The tongue's FAPs move no skin; the eyes', brows',
#: head's and ears' FAPs are audited at the sheet's values only.
PRACTICAL_RANGE: dict[int, float] = {
    3: 1280,
    **dict.fromkeys((4, 5, 8, 9, 10, 11, 16, 17, 51, 52, 55, 56, 57, 58), 800),
    **dict.fromkeys((6, 7, 53, 54, 15), 256),
    **dict.fromkeys((12, 13, 59, 60), 800),
    14: 600,
    18: 512,
    **dict.fromkeys((39, 40), 256),
    **dict.fromkeys((41, 42), 170),
    **dict.fromkeys((61, 62), 150),
}
#: The values :func:`audit_range` tries: these shares of the practical range.
RANGE_STEPS = (0.25, 0.5, 0.75, 1.0)

_AXES = {
    "up": (0.0, 1.0, 0.0),
    "down": (0.0, -1.0, 0.0),
    "left": (1.0, 0.0, 0.0),
    "right": (-1.0, 0.0, 0.0),
    "forward": (0.0, 0.0, 1.0),
}
#: Probes for FAPs without a feature point of their own in Table 7.
_PROBES = {23: "3.5", 25: "3.5", 27: "3.5", 24: "3.6", 26: "3.6", 28: "3.6"}
#: The head: pitch and yaw move the nose tip; the roll, about the top of the
#: spine 7.1 (level with the nose tip), is seen at the top of the head 11.1.
_PROBES.update({48: "9.3", 49: "9.3", 50: "11.1"})


@dataclass(frozen=True, slots=True)
class AuditRow:
    """One displacement: ``fap`` at ``value`` and what the mesh showed."""

    fap: int
    value: float
    probe: str
    along_mm: float  # the probe's motion along the expected direction
    mirror_mm: float | None  # the mirror point's motion (one-sided FAPs)
    folds: int

    @property
    def name(self) -> str:
        return FAP_TABLE[self.fap].name

    @property
    def direction_ok(self) -> bool:
        return self.along_mm > 0.0

    @property
    def side_ok(self) -> bool | None:
        if self.mirror_mm is None:
            return None
        return self.mirror_mm <= MIRROR_SHARE * abs(self.along_mm)

    @property
    def visible(self) -> bool:
        small = self.fap in (29, 30, 47)
        return self.along_mm >= (VISIBLE_SMALL_M if small else VISIBLE_M) * 1000

    @property
    def ok(self) -> bool:
        return self.folds == 0 and self.direction_ok and self.side_ok is not False and self.visible


def _normals(face: Face, vertices: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    tri = np.asarray(vertices, dtype=np.float64)[face.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    return normal / np.maximum(area, 1e-30)[:, None], area


def count_folds(face: Face, before: npt.ArrayLike, after: npt.ArrayLike) -> int:
    """Skin triangles whose normal turns by more than 90 degrees."""
    n0, area = _normals(face, before)
    n1, _ = _normals(face, after)
    member = np.zeros(face.vertex_count, dtype=bool)
    member[face.part("skin")] = True
    skin = member[face.faces].all(axis=1) & (area > 1e-9)
    return int(np.sum(skin & (np.sum(n0 * n1, axis=1) < 0.0)))


def _mirror(face: Face, point: str) -> str | None:
    """The feature point nearest ``point`` mirrored through x = 0, or None
    for a point on the midline."""
    p = face.feature_position(point)
    if abs(p[0]) < 0.001:
        return None
    target = p * np.array([-1.0, 1.0, 1.0])
    names = list(face.params.feature_points)
    distances = [float(np.linalg.norm(face.feature_position(n) - target)) for n in names]
    return names[int(np.argmin(distances))]


def _pupil_radius(face: Face, vertices: np.ndarray, side: str) -> float:
    ring = vertices[face.part(f"{side}_pupil")]
    centre = ring.mean(axis=0)
    return float(np.linalg.norm((ring - centre)[:, :2], axis=1).max())


def _tongue_roll(face: Face, vertices: np.ndarray) -> float:
    """How far the tongue's borders stand above its middle (m)."""
    tongue = face.part("tongue")
    rest = np.asarray(face.vertices, dtype=np.float64)[tongue]
    half = float(np.ptp(rest[:, 0])) / 2
    centre_x = float(rest[:, 0].mean())
    border = np.abs(rest[:, 0] - centre_x) > 0.6 * half
    middle = np.abs(rest[:, 0] - centre_x) < 0.2 * half
    lift = vertices[tongue, 1] - rest[:, 1]
    return float(lift[border].mean() - lift[middle].mean())


def audit_displacement(face: Face, fap: int, value: float, jaw_open: float = 0.0) -> AuditRow:
    """Deform ``face`` by FAP ``fap`` at ``value`` alone (over FAP 3 at
    ``jaw_open``, as the sheet shows the tongue) and measure it."""
    base_values = np.zeros(68)
    base_values[2] = jaw_open
    values = base_values.copy()
    values[fap - 1] = value
    base = deform(face, base_values) if jaw_open else np.asarray(face.vertices)
    base = np.asarray(base, dtype=np.float64)
    moved = np.asarray(deform(face, values), dtype=np.float64)
    folds = count_folds(face, base, moved)
    sign = 1.0 if value > 0 else -1.0
    if fap in (29, 30):
        side = "left" if fap == 29 else "right"
        along = sign * (_pupil_radius(face, moved, side) - _pupil_radius(face, base, side))
        return AuditRow(fap, value, f"{side}_pupil", along * 1000, None, folds)
    if fap == 47:
        along = sign * (_tongue_roll(face, moved) - _tongue_roll(face, base))
        return AuditRow(fap, value, "tongue", along * 1000, None, folds)
    info = FAP_TABLE[fap]
    probe = _PROBES.get(fap) or info.feature_points[0]
    axis = np.asarray(_AXES[info.direction])
    k = face.feature_vertex(probe)
    along = sign * float((moved[k] - base[k]) @ axis)
    mirror_mm = None
    mirror = _mirror(face, probe) if fap not in (48, 49, 50) else None
    if mirror is not None and mirror != probe:
        m = face.feature_vertex(mirror)
        mirror_mm = float(np.linalg.norm(moved[m] - base[m])) * 1000
    return AuditRow(fap, value, probe, along * 1000, mirror_mm, folds)


def audit_face(face: Face, poses: Iterable[tuple[int, float, float]]) -> list[AuditRow]:
    """Every displacement of ``poses`` (FAP, value, FAP 3 under it: the rows
    of ``data/fap_sheet.csv``, which ``realizer fap-audit`` passes), both
    signs of a bidirectional FAP: 127 rows for the sheet's FAPs 3..68."""
    rows = []
    for fap, value, jaw_open in poses:
        signs = (1.0, -1.0) if FAP_TABLE[fap].bidirectional else (1.0,)
        for sign in signs:
            rows.append(audit_displacement(face, fap, sign * value, jaw_open))
    return rows


def audit_range(
    face: Face, ranges: dict[int, float] | None = None, steps: Iterable[float] = RANGE_STEPS
) -> list[AuditRow]:
    """Every FAP of ``ranges`` (default :data:`PRACTICAL_RANGE`) at the
    ``steps`` shares of its range, both signs of a bidirectional FAP: the
    same measures as :func:`audit_face`, beyond the sheet's single value."""
    rows = []
    for fap, reach in sorted((PRACTICAL_RANGE if ranges is None else ranges).items()):
        for share in steps:
            rows.extend(audit_face(face, [(fap, share * reach, 0.0)]))
    return rows


def format_audit(rows: list[AuditRow]) -> str:
    """The audit as a text table, one displacement a line, and a summary."""

    def mark(flag: bool | None) -> str:
        return "-" if flag is None else ("ok" if flag else "NO")

    lines = [
        f"{'FAP':>4} {'name':<22} {'value':>7} {'probe':<12} {'moved mm':>8} "
        f"{'mirror mm':>9} {'folds':>5} {'dir':>3} {'side':>4} {'seen':>4}  result"
    ]
    for r in rows:
        mirror = "" if r.mirror_mm is None else f"{r.mirror_mm:.2f}"
        lines.append(
            f"{r.fap:>4} {r.name:<22} {r.value:>7g} {r.probe:<12} {r.along_mm:>8.2f} "
            f"{mirror:>9} {r.folds:>5} {mark(r.direction_ok):>3} {mark(r.side_ok):>4} "
            f"{mark(r.visible):>4}  {'pass' if r.ok else 'FAIL'}"
        )
    failed = [r for r in rows if not r.ok]
    names = ", ".join(f"{r.fap}{'+' if r.value > 0 else '-'}" for r in failed)
    lines.append(
        f"{len(rows)} displacements: {len(rows) - len(failed)} pass, {len(failed)} fail"
        + (f": {names}" if failed else "")
    )
    return "\n".join(lines)
