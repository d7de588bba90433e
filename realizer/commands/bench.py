"""``realizer bench [AREA...] [--quick]``: run the benchmark harness.

Benchmarks live in ``benchmarks/bench_<area>.py`` of a source checkout; each
defines ``run(quick: bool = False) -> None`` and prints its figures and
ratios. Timings are printed, never asserted.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path
from typing import Any


def benchmarks_dir() -> Path:
    """``benchmarks/`` beside the package (a source checkout or editable install)."""
    return Path(__file__).resolve().parents[2] / "benchmarks"


def available() -> dict[str, Path]:
    directory = benchmarks_dir()
    return {p.stem.removeprefix("bench_"): p for p in sorted(directory.glob("bench_*.py"))}


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("bench", help="run benchmarks and print figures and ratios")
    parser.add_argument("areas", nargs="*", metavar="AREA", help="which benchmarks (default: all)")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, fewer repeats")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    found = available()
    if not found:
        print(f"no benchmarks found in {benchmarks_dir()}", file=sys.stderr)
        return 2
    if args.list:
        print("\n".join(found))
        return 0
    unknown = [area for area in args.areas if area not in found]
    if unknown:
        print(
            f"unknown benchmark(s): {', '.join(unknown)}; have: {', '.join(found)}", file=sys.stderr
        )
        return 2
    for area in args.areas or list(found):
        spec = importlib.util.spec_from_file_location(f"bench_{area}", found[area])
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        print(f"== {area}")
        module.run(quick=args.quick)
    return 0
