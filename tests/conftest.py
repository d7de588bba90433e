"""Shared test helpers: where the conformance corpus and the examples are."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Idle motion (blinks, saccades, breathing) is on by default in `realizer
# serve` and `render`; tests see still faces unless they ask for it, and the
# commands they start inherit this.
os.environ.setdefault("REALIZER_IDLE", "0")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "bml"
# CI has shared/ beside the checkout; a developer's worktree may sit elsewhere.
_CANDIDATES = [
    ROOT.parent / "shared" / "conformance" / "openbmlparser-bmltest",
    Path("/work/shared/conformance/openbmlparser-bmltest"),
]
CONFORMANCE = next((p for p in _CANDIDATES if p.is_dir()), _CANDIDATES[0])


def conformance_files() -> list[Path]:
    if not CONFORMANCE.is_dir():
        return []
    return sorted(CONFORMANCE.glob("*.xml"))


@pytest.fixture
def conformance_dir() -> Path:
    if not CONFORMANCE.is_dir():
        pytest.skip(f"conformance corpus not found at {CONFORMANCE}")
    return CONFORMANCE
