"""FACS Action Units to MPEG-4 FAPs (Paul 2010, chapter 5).

The mapping file format is the one of Paul 2010, section 5.2 and figure 5.2: a
plain text file whose significant lines are either an **AU line** (the AU
number, optionally followed by ``L`` or ``R`` for a left- or right-side
movement) or a **FAP line** with five fields, ``FAP au-start au-end
fap-start fap-end``, which belongs to the last AU line above it. ``#`` starts
a comment; blank lines are ignored. Fields may be separated by tabs (as in
the thesis) or spaces::

    23 L
    53 0.0 1.0 0 -300
    25
    3  0.0 1.0 0 900
    4  0.5 1.0 0 -100

A FAP line maps the AU's intensity linearly (Paul 2010, section 5.2: "AU 23
... When the AU is activated half way down its range (0.5), the FAP is
calculated as 0 + (-300 - 0) * 0.5 = -150"): below ``au-start`` the FAP
holds ``fap-start``, above ``au-end`` it holds ``fap-end``.

Sides. An AU requested without a side (``12``) moves both halves of the face:
the AU's unsided lines and its ``L`` and ``R`` lines all apply. ``12L`` applies
the ``L`` lines and the unsided ones (midline FAPs such as the jaw cannot be
lateralised). Several AUs moving the same FAP add up (:func:`summed`).

The default mapping (``realizer/face/data/facs/default.map``) covers every AU
of Paul 2010, Appendix A; docs/facs.md says where each line comes from.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from realizer.face.convert.config import FAP_COUNT, FapConfiguration, check_fap_number
from realizer.face.convert.errors import ConversionError, DataFileError

#: Where the converters' data files live (package data).
DATA_DIR = Path(__file__).resolve().parent.parent / "data"

#: The sides an AU line may carry (Paul 2010, section 5.2); ``None`` is both.
SIDES = ("L", "R")

_ACTIVATION = re.compile(r"^\s*(?:AU)?(\d+)\s*([LRlr])?\s*(?::\s*([-+0-9.eE]+))?\s*$")


@dataclass(frozen=True, slots=True)
class AuKey:
    """An Action Unit on one side of the face (``side`` ``"L"``/``"R"``) or unsided."""

    au: int
    side: str | None = None

    def __post_init__(self) -> None:
        if self.au < 1:
            raise ConversionError(f"AU {self.au} is not an Action Unit number")
        if self.side is not None and self.side not in SIDES:
            raise ConversionError(f"AU side must be L or R, not {self.side!r}")

    def __str__(self) -> str:
        return f"{self.au}{self.side or ''}"


@dataclass(frozen=True, slots=True)
class FapInfluence:
    """One FAP line: FAP ``fap`` goes from ``fap_start`` to ``fap_end`` (FAPU-scaled
    units) while the AU's intensity goes from ``au_start`` to ``au_end``."""

    fap: int
    au_start: float
    au_end: float
    fap_start: float
    fap_end: float

    def __post_init__(self) -> None:
        check_fap_number(self.fap)
        if not self.au_end > self.au_start:
            raise ConversionError(
                f"FAP {self.fap}: AU range [{self.au_start}, {self.au_end}] is empty"
            )

    def value(self, intensity: float) -> float:
        """The FAP value at AU ``intensity`` (Paul 2010, section 5.2, linear)."""
        u = (intensity - self.au_start) / (self.au_end - self.au_start)
        u = min(1.0, max(0.0, u))
        return self.fap_start + (self.fap_end - self.fap_start) * u


@dataclass(frozen=True, slots=True)
class AuActivation:
    """A requested AU: number, side (``None`` = both) and intensity 0..1."""

    au: int
    side: str | None = None
    intensity: float = 1.0

    def __post_init__(self) -> None:
        AuKey(self.au, self.side)  # validates number and side
        if not 0.0 <= self.intensity <= 1.0:
            raise ConversionError(
                f"AU {self.au}{self.side or ''}: intensity {self.intensity} is outside 0..1"
            )

    @classmethod
    def parse(cls, text: str) -> AuActivation:
        """Parse ``12``, ``12L``, ``12R:0.8`` or ``AU12L:0.8`` (intensity defaults to 1)."""
        match = _ACTIVATION.match(text)
        if match is None:
            raise ConversionError(f"{text!r} is not an AU (expected e.g. 12, 12L or 12L:0.8)")
        number, side, intensity = match.groups()
        try:
            value = 1.0 if intensity is None else float(intensity)
        except ValueError:
            raise ConversionError(f"{text!r}: bad intensity {intensity!r}") from None
        return cls(int(number), side.upper() if side else None, value)

    def __str__(self) -> str:
        return f"{self.au}{self.side or ''}:{self.intensity:g}"


