"""Start-up time of the command line: ``realizer --help`` against the bare interpreter.

Runs ``python -m realizer --help`` (and, for comparison, ``python -c pass``
and ``realizer parse --help``) as fresh processes, several times, and prints
the best and the median wall time. Goal: ``--help`` under 50 ms.
``realizer --help`` imports no command module (``realizer.cli.SUMMARIES``
lists them); what is left is the interpreter, ``site`` and ``argparse``.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure

ROOT = Path(__file__).resolve().parents[1]
GOAL_MS = 50.0


def wall(argv: list[str], runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(argv, cwd=ROOT, stdout=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - start)
    return times


def run(quick: bool = False) -> None:
    runs = 5 if quick else 15
    python = sys.executable
    for label, argv, goal in (
        ("python -c pass", [python, "-c", "pass"], None),
        ("realizer --help", [python, "-m", "realizer", "--help"], GOAL_MS),
        ("realizer parse --help", [python, "-m", "realizer", "parse", "--help"], None),
    ):
        times = wall(argv, runs)
        figure(
            f"{label}: best",
            min(times) * 1e3,
            "ms",
            goal=goal,
            note=f"median {statistics.median(times) * 1e3:.1f} ms of {runs} runs",
        )


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
