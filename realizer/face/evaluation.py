"""The thesis's evaluation of a face: scores of every FAP displacement.

"Realization and high level specification of facial expressions for
embodied agents", section 4.4 scores each of the 127 displacements of FAPs
3..68 (each direction of a bidirectional FAP on its own; 3, 14, 41, 42 and
47 are unidirectional) by eye: 3 = looks as it should, 2 = right at first
sight but slightly odd, 1 = one can tell which FAP it was. Each FAP has a
weight 1..3 for its importance (its Table 4.3), and a face's figure is the
weighted mean of its scores (its Table 4.5: FaceEditor 2.88, Greta 2.55,
Miraface 2.17, Xface 1.97).

The scores of the default face live in ``data/evaluation.csv`` (one row per
displacement: FAP, direction, weight, score, what was seen, date and the
commit judged). This module reads them, checks that they cover every
displacement once, and computes the figure; ``realizer fap-audit --scores``
prints it. The scoring itself is done by eye; nothing here judges looks.
"""

from __future__ import annotations

import csv
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import resources
from typing import Literal

from realizer.face.faps import FAP_TABLE

__all__ = [
    "Score",
    "displacements",
    "format_scores",
    "load_scores",
    "parse_scores",
    "weighted_score",
]

Direction = Literal["+", "-"]


@dataclass(frozen=True, slots=True)
class Score:
    """One scored displacement: FAP ``fap`` moved in ``direction``."""

    fap: int
    direction: Direction
    weight: int  # 1..3, Table 4.3
    score: int  # 1..3, section 4.4.3
    remark: str
    date: str
    commit: str


def displacements() -> list[tuple[int, Direction]]:
    """The 127 displacements of section 4.4.2: FAPs 3..68, both directions of
    a bidirectional FAP, the positive one of a unidirectional FAP."""
    out: list[tuple[int, Direction]] = []
    for fap in range(3, 69):
        if not FAP_TABLE[fap].unidirectional:
            out.append((fap, "-"))
        out.append((fap, "+"))
    return out


def parse_scores(text: str) -> list[Score]:
    """Rows of an evaluation CSV (``#`` lines are comments). Raises
    ValueError for a malformed row, a score or weight outside 1..3, a FAP
    scored twice in one direction, a direction a unidirectional FAP does
    not have, or a missing displacement."""
    lines = (line for line in text.splitlines() if line and not line.startswith("#"))
    rows: list[Score] = []
    for number, row in enumerate(csv.DictReader(lines), start=1):
        try:
            fap = int(row["fap"])
            direction = row["direction"]
            weight = int(row["weight"])
            score = int(row["score"])
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"evaluation row {number}: {error}") from error
        if direction not in ("+", "-"):
            raise ValueError(f"evaluation row {number}: direction {direction!r} is not + or -")
        if not (1 <= weight <= 3 and 1 <= score <= 3):
            raise ValueError(f"evaluation row {number}: weight and score must be 1..3")
        rows.append(
            Score(fap, direction, weight, score, row["remark"], row["date"], row["commit"])  # type: ignore[arg-type]
        )
    seen = Counter((r.fap, r.direction) for r in rows)
    twice = sorted(k for k, n in seen.items() if n > 1)
    wanted = set(displacements())
    extra = sorted(set(seen) - wanted)
    missing = sorted(wanted - set(seen))
    if twice or extra or missing:
        raise ValueError(
            f"the evaluation must score each of the {len(wanted)} displacements once: "
            f"twice {twice}, not a displacement {extra}, missing {missing}"
        )
    weights: dict[int, int] = {}
    for r in rows:
        if weights.setdefault(r.fap, r.weight) != r.weight:
            raise ValueError(f"FAP {r.fap} has two weights")
    return sorted(rows, key=lambda r: (r.fap, r.direction == "+"))


def load_scores() -> list[Score]:
    """The default face's scores, ``data/evaluation.csv``."""
    text = resources.files("realizer.face").joinpath("data/evaluation.csv").read_text("utf-8")
    return parse_scores(text)


def weighted_score(rows: Iterable[Score]) -> float:
    """Section 4.4.3's figure: sum(weight x score) / sum(weight)."""
    rows = list(rows)
    total = sum(r.weight for r in rows)
    if not total:
        raise ValueError("no scores")
    return sum(r.weight * r.score for r in rows) / total


#: Regions for the summary, by FAP range (Tekalp and Ostermann's groups).
REGIONS: tuple[tuple[str, range], ...] = (
    ("jaw, lips", range(3, 19)),
    ("eyelids", range(19, 23)),
    ("eyeballs", range(23, 31)),
    ("eyebrows", range(31, 39)),
    ("cheeks", range(39, 43)),
    ("tongue", range(43, 48)),
    ("head", range(48, 51)),
    ("outer lips", range(51, 61)),
    ("nose", range(61, 65)),
    ("ears", range(65, 69)),
)


def format_scores(rows: list[Score], *, every: bool = False) -> str:
    """A summary: the figure, counts of each score, the figure per region,
    and (``every``) one line per displacement that is not a 3."""
    counts = Counter(r.score for r in rows)
    lines = [
        f"{'region':<12} {'n':>3} {'score':>6}",
    ]
    for name, faps in REGIONS:
        part = [r for r in rows if r.fap in faps]
        if part:
            lines.append(f"{name:<12} {len(part):>3} {weighted_score(part):>6.2f}")
    if every:
        lines.append("")
        for r in rows:
            if r.score < 3:
                lines.append(f"{r.fap:>2}{r.direction} w{r.weight} score {r.score}: {r.remark}")
    judged = sorted({(r.date, r.commit) for r in rows})
    lines += [
        "",
        f"judged {', '.join(f'{d} on {c}' for d, c in judged)}",
        f"{len(rows)} displacements: {counts[3]} score 3, {counts[2]} score 2, "
        f"{counts[1]} score 1; weighted score {weighted_score(rows):.2f}",
    ]
    return "\n".join(lines)