@dataclass(frozen=True, slots=True)
class FacsMapping:
    """A parsed mapping file: AU lines, each with its FAP lines, in file order.

    ``descriptions`` keeps the comment that follows an AU line's fields (the
    default file names each AU there), so a round trip keeps it.
    """

    entries: tuple[tuple[AuKey, tuple[FapInfluence, ...]], ...]
    descriptions: tuple[tuple[AuKey, str], ...] = ()
    _table: dict[AuKey, tuple[FapInfluence, ...]] = field(
        init=False, repr=False, compare=False, hash=False
    )

    def __post_init__(self) -> None:
        keys = [key for key, _ in self.entries]
        if len(set(keys)) != len(keys):
            raise ConversionError("an AU line with the same side appears twice")
        object.__setattr__(self, "_table", dict(self.entries))  # lookups per request

    def action_units(self) -> tuple[int, ...]:
        """The AU numbers the mapping defines, ascending."""
        return tuple(sorted({key.au for key, _ in self.entries}))

    def influences(self, au: int, side: str | None = None) -> tuple[FapInfluence, ...]:
        """The FAP lines that apply when ``au`` is requested on ``side`` (see module doc)."""
        sides: tuple[str | None, ...] = (None, "L", "R") if side is None else (None, side)
        found = [self._table[key] for s in sides if (key := AuKey(au, s)) in self._table]
        if not found:
            defined = "" if side is None else f" on side {side}"
            raise ConversionError(f"AU {au}{defined} is not in the FACS mapping")
        return tuple(influence for group in found for influence in group)

    def configuration(self, activations: Iterable[AuActivation]) -> FapConfiguration:
        """The FAP values of several AUs at once; FAPs moved by several AUs add up."""
        values = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        for activation in activations:
            if activation.intensity <= 0.0:
                continue  # an AU at rest sets nothing, not even fap-start
            for influence in self.influences(activation.au, activation.side):
                values[influence.fap - 1] += influence.value(activation.intensity)
                mask[influence.fap - 1] = True
        return FapConfiguration(values, mask)

    def description(self, key: AuKey) -> str:
        return dict(self.descriptions).get(key, "")


def _fields(line: str) -> tuple[list[str], str]:
    body, _, comment = line.partition("#")
    return body.split(), comment.strip()


def parse_mapping(text: str, *, source: str = "<mapping>") -> FacsMapping:
    """Parse a mapping file (format in the module docstring); raise DataFileError."""
    entries: list[tuple[AuKey, list[FapInfluence]]] = []
    descriptions: list[tuple[AuKey, str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields, comment = _fields(line)
        if not fields:
            continue
        try:
            if len(fields) in (1, 2):
                side = fields[1].upper() if len(fields) == 2 else None
                key = AuKey(int(fields[0]), side)
                entries.append((key, []))
                if comment:
                    descriptions.append((key, comment))
            elif len(fields) == 5:
                if not entries:
                    raise DataFileError("a FAP line before any AU line", source=source, line=number)
                fap = int(fields[0])
                au_start, au_end, fap_start, fap_end = (float(f) for f in fields[1:])
                entries[-1][1].append(FapInfluence(fap, au_start, au_end, fap_start, fap_end))
            else:
                raise DataFileError(
                    "expected an AU line (AU [L|R]) or a FAP line (5 fields), "
                    f"got {len(fields)} fields",
                    source=source,
                    line=number,
                )
        except DataFileError:
            raise
        except (ValueError, ConversionError) as error:
            raise DataFileError(str(error), source=source, line=number) from None
    try:
        return FacsMapping(
            tuple((key, tuple(group)) for key, group in entries), tuple(descriptions)
        )
    except ConversionError as error:
        raise DataFileError(str(error), source=source) from None


def _number(value: float) -> str:
    return str(int(value)) if value == int(value) else repr(value)


def _au_number(value: float) -> str:
    # the thesis writes AU bounds with one decimal ("0.0 1.0"); keep exact otherwise
    return f"{value:.1f}" if round(value, 1) == value else repr(value)


def format_mapping(mapping: FacsMapping) -> str:
    """Write a mapping in the file format; :func:`parse_mapping` reads it back equal."""
    lines: list[str] = []
    for key, influences in mapping.entries:
        head = f"{key.au}\t{key.side}" if key.side else f"{key.au}"
        description = mapping.description(key)
        lines.append(f"{head}\t# {description}" if description else head)
        for i in influences:
            lines.append(
                f"{i.fap}\t{_au_number(i.au_start)}\t{_au_number(i.au_end)}\t"
                f"{_number(i.fap_start)}\t{_number(i.fap_end)}"
            )
        lines.append("")
    return "\n".join(lines)


@lru_cache(maxsize=1)
def load_default_mapping() -> FacsMapping:
    """The default mapping shipped in ``realizer/face/data/facs/default.map``."""
    path = DATA_DIR / "facs" / "default.map"
    return parse_mapping(path.read_text(encoding="utf-8"), source=str(path))


def facs_to_faps(
    activations: Iterable[AuActivation | str] | Mapping[str, float],
    mapping: FacsMapping | None = None,
) -> FapConfiguration:
    """FAP values of AUs given as :class:`AuActivation`, strings like ``"12L:0.8"``,
    or a mapping ``{"12L": 0.8}``; uses the default mapping unless one is given."""
    if isinstance(activations, Mapping):
        items = [AuActivation.parse(f"{key}:{value}") for key, value in activations.items()]
    else:
        items = [a if isinstance(a, AuActivation) else AuActivation.parse(a) for a in activations]
    return (mapping or load_default_mapping()).configuration(items)
