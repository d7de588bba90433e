"""Face animation parameter units (FAPU), Tekalp and Ostermann 2000, section 2.1.1, Table 1.

FAPU are fractions of key distances of the neutral face, so the same FAP value
means the same expression on faces of any size: IRISD = IRISD0/1024, ES =
ES0/1024, ENS = ENS0/1024, MNS = MNS0/1024, MW = MW0/1024 (metres per unit),
and AU = 1e-5 rad per unit. A FAP of 1024 moves its feature point by the whole
key distance (Paul 2010, section 4.1).

Key distances from feature points (MPEG-4 Figure 1; the frame of
docs/face-model.md, +x the face's left, +y up):

=======  ===============================  ================================
IRISD0   iris diameter = distance upper    3.1.y - 3.3.y (left eye), mean
         to lower eyelid                   with 3.2.y - 3.4.y (right eye)
ES0      eye separation                    3.5.x - 3.6.x (pupil centres)
ENS0     eye-nose separation               3.5.y - 9.15.y (mean of both eyes)
MNS0     mouth-nose separation             9.15.y - 2.2.y
MW0      mouth width                       8.3.x - 8.4.x (outer lip corners)
=======  ===============================  ================================
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from realizer.face.errors import FaceError
from realizer.face.faps import FAP_COUNT, FAP_TABLE

#: The angle unit, radians per FAP unit (Table 1: "10E-5 rad", i.e. 1e-5).
ANGLE_UNIT_RAD = 1e-5

Point = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Fapu:
    """The FAPU of one face: metres per FAP unit, and radians per unit for AU."""

    irisd: float
    es: float
    ens: float
    mns: float
    mw: float
    au: float = ANGLE_UNIT_RAD

    def __post_init__(self) -> None:
        for name in ("irisd", "es", "ens", "mns", "mw", "au"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise FaceError(f"FAPU {name.upper()} must be positive, not {value!r}")

    @classmethod
    def from_feature_points(cls, points: Mapping[str, Point]) -> Fapu:
        """Compute the FAPU from a neutral face's feature point positions (metres).

        Needs 3.1, 3.3 (or 3.2, 3.4), 3.5, 3.6, 9.15, 2.2, 8.3 and 8.4. Raises
        :class:`FaceError` when one is missing or a distance is not positive
        (e.g. left and right swapped).
        """

        def at(name: str) -> np.ndarray:
            try:
                return np.asarray(points[name], dtype=np.float64)
            except KeyError:
                raise FaceError(f"FAPU need feature point {name}") from None

        lids = [
            at(top)[1] - at(bottom)[1]
            for top, bottom in (("3.1", "3.3"), ("3.2", "3.4"))
            if top in points and bottom in points
        ]
        if not lids:
            raise FaceError("FAPU need feature points 3.1 and 3.3 (or 3.2 and 3.4)")
        irisd0 = float(np.mean(lids))
        es0 = float(at("3.5")[0] - at("3.6")[0])
        ens0 = float((at("3.5")[1] + at("3.6")[1]) / 2 - at("9.15")[1])
        mns0 = float(at("9.15")[1] - at("2.2")[1])
        mw0 = float(at("8.3")[0] - at("8.4")[0])
        return cls(
            irisd=irisd0 / 1024, es=es0 / 1024, ens=ens0 / 1024, mns=mns0 / 1024, mw=mw0 / 1024
        )

    def unit(self, name: str) -> float:
        """Size of one unit of ``name`` ("MNS", "AU", ...); 0.0 for "na"."""
        if name == "na":
            return 0.0
        try:
            return float(getattr(self, name.lower()))
        except AttributeError:
            raise FaceError(f"unknown FAPU {name!r}") from None

    def per_fap(self) -> np.ndarray:
        """(68,) float64: the unit of FAP n at index n-1 (metres or radians; 0 for 1, 2)."""
        return np.array(
            [self.unit(FAP_TABLE[n].unit) for n in range(1, FAP_COUNT + 1)], dtype=np.float64
        )
