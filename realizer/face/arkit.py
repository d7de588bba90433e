"""FAP frames as Apple ARKit blendshape weights, and speech visemes as Oculus visemes.

The face engine works in FAP space (docs/architecture.md) and every
other face format is derived from FAP frames. The default face's source
mesh (MakeHuman hm08, CC0) comes with CC0 ARKit "Face Units" morph targets
(``data/arkit/faceunits.npz``, made by ``scripts/extract_arkit_targets.py``),
so a frame can be projected exactly onto them:

* the face is deformed from the frame's FAPs without the head and eye
  turns (:meth:`realizer.face.deform.FaceRig.deform_posed` with FAPs 23-26
  and 48-50 at 0), and the displacement
  of every skin vertex the targets reach is fitted by the 52 targets'
  offsets with weights bounded to 0..1 (bounded linear least squares,
  solved on the normal equations by projected coordinate descent, warm
  started from the previous frame, so a frame costs one product with the
  targets and a few sweeps over 44 weights);
* the eye-look shapes (``eyeLook*``) come from the eyeball FAPs 23-26 as
  angles over :data:`EYE_LOOK_FULL_RAD` (the default face's eyeballs are
  rigid spheres the targets do not move);
* head and eye rotations also travel as angles (the pose: head pitch, yaw,
  roll from FAPs 48-50; eye pitch and yaw from FAPs 23-26), for avatars
  with bones.

How well the fit reproduces the face is measured by
:func:`fit_error` (``docs/viewer-formats.md`` lists the figures).

The Oculus / OpenXR visemes (15: silence and 14 classes) map one to one
from MPEG-4's FAP 1 visemes (Table 3 of "Face and 2-D mesh animation in
MPEG-4"): ``data/arkit/oculus_visemes.csv``.
"""

from __future__ import annotations

import csv
import io
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

import numpy as np
import numpy.typing as npt

from realizer.face.errors import FaceError

FloatArray = npt.NDArray[np.float64]

#: Coordinate descent stops after this many sweeps, or when no weight moves
#: by more than the tolerance in a sweep.
FIT_SWEEPS = 25
FIT_TOLERANCE = 1e-4
#: An eyeball turned this far (radians) looks fully in, out, up or down.
EYE_LOOK_FULL_RAD = 0.5
#: Radians per FAP unit of the angle FAPs (the AU of Table 1, 1e-5 rad).
ANGLE_UNIT_RAD = 1e-5
#: Radians per unit of the pose's int16 angles in the arkit payload.
POSE_STEP_RAD = 1e-4
#: The pose angles, in payload order, and the FAP (index 0..67) each comes from.
POSE_FIELDS = (
    ("headPitch", 47),
    ("headYaw", 48),
    ("headRoll", 49),
    ("leftEyePitch", 24),
    ("leftEyeYaw", 22),
    ("rightEyePitch", 25),
    ("rightEyeYaw", 23),
)


def _data(name: str) -> Any:
    return resources.files("realizer.face") / "data" / "arkit" / name


@cache
def arkit_names() -> tuple[str, ...]:
    """Apple's 52 blendshape names, in the payload's order."""
    text = _data("names.txt").read_text(encoding="utf-8")
    names = tuple(line.strip() for line in text.splitlines() if line.strip()[:1] not in ("#", ""))
    if len(names) != 52:
        raise FaceError(f"names.txt lists {len(names)} ARKit names, not 52")
    return names


ARKIT_NAMES = arkit_names()
_EYE_LOOK = tuple(i for i, n in enumerate(ARKIT_NAMES) if n.startswith("eyeLook"))


@cache
def oculus_visemes() -> tuple[str, ...]:
    """Oculus viseme name of each MPEG-4 viseme 0..14 (index = FAP 1 viseme number)."""
    text = _data("oculus_visemes.csv").read_text(encoding="utf-8")
    rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
    table = {int(row["mpeg4"]): row["oculus"] for row in rows}
    return tuple(table[n] for n in range(15))


