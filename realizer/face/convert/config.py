"""FAP configurations: the common result of every converter.

A configuration is a FAP vector in the layout of ``docs/interfaces.md``:
``values`` has shape ``(68,)``, float64, FAP *n* at index *n - 1*, in
FAPU-scaled units; ``mask`` (``(68,)`` bool) says which FAPs the converter
sets. A FAP that is set to 0 is different from one that is not set: the
first holds the face neutral there, the second leaves it to other layers.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from realizer.face.convert.errors import ConversionError

#: Number of MPEG-4 FAPs (Tekalp and Ostermann 2000, Table 7).
FAP_COUNT = 68

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def check_fap_number(fap: int) -> int:
    """Return ``fap`` if it is an MPEG-4 FAP number 1..68; raise ConversionError otherwise."""
    if not 1 <= fap <= FAP_COUNT:
        raise ConversionError(f"FAP {fap} is not an MPEG-4 FAP number (1..{FAP_COUNT})")
    return fap


@dataclass(frozen=True, slots=True, eq=False)
class FapConfiguration:
    """FAP values a converter sets: ``values`` (68,) float64 and ``mask`` (68,) bool."""

    values: FloatArray
    mask: BoolArray

    def __post_init__(self) -> None:
        if self.values.shape != (FAP_COUNT,) or self.mask.shape != (FAP_COUNT,):
            raise ConversionError("a FAP configuration needs (68,) values and a (68,) mask")

    @classmethod
    def empty(cls) -> FapConfiguration:
        return cls(np.zeros(FAP_COUNT), np.zeros(FAP_COUNT, dtype=bool))

    @classmethod
    def from_mapping(cls, faps: Mapping[int, float]) -> FapConfiguration:
        """Build from ``{FAP number: value}``."""
        values = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        for fap, value in faps.items():
            values[check_fap_number(fap) - 1] = value
            mask[fap - 1] = True
        return cls(values, mask)

    def as_dict(self) -> dict[int, float]:
        """``{FAP number: value}`` for the FAPs that are set, in FAP order."""
        return {int(i) + 1: float(self.values[i]) for i in np.flatnonzero(self.mask)}

    def scaled(self, factor: float) -> FapConfiguration:
        """Every set value multiplied by ``factor`` (e.g. a BML ``amount``)."""
        return FapConfiguration(self.values * factor, self.mask.copy())

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FapConfiguration):
            return NotImplemented
        return bool(np.array_equal(self.mask, other.mask)) and bool(
            np.allclose(self.values[self.mask], other.values[other.mask])
        )

    def __hash__(self) -> int:
        return hash(tuple(self.as_dict().items()))


def summed(configurations: Iterable[FapConfiguration]) -> FapConfiguration:
    """Per-FAP sum of configurations; a FAP is set where any of them sets it.

    This is how simultaneous Action Units combine (Paul 2010, chapter 5 maps each
    AU linearly; two AUs moving the same feature point add their displacements).
    """
    values = np.zeros(FAP_COUNT)
    mask = np.zeros(FAP_COUNT, dtype=bool)
    for configuration in configurations:
        values += np.where(configuration.mask, configuration.values, 0.0)
        mask |= configuration.mask
    return FapConfiguration(values, mask)
