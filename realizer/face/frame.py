"""FAP frames: one FAP vector at one time (docs/interfaces.md, "Units and numbering").

A :class:`FapFrame` holds the 68 FAP values in FAPU-scaled units (FAP n at
index n-1), a mask of which FAPs are set, the time in seconds and the frame
number, as in the .fap files of Paul 2010, section 4.2.2 (a mask line and a
value line per frame).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from realizer.face.errors import FapValueError
from realizer.face.faps import FAP_COUNT


@dataclass(frozen=True, slots=True, eq=False)
class FapFrame:
    """``values``: (68,) float64; ``mask``: (68,) bool; ``time``: seconds.

    The arrays are made read-only, so a frame can be shared safely. Values of
    FAPs whose mask bit is False are kept as given (normally 0) and mean "not
    set"; :attr:`vector` gives the values with unset FAPs zeroed, ready for
    :func:`realizer.face.deform.deform`.
    """

    values: np.ndarray
    mask: np.ndarray
    time: float = 0.0
    number: int = 0

    def __post_init__(self) -> None:
        values = np.array(self.values, dtype=np.float64)
        mask = np.array(self.mask, dtype=bool)
        if values.shape != (FAP_COUNT,) or mask.shape != (FAP_COUNT,):
            raise FapValueError(
                f"a FapFrame has (68,) values and mask, not {values.shape} and {mask.shape}"
            )
        if not np.isfinite(values).all():
            raise FapValueError("FAP values must be finite")
        values.setflags(write=False)
        mask.setflags(write=False)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "mask", mask)

    @classmethod
    def neutral(cls, time: float = 0.0, number: int = 0) -> FapFrame:
        """The neutral face: every FAP unset."""
        return cls(np.zeros(FAP_COUNT), np.zeros(FAP_COUNT, dtype=bool), time, number)

    @classmethod
    def from_mapping(
        cls, values: Mapping[int, float], time: float = 0.0, number: int = 0
    ) -> FapFrame:
        """A frame from {FAP number: value}; the named FAPs are set."""
        vector = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        for fap_number, value in values.items():
            if not 1 <= fap_number <= FAP_COUNT:
                raise FapValueError(f"FAP numbers are 1..68, not {fap_number}")
            vector[fap_number - 1] = value
            mask[fap_number - 1] = True
        return cls(vector, mask, time, number)

    @property
    def vector(self) -> np.ndarray:
        """(68,) float64 FAP vector with unset FAPs as 0 (a new array)."""
        return np.where(self.mask, self.values, 0.0)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FapFrame):
            return NotImplemented
        return (
            self.time == other.time
            and self.number == other.number
            and bool(np.array_equal(self.mask, other.mask))
            and bool(np.array_equal(self.values, other.values))
        )

    __hash__ = None  # type: ignore[assignment]