def has_targets() -> bool:
    return bool(_data("faceunits.npz").is_file())


@cache
def _target_file() -> dict[str, np.ndarray]:
    if not has_targets():
        raise FaceError(
            "the ARKit targets are missing: run python scripts/extract_arkit_targets.py"
        )
    with np.load(io.BytesIO(_data("faceunits.npz").read_bytes())) as data:
        return {key: data[key] for key in data.files}


def arkit_targets(face: Any) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """(vertices, offsets): the face vertices the targets move (sorted), and
    each target's offsets there, (52, k, 3) metres. Needs
    ``attr:source_index`` (the hm08 vertex of each face vertex), which the
    default face has. A few whole-array operations over the targets' stored
    offsets (no per-vertex or dense per-face work)."""
    source = face.attributes.get("source_index")
    if source is None:
        raise FaceError("this face has no source_index: ARKit targets fit only the default face")
    source = np.asarray(source, dtype=np.int64)
    data = _target_file()
    step = float(data["offset_step"])
    to_face = np.full(int(source.max()) + 1, -1, dtype=np.int64)
    mapped = np.flatnonzero(source >= 0)
    to_face[source[mapped]] = mapped
    indices = [data[f"{name}:index"].astype(np.int64) for name in ARKIT_NAMES]
    target = np.repeat(np.arange(52), [len(i) for i in indices])
    index = np.concatenate(indices)
    offsets = np.concatenate([data[f"{name}:offset"] for name in ARKIT_NAMES]).astype(np.float64)
    keep = index < to_face.size
    vertex = np.full(index.size, -1, dtype=np.int64)
    vertex[keep] = to_face[index[keep]]
    ok = vertex >= 0
    target, vertex, offsets = target[ok], vertex[ok], offsets[ok] * step
    moved = np.unique(vertex[np.any(offsets != 0, axis=1)])
    column = np.minimum(np.searchsorted(moved, vertex), max(moved.size - 1, 0))
    hit = moved[column] == vertex if moved.size else np.zeros(vertex.size, dtype=bool)
    out = np.zeros((52, moved.size, 3))
    out[target[hit], column[hit]] = offsets[hit]
    return moved, out


@dataclass(frozen=True, slots=True)
class ArkitFrame:
    """One frame as ARKit: ``weights`` (52,) in 0..1, ``pose`` (7,) radians."""

    weights: FloatArray
    pose: FloatArray


@dataclass(frozen=True, slots=True, eq=False)
class ArkitBasis:
    """What fitting a face costs to set up, once per face (tens of ms on
    the default face, mostly :func:`arkit_targets`): its rig, the vertices
    the targets move and their rest positions, the fitted targets' offsets
    as the columns of ``basis`` (3k, f), and the normal equations' ``gram``
    (f, f). Read-only once built, so every fit of the face shares it."""

    rig: Any
    vertices: npt.NDArray[np.int64]
    neutral: FloatArray
    fitted: npt.NDArray[np.int64]
    basis: FloatArray
    gram: FloatArray

    @classmethod
    def build(cls, face: Any) -> ArkitBasis:
        from realizer.face.deform import rig_for

        vertices, offsets = arkit_targets(face)
        fitted = np.array([i for i in range(52) if i not in _EYE_LOOK])
        basis = offsets[fitted].reshape(fitted.size, -1).T  # (3k, f)
        gram = basis.T @ basis + 1e-12 * np.eye(fitted.size)
        neutral = np.asarray(face.vertices, dtype=np.float64)[vertices]
        return cls(rig_for(face), vertices, neutral, fitted, basis, gram)


_BASES: weakref.WeakKeyDictionary[Any, ArkitBasis] = weakref.WeakKeyDictionary()
_PREPARING: weakref.WeakKeyDictionary[Any, Future[ArkitBasis]] = weakref.WeakKeyDictionary()
_BASES_LOCK = threading.Lock()
_BUILDER: ThreadPoolExecutor | None = None


