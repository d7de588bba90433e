"""The MPEG-4 FAP table: the 68 facial animation parameters of Tekalp and Ostermann 2000, Table 7.

The table itself lives in ``data/faps.csv`` (a transcription of every column);
this module loads it into :class:`FapInfo` records. :data:`FAP_TABLE` maps the
FAP number (1..68) to its record; :func:`fap` looks one up by number or name.

Coordinate frame (see docs/face-model.md): right-handed, metres, the face looks
along +z, y points up, and +x points to the face's *own* left. This is the frame
of the FaceDefMesh example of Tekalp and Ostermann 2000 (FAP 6, "stretch left corner lip", has
the displacement (1, 0, 0)). "left"/"right" in the table are the face's own.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Literal

import numpy as np

from realizer.face.errors import FapValueError

Unit = Literal["IRISD", "ES", "ENS", "MNS", "MW", "AU", "na"]

#: Number of FAPs in a FAP vector.
FAP_COUNT = 68

#: Unit vectors of the translational directions of Table 7, in the face frame.
DIRECTION_AXES: dict[str, tuple[float, float, float]] = {
    "up": (0.0, 1.0, 0.0),
    "down": (0.0, -1.0, 0.0),
    "left": (1.0, 0.0, 0.0),
    "right": (-1.0, 0.0, 0.0),
    "forward": (0.0, 0.0, 1.0),
}

#: Rotation axes (right-hand rule) of the angular FAPs whose positive value turns
#: the part the way Table 7 says: pitch "down" turns +z towards -y (axis +x),
#: yaw "left" turns +z towards +x (axis +y), roll "right" turns +y towards -x
#: (axis +z).
ROTATION_AXES: dict[str, tuple[float, float, float]] = {
    "pitch_down": (1.0, 0.0, 0.0),
    "yaw_left": (0.0, 1.0, 0.0),
    "roll_right": (0.0, 0.0, 1.0),
}


@dataclass(frozen=True, slots=True)
class FapInfo:
    """One row of Tekalp and Ostermann 2000, Table 7.

    ``feature_points`` are the names ("2.1") of the feature points the FAP
    moves (empty for FAPs 1, 2, 23-28 and 48-50, whose table cell is "na").
    Ranges are quantised FAP values (FAPU-scaled integers).
    """

    number: int
    name: str
    description: str
    unit: Unit
    bidirectional: bool
    direction: str  # "up", "down", "left", "right", "forward", "growing", ...
    group: int
    feature_points: tuple[str, ...]
    quant_step: int
    iframe_min: int
    iframe_max: int
    pframe_min: int
    pframe_max: int

    @property
    def index(self) -> int:
        """Position of this FAP in a FAP vector (number - 1)."""
        return self.number - 1

    @property
    def unidirectional(self) -> bool:
        return not self.bidirectional

    @property
    def feature_point(self) -> str | None:
        """The first (usually only) feature point this FAP moves, if any."""
        return self.feature_points[0] if self.feature_points else None

    @property
    def axis(self) -> tuple[float, float, float] | None:
        """Unit vector of a positive value, for translational FAPs; else None.

        Angular FAPs (unit AU), pupil dilation ("growing") and the high-level
        FAPs 1 and 2 have no single axis.
        """
        if self.unit in ("AU", "na"):
            return None
        return DIRECTION_AXES.get(self.direction)


def _parse_range(cell: str) -> tuple[int, int]:
    """'+-600' -> (-600, 600); '+1080' -> (0, 1080); 'viseme_blend: +63' -> (0, 63)."""
    match = re.search(r"\+(-?)(\d+)\s*$", cell)
    if match is None:
        raise ValueError(f"unreadable FAP range {cell!r}")
    high = int(match.group(2))
    return (-high if match.group(1) else 0), high


def _parse_feature_points(group: str, subgroup: str) -> tuple[str, ...]:
    if subgroup.strip() == "na":
        return ()
    return tuple(f"{group}.{part.strip()}" for part in subgroup.split(","))


@cache
def load_fap_table() -> dict[int, FapInfo]:
    """Read ``data/faps.csv`` into a dict FAP number -> :class:`FapInfo`."""
    text = resources.files("realizer.face").joinpath("data/faps.csv").read_text("utf-8")
    lines = [line for line in text.splitlines() if not line.startswith("#")]
    table: dict[int, FapInfo] = {}
    for row in csv.DictReader(lines):
        imin, imax = _parse_range(row["iframe_range"])
        pmin, pmax = _parse_range(row["pframe_range"])
        number = int(row["number"])
        bidir = row["unidir_or_bidir"]
        table[number] = FapInfo(
            number=number,
            name=row["name"],
            description=row["description"],
            unit=row["unit"],  # type: ignore[arg-type]
            # FAPs 1 and 2 ("na") take signed blend values in P frames; they are
            # never given to a deformer, so call them bidirectional.
            bidirectional=bidir != "U",
            direction=row["positive_motion"],
            group=int(row["group"]),
            feature_points=_parse_feature_points(row["group"], row["fdp_subgroup"]),
            quant_step=int(row["quant_step"]),
            iframe_min=imin,
            iframe_max=imax,
            pframe_min=pmin,
            pframe_max=pmax,
        )
    if sorted(table) != list(range(1, FAP_COUNT + 1)):
        raise RuntimeError("data/faps.csv must list FAPs 1..68 exactly once")
    return table


#: FAP number (1..68) -> :class:`FapInfo`, from Tekalp and Ostermann 2000, Table 7.
FAP_TABLE: dict[int, FapInfo] = load_fap_table()

_BY_NAME = {info.name: info for info in FAP_TABLE.values()}


def fap(key: int | str) -> FapInfo:
    """The FAP with this number (1..68) or name ("open_jaw"); KeyError if none."""
    if isinstance(key, int):
        return FAP_TABLE[key]
    return _BY_NAME[key]


@cache
def unidirectional_mask() -> np.ndarray:
    """(68,) bool, True where the FAP is unidirectional (3, 14, 41, 42, 47)."""
    mask = np.array([FAP_TABLE[n].unidirectional for n in range(1, FAP_COUNT + 1)])
    mask.setflags(write=False)
    return mask


def as_fap_vector(values: object) -> np.ndarray:
    """Check and convert a FAP vector: (68,) float64, finite.

    Raises :class:`FapValueError` for another shape or non-finite values.
    """
    vector = np.asarray(values, dtype=np.float64)
    if vector.shape != (FAP_COUNT,):
        raise FapValueError(f"a FAP vector has shape (68,), not {vector.shape}")
    if not np.all(np.isfinite(vector)):
        raise FapValueError("a FAP vector must be finite")
    return vector


def clamp_unidirectional(values: np.ndarray) -> np.ndarray:
    """Copy of a FAP vector with negative values of unidirectional FAPs set to 0.

    Table 7 marks FAPs 3, 14, 41, 42 and 47 "U": they move only in their
    positive direction (a jaw cannot open upwards). The deformer clamps rather
    than raises, so a stream with a small negative overshoot still animates;
    :func:`check_fap_vector` is the strict check.
    """
    out = np.array(values, dtype=np.float64, copy=True)
    mask = unidirectional_mask()
    out[mask] = np.maximum(out[mask], 0.0)
    return out


def check_fap_vector(values: object) -> np.ndarray:
    """Strict check: as :func:`as_fap_vector`, and no unidirectional FAP negative.

    Raises :class:`FapValueError` naming the first offending FAP.
    """
    vector = as_fap_vector(values)
    bad = np.flatnonzero(unidirectional_mask() & (vector < 0))
    if bad.size:
        info = FAP_TABLE[int(bad[0]) + 1]
        raise FapValueError(
            f"FAP {info.number} ({info.name}) is unidirectional; {vector[bad[0]]:g} is negative"
        )
    return vector
