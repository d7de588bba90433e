"""The tiny path compiled (mypyc, ``realizer.compiled``) and from its source.

``realizer.scheduler.tiny`` is on :data:`realizer.compiled.MODULES`: where
``scripts/build_compiled.py`` built it, the solver calls the extension, and
the rest of the suite tests that. Here: the extension and the source give
the same times (or both decline) on the random problems of
``test_solver_paths``, and the tests that compare the solver's paths pass
against the source too (``REALIZER_PURE=1``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from realizer import compiled
from realizer.scheduler import solver, tiny
from tests.scheduler.test_solver_paths import pinned_problem, random_problem

ROOT = Path(__file__).resolve().parents[2]
SEEDS = range(120)


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != compiled.PURE_ENV}
    env.update(extra)
    return env


def _times(seeds: range) -> list[list[float] | None]:
    makers = (random_problem, pinned_problem)
    return [solver._tiny_times(make(seed)) for seed in seeds for make in makers]


def test_the_compiled_and_the_source_tiny_path_give_the_same_times() -> None:
    here = _times(SEEDS)
    script = (
        "import json, sys\n"
        "from realizer import compiled\n"
        "assert compiled.mode() == 'pure', compiled.describe()\n"
        "from tests.scheduler.test_compiled_tiny import SEEDS, _times\n"
        "print(json.dumps(_times(SEEDS)))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        cwd=ROOT,
        env=_env(**{compiled.PURE_ENV: "1"}, PYTHONPATH=str(ROOT)),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    there = json.loads(done.stdout)
    assert len(there) == len(here)
    taken = 0
    for ours, theirs in zip(here, there, strict=True):
        assert (ours is None) == (theirs is None)
        if ours is not None:
            taken += 1
            assert ours == pytest.approx(theirs, abs=1e-12)
    assert taken > 30  # 55 of the 240 are solved here (the others conflict or go to numpy)


@pytest.mark.slow
def test_the_path_comparisons_pass_against_the_source() -> None:
    """test_solver_paths and test_fast_paths once more with every module from
    its source (the rest of the suite ran against what this process loaded)."""
    if not str(getattr(tiny, "__file__", "")).endswith((".so", ".pyd")):
        pytest.skip("this run is already against the source of the tiny path")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:randomly",
         "tests/scheduler/test_solver_paths.py", "tests/scheduler/test_fast_paths.py"],
        cwd=ROOT,
        env=_env(**{compiled.PURE_ENV: "1"}),
        capture_output=True,
        text=True,
        timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert " passed" in done.stdout