def arkit_basis(face: Any) -> ArkitBasis:
    """The face's :class:`ArkitBasis`, built here on first use (blocking;
    a real-time caller uses :func:`prepare_arkit` instead)."""
    with _BASES_LOCK:
        found = _BASES.get(face)
    if found is None:
        found = ArkitBasis.build(face)
        with _BASES_LOCK:
            found = _BASES.setdefault(face, found)
    return found


def prepare_arkit(face: Any) -> Future[ArkitBasis]:
    """The face's :class:`ArkitBasis`, built in a background thread (once
    per face, however many callers ask) so that a frame clock never waits
    for it: the future is done at once when the basis exists, and holds the
    :class:`FaceError` of a face the targets do not fit."""
    global _BUILDER
    with _BASES_LOCK:
        found = _BASES.get(face)
        if found is not None:
            done: Future[ArkitBasis] = Future()
            done.set_result(found)
            return done
        pending = _PREPARING.get(face)
        if pending is None:
            if _BUILDER is None:
                _BUILDER = ThreadPoolExecutor(1, thread_name_prefix="realizer-arkit")
            pending = _PREPARING[face] = _BUILDER.submit(arkit_basis, face)
        return pending


def forget_arkit_bases() -> None:
    """Drop every built basis (tests measure a first build with it)."""
    with _BASES_LOCK:
        _BASES.clear()
        _PREPARING.clear()


class ArkitFit:
    """Projects FAP frames onto the ARKit targets of a face (module docstring).

    The per-face set-up is the shared :class:`ArkitBasis` (``basis``, or
    built here); a fit keeps only its warm start, one per stream."""

    def __init__(self, face: Any, basis: ArkitBasis | None = None) -> None:
        shared = basis if basis is not None else arkit_basis(face)
        self.rig = shared.rig
        self.vertices = shared.vertices
        self.neutral = shared.neutral
        self.fitted = shared.fitted
        self.basis = shared.basis
        self.gram = shared.gram
        self._last = np.zeros(self.fitted.size)

    def displacement(self, fap_vector: FloatArray) -> FloatArray:
        """(k, 3) metres: the face's displacement at the targets' vertices, without
        the head and eye turns (they travel as the pose's angles)."""
        vector = np.array(fap_vector, dtype=np.float64)
        vector[[i for _, i in POSE_FIELDS]] = 0.0  # head and eye turns travel as angles
        posed, _ = self.rig.deform_posed(vector)
        out: FloatArray = np.asarray(posed, dtype=np.float64)[self.vertices] - self.neutral
        return out

    def solve(self, rhs: FloatArray, sweeps: int = FIT_SWEEPS) -> FloatArray:
        """argmin over 0 <= w <= 1 of |basis w - d|^2, given ``rhs = basis^T d``."""
        w = self._last.copy()
        gram = self.gram
        diagonal = np.diag(gram)
        for _ in range(sweeps):
            change = 0.0
            for j in range(w.size):
                g = float(gram[j] @ w) - float(rhs[j])
                new = min(1.0, max(0.0, w[j] - g / diagonal[j]))
                change = max(change, abs(new - w[j]))
                w[j] = new
            if change < FIT_TOLERANCE:
                break
        self._last = w
        return w

    def frame(self, fap_vector: FloatArray) -> ArkitFrame:
        vector = np.asarray(fap_vector, dtype=np.float64)
        weights = np.zeros(52)
        d = self.displacement(vector).reshape(-1)
        if np.any(d):
            weights[self.fitted] = self.solve(self.basis.T @ d)
        angles = vector * ANGLE_UNIT_RAD
        look = {
            "eyeLookOutLeft": angles[22],
            "eyeLookInLeft": -angles[22],
            "eyeLookInRight": angles[23],
            "eyeLookOutRight": -angles[23],
            "eyeLookDownLeft": angles[24],
            "eyeLookUpLeft": -angles[24],
            "eyeLookDownRight": angles[25],
            "eyeLookUpRight": -angles[25],
        }
        for name, angle in look.items():
            weights[ARKIT_NAMES.index(name)] = min(1.0, max(0.0, angle / EYE_LOOK_FULL_RAD))
        pose = np.array([angles[i] for _, i in POSE_FIELDS])
        return ArkitFrame(np.clip(weights, 0.0, 1.0), pose)

    def reconstruct(self, frame: ArkitFrame) -> FloatArray:
        """(k, 3) the targets' sum at ``frame``'s weights (for measuring the fit)."""
        out: FloatArray = (self.basis @ frame.weights[self.fitted]).reshape(-1, 3)
        return out


