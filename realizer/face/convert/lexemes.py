"""BML 1.0 ``faceLexeme`` lexemes and FACS behaviours to FAPs.

A lexeme names a set of FACS Action Units (``data/facs/lexemes.txt``, the
standard's full lexeme list); the AUs go through the FACS mapping
(:mod:`.facs`) to FAPs. The BML ``amount`` (0..1) multiplies each AU's
intensity, so it follows each FAP line's AU range rather than scaling FAP
values blindly (an AU line that starts at 0.5 stays off at small amounts).

``<ext:faceFacs au="12" side="LEFT" amount="0.8"/>`` (BML 1.0 core
extensions) and the draft ``<face type="FACS" au="12" .../>`` both go through
:func:`facs_behaviour_faps`, the same path with one AU.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from realizer.face.convert.config import FapConfiguration
from realizer.face.convert.errors import ConversionError, DataFileError
from realizer.face.convert.facs import (
    DATA_DIR,
    AuActivation,
    FacsMapping,
    load_default_mapping,
)

#: BML side names (ext:faceFacs ``side``) -> mapping-file sides.
BML_SIDES: dict[str, str | None] = {"LEFT": "L", "RIGHT": "R", "BOTH": None}


@dataclass(frozen=True, slots=True)
class LexemeTable:
    """Lexeme name -> the AUs (with side and base intensity) it stands for."""

    lexemes: tuple[tuple[str, tuple[AuActivation, ...]], ...]

    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.lexemes)

    def action_units(self, lexeme: str) -> tuple[AuActivation, ...]:
        table = dict(self.lexemes)
        key = lexeme.strip().upper()
        if key not in table:
            raise ConversionError(
                f"unknown faceLexeme {lexeme!r}; known: {', '.join(self.names())}"
            )
        return table[key]


def parse_lexemes(text: str, *, source: str = "<lexemes>") -> LexemeTable:
    """Parse a lexeme file: ``LEXEME AU[L|R][:intensity] ...`` per line, ``#`` comments."""
    entries: list[tuple[str, tuple[AuActivation, ...]]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.partition("#")[0].split()
        if not fields:
            continue
        if len(fields) < 2:
            raise DataFileError(f"lexeme {fields[0]} lists no AU", source=source, line=number)
        try:
            aus = tuple(AuActivation.parse(token) for token in fields[1:])
        except ConversionError as error:
            raise DataFileError(str(error), source=source, line=number) from None
        if any(name == fields[0].upper() for name, _ in entries):
            raise DataFileError(f"lexeme {fields[0]} appears twice", source=source, line=number)
        entries.append((fields[0].upper(), aus))
    return LexemeTable(tuple(entries))


def format_lexemes(table: LexemeTable) -> str:
    """Write a lexeme table in the file format (round trip with :func:`parse_lexemes`)."""
    width = max((len(name) for name in table.names()), default=0) + 2
    lines = []
    for name, aus in table.lexemes:
        tokens = " ".join(
            f"{a.au}{a.side or ''}" + ("" if a.intensity == 1.0 else f":{a.intensity!r}")
            for a in aus
        )
        lines.append(f"{name:<{width}}{tokens}")
    return "\n".join(lines) + "\n"


@lru_cache(maxsize=1)
def load_default_lexemes() -> LexemeTable:
    path = DATA_DIR / "facs" / "lexemes.txt"
    return parse_lexemes(path.read_text(encoding="utf-8"), source=str(path))


def _check_amount(amount: float) -> float:
    if not 0.0 <= amount <= 1.0:
        raise ConversionError(f"amount {amount} is outside 0..1")
    return amount


def lexeme_faps(
    lexeme: str,
    amount: float = 0.5,
    *,
    table: LexemeTable | None = None,
    mapping: FacsMapping | None = None,
) -> FapConfiguration:
    """FAP values of a BML ``faceLexeme`` at ``amount`` (BML 1.0 default 0.5)."""
    _check_amount(amount)
    aus = (table or load_default_lexemes()).action_units(lexeme)
    scaled = [AuActivation(a.au, a.side, a.intensity * amount) for a in aus]
    return (mapping or load_default_mapping()).configuration(scaled)


def facs_behaviour_faps(
    au: int,
    side: str | None = "BOTH",
    amount: float = 0.5,
    *,
    mapping: FacsMapping | None = None,
) -> FapConfiguration:
    """FAP values of ``<ext:faceFacs>`` / draft ``<face type="FACS">``: one AU,
    ``side`` LEFT, RIGHT or BOTH (also L/R), ``amount`` 0..1."""
    _check_amount(amount)
    key = (side or "BOTH").strip().upper()
    if key in BML_SIDES:
        mapped = BML_SIDES[key]
    elif key in ("L", "R"):
        mapped = key
    else:
        raise ConversionError(f"side must be LEFT, RIGHT or BOTH, not {side!r}")
    return (mapping or load_default_mapping()).configuration([AuActivation(au, mapped, amount)])
