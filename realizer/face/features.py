"""MPEG-4 feature points: the 84 points of Tekalp and Ostermann 2000, Table 6 (Figure 2).

Feature points are named "group.index" ("3.5" = centre of the pupil of the
left eye). The table lives in ``data/feature_points.csv``; this module loads
it into :class:`FeaturePoint` records.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from functools import cache
from importlib import resources


@dataclass(frozen=True, slots=True)
class FeaturePoint:
    """One feature point of Table 6 and its recommended location constraints."""

    name: str  # "2.1"
    description: str
    constraint_x: str
    constraint_y: str
    constraint_z: str

    @property
    def group(self) -> int:
        return int(self.name.split(".")[0])

    @property
    def index(self) -> int:
        return int(self.name.split(".")[1])


@cache
def load_feature_points() -> dict[str, FeaturePoint]:
    """Read ``data/feature_points.csv``: name -> :class:`FeaturePoint`, in table order."""
    text = resources.files("realizer.face").joinpath("data/feature_points.csv").read_text("utf-8")
    lines = [line for line in text.splitlines() if not line.startswith("#")]
    points: dict[str, FeaturePoint] = {}
    for row in csv.DictReader(lines):
        points[row["feature_point"]] = FeaturePoint(
            name=row["feature_point"],
            description=row["description"],
            constraint_x=row["constraint_x"],
            constraint_y=row["constraint_y"],
            constraint_z=row["constraint_z"],
        )
    return points


#: Feature point name -> :class:`FeaturePoint`, the 84 points of Table 6.
FEATURE_POINTS: dict[str, FeaturePoint] = load_feature_points()


def sort_key(name: str) -> tuple[int, int]:
    """Order feature point names numerically: 2.1 < 2.2 < 2.10 < 3.1."""
    group, index = name.split(".")
    return int(group), int(index)