def payload(frame: ArkitFrame) -> bytes:
    """The ``arkit`` payload: 52 uint8 weights (x / 255), then 7 int16 LE pose angles."""
    weights = np.rint(np.clip(frame.weights, 0.0, 1.0) * 255).astype(np.uint8)
    pose = np.clip(np.rint(frame.pose / POSE_STEP_RAD), -32767, 32767).astype("<i2")
    return weights.tobytes() + pose.tobytes()


def decode_payload(data: bytes) -> ArkitFrame:
    """The inverse of :func:`payload` (weights to 1/255, angles to 1e-4 rad)."""
    if len(data) != 52 + 2 * len(POSE_FIELDS):
        raise FaceError(f"an arkit payload has {52 + 2 * len(POSE_FIELDS)} bytes, not {len(data)}")
    weights = np.frombuffer(data[:52], dtype=np.uint8).astype(np.float64) / 255.0
    pose = np.frombuffer(data[52:], dtype="<i2").astype(np.float64) * POSE_STEP_RAD
    return ArkitFrame(weights, pose)


def arkit_encoder(face: Any, basis: ArkitBasis | None = None) -> Callable[[FloatArray], bytes]:
    """``vector -> arkit payload`` for a face, the last result kept for an unchanged vector."""
    fit = ArkitFit(face, basis)
    last: list[Any] = [None, b""]

    def encode(vector: FloatArray) -> bytes:
        if last[0] is not None and np.array_equal(last[0], vector):
            return bytes(last[1])
        data = payload(fit.frame(vector))
        last[0], last[1] = np.array(vector, copy=True), data
        return data

    return encode


def write_arkit_csv(
    path: Any, face: Any, times: FloatArray, values: FloatArray, mask: npt.NDArray[np.bool_]
) -> None:
    """An ARKit track: a header ``timecode`` then Apple's 52 names (and the
    pose angles in radians), one row per frame, as ARKit face recordings are
    laid out."""
    from pathlib import Path

    fit = ArkitFit(face)
    header = ["time", *ARKIT_NAMES, *(name for name, _ in POSE_FIELDS)]
    lines = [",".join(header)]
    for t, vector, set_ in zip(times, values, mask, strict=True):
        frame = fit.frame(np.where(set_, vector, 0.0))
        cells = [
            f"{t:.4f}",
            *(f"{w:.4f}" for w in frame.weights),
            *(f"{a:.5f}" for a in frame.pose),
        ]
        lines.append(",".join(cells))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def fit_error(fit: ArkitFit, vectors: list[FloatArray]) -> tuple[float, float]:
    """(largest vertex error, metres; relative RMS error) of the fit over ``vectors``."""
    worst, num, den = 0.0, 0.0, 0.0
    for vector in vectors:
        d = fit.displacement(vector)
        r = fit.reconstruct(fit.frame(vector)) - d
        worst = max(worst, float(np.linalg.norm(r, axis=1).max()))
        num += float((r**2).sum())
        den += float((d**2).sum())
    return worst, (num / den) ** 0.5 if den else 0.0
