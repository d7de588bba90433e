"""FAP 1 (visemes) and FAP 2 (expressions) as low-level FAPs.

Tekalp and Ostermann 2000, section 2.1.

MPEG-4 defines the 15 viseme numbers by phonemes (Tekalp and Ostermann 2000, Table 3) and the
six expressions by textual descriptions (Table 4); their shapes belong to the
face model. The shapes of the default face are in
``realizer/face/data/visemes/{visemes,expressions}.txt``.

Blending follows the FAP 1 and FAP 2 syntax of MPEG-4: a viseme frame names
two visemes and ``viseme_blend`` (0..63), giving
``blend/63 * viseme1 + (1 - blend/63) * viseme2``; an expression frame names
two expressions, each with an intensity 0..63, giving
``i1/63 * expression1 + i2/63 * expression2``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from realizer.face.convert.config import FAP_COUNT, FapConfiguration, check_fap_number
from realizer.face.convert.errors import ConversionError, DataFileError
from realizer.face.convert.facs import DATA_DIR

#: The largest viseme_blend and expression intensity (Tekalp and Ostermann 2000, Table 7: "+63").
FAP12_MAX = 63


@dataclass(frozen=True, slots=True)
class Shape:
    """A viseme or expression: number, label words and its FAP values."""

    kind: str  # "Viseme" or "Expression"
    number: int
    label: tuple[str, ...]
    values: tuple[tuple[int, float], ...]


@dataclass(frozen=True, slots=True)
class ShapeTable:
    kind: str
    shapes: tuple[Shape, ...]

    def numbers(self) -> tuple[int, ...]:
        return tuple(s.number for s in self.shapes)

    def shape(self, number: int) -> Shape:
        for shape in self.shapes:
            if shape.number == number:
                return shape
        raise ConversionError(f"no {self.kind.lower()} {number}; known: {self.numbers()}")

    def faps(self) -> tuple[int, ...]:
        """Every FAP some shape of the table sets."""
        return tuple(sorted({fap for s in self.shapes for fap, _ in s.values}))

    def configuration(self, number: int) -> FapConfiguration:
        """The shape's FAPs; for visemes every FAP of the table is set (the
        viseme defines the whole mouth), for expressions only the listed ones."""
        values = np.zeros(FAP_COUNT)
        mask = np.zeros(FAP_COUNT, dtype=bool)
        if self.kind == "Viseme":
            mask[np.array(self.faps(), dtype=int) - 1] = True
        for fap, value in self.shape(number).values:
            values[fap - 1] = value
            mask[fap - 1] = True
        return FapConfiguration(values, mask)


def _parse_values(body: str, *, source: str, line: int) -> tuple[tuple[int, float], ...]:
    values: list[tuple[int, float]] = []
    for item in body.split(","):
        fields = item.split()
        try:
            if len(fields) != 2 or not fields[0].upper().startswith("F"):
                raise ValueError(f"expected 'F<fap> <value>', got {item.strip()!r}")
            fap = check_fap_number(int(fields[0][1:]))
            value = float(fields[1])
        except (ValueError, ConversionError) as error:
            raise DataFileError(str(error), source=source, line=line) from None
        if any(f == fap for f, _ in values):
            raise DataFileError(f"F{fap} appears twice", source=source, line=line)
        values.append((fap, value))
    return tuple(values)


def parse_shapes(text: str, kind: str, *, source: str = "<shapes>") -> ShapeTable:
    """Parse a viseme (``kind="Viseme"``) or expression file."""
    lines = [
        (n, line.partition("#")[0].strip())
        for n, line in enumerate(text.splitlines(), start=1)
        if line.partition("#")[0].strip()
    ]
    if len(lines) % 2:
        raise DataFileError("a label without its values line", source=source, line=lines[-1][0])
    shapes: list[Shape] = []
    for (label_line, label), (line, body) in zip(lines[::2], lines[1::2], strict=True):
        fields = label.split()
        if len(fields) < 2 or fields[0] != kind or not fields[1].isdigit():
            raise DataFileError(
                f"expected '{kind} <number> ...', got {label!r}", source=source, line=label_line
            )
        number = int(fields[1])
        if any(s.number == number for s in shapes):
            raise DataFileError(f"{kind} {number} appears twice", source=source, line=label_line)
        shapes.append(
            Shape(kind, number, tuple(fields[2:]), _parse_values(body, source=source, line=line))
        )
    return ShapeTable(kind, tuple(shapes))


def format_shapes(table: ShapeTable) -> str:
    """Write a shape table in the file format (round trip with :func:`parse_shapes`)."""

    def num(value: float) -> str:
        return str(int(value)) if value == int(value) else repr(value)

    out: list[str] = []
    for shape in table.shapes:
        out.append(" ".join([shape.kind, str(shape.number), *shape.label]))
        out.append(", ".join(f"F{fap} {num(v)}" for fap, v in shape.values))
    return "\n".join(out) + "\n"


@lru_cache(maxsize=1)
def load_default_visemes() -> ShapeTable:
    path = DATA_DIR / "visemes" / "visemes.txt"
    return parse_shapes(path.read_text(encoding="utf-8"), "Viseme", source=str(path))


@lru_cache(maxsize=1)
def load_default_expressions() -> ShapeTable:
    path = DATA_DIR / "visemes" / "expressions.txt"
    return parse_shapes(path.read_text(encoding="utf-8"), "Expression", source=str(path))


def _check_level(name: str, value: float) -> float:
    if not 0 <= value <= FAP12_MAX:
        raise ConversionError(f"{name} {value} is outside 0..{FAP12_MAX}")
    return value


def viseme_faps(
    viseme1: int, viseme2: int = 0, blend: float = FAP12_MAX, *, table: ShapeTable | None = None
) -> FapConfiguration:
    """FAP 1: ``blend/63`` of ``viseme1`` and the rest of ``viseme2``."""
    weight = _check_level("viseme_blend", blend) / FAP12_MAX
    shapes = table or load_default_visemes()
    first, second = shapes.configuration(viseme1), shapes.configuration(viseme2)
    return FapConfiguration(
        weight * first.values + (1.0 - weight) * second.values, first.mask | second.mask
    )


def expression_faps(
    expression1: int,
    intensity1: float,
    expression2: int | None = None,
    intensity2: float = 0.0,
    *,
    table: ShapeTable | None = None,
) -> FapConfiguration:
    """FAP 2: ``i1/63 * expression1 + i2/63 * expression2`` (intensities 0..63)."""
    shapes = table or load_default_expressions()
    first = shapes.configuration(expression1)
    values = _check_level("expression_intensity1", intensity1) / FAP12_MAX * first.values
    mask = first.mask.copy()
    if expression2 is not None:
        second = shapes.configuration(expression2)
        values = (
            values + _check_level("expression_intensity2", intensity2) / FAP12_MAX * second.values
        )
        mask |= second.mask
    return FapConfiguration(values, mask)
