"""The product cites its sources by title and names nothing outside the repository.

Users have the repository, not the notes it was built from: no "seed 000"
style references, no internal issue numbers, no ARCHITECTURE.md decision
numbers and no paths of the machine it was written on. docs/references.md
lists the sources by title.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ["realizer", "docs", "protocols", "examples", "benchmarks", "scripts", "docker"]
TOP_LEVEL = ["README.md", "CHANGELOG.md", "pyproject.toml"]
BINARY = {".png", ".jpg", ".npz", ".glb", ".wav", ".mp4", ".ico", ".pyc", ".so"}

FORBIDDEN = {
    "a seed number": re.compile(r"\bseeds?[\s_:/]*0\d\d", re.IGNORECASE),
    "the notes' ARCHITECTURE.md": re.compile(r"ARCHITECTURE\.md"),
    # docs/architecture.md's decisions have names, not numbers
    "a decision number": re.compile(r"\bdecision\s+\d|\barchitecture decision\b", re.I),
    "an issue number": re.compile(r"\bissues?\s*#?\s*\d+\b", re.IGNORECASE),
    "a path outside the repository": re.compile(
        r"/work/(?:shared|main|wt)\b|(?:\.\./)+shared\b|/home/\w+|/root/"
    ),
}


def product_files() -> list[Path]:
    files = [ROOT / name for name in TOP_LEVEL if (ROOT / name).is_file()]
    for folder in PRODUCT:
        for path in sorted((ROOT / folder).rglob("*")):
            if not path.is_file() or path.suffix.lower() in BINARY:
                continue
            if any(part in {"__pycache__", "node_modules", ".cache"} for part in path.parts):
                continue
            files.append(path)
    return files


def test_the_product_has_text_files_to_check() -> None:
    names = {p.relative_to(ROOT).as_posix() for p in product_files()}
    assert "README.md" in names
    assert "realizer/session.py" in names
    assert "docs/references.md" in names


@pytest.mark.parametrize("what", sorted(FORBIDDEN))
def test_the_product_never_mentions(what: str) -> None:
    pattern = FORBIDDEN[what]
    hits = []
    for path in product_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not hits, f"{what} in the product:\n" + "\n".join(hits)


def test_the_patterns_catch_what_they_are_for() -> None:
    assert FORBIDDEN["a seed number"].search("as seed 000 section 4.3 says")
    assert FORBIDDEN["a seed number"].search("Seeds: 002 (Tekalp)")
    assert FORBIDDEN["an issue number"].search("the goal of issue 4")
    assert FORBIDDEN["a path outside the repository"].search("/work/shared/conformance")
    assert not FORBIDDEN["an issue number"].search("issues are welcome")


def test_the_references_page_names_every_source_by_title() -> None:
    text = " ".join((ROOT / "docs" / "references.md").read_text(encoding="utf-8").split())
    for title in (
        "Realization and high level specification of facial expressions for embodied agents",
        "Parameterized Facial Expression Synthesis Based on MPEG-4",
        "Face and 2-D mesh animation in MPEG-4",
        "Behavior Markup Language (BML) Version 1.0",
    ):
        assert title in text
