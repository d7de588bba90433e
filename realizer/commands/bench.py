"""``realizer bench [AREA...] [--quick] [--json FILE]``: run the benchmark harness.

Benchmarks live in ``benchmarks/bench_<area>.py`` (in the wheel too); each
defines ``run(quick: bool = False) -> None`` and prints its figures and
ratios, recording its headline figures through ``benchmarks/_timing.py``'s
``figure`` so that ``--json FILE`` can write them for a machine to compare
(format in ``benchmarks/README.md``). Options an area's ``run`` takes as
keyword arguments (``port``, ``viewers``, ``planner_processes`` for the service) are passed to the
areas that take them. Timings are printed, never asserted.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import inspect
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any


def benchmarks_dir() -> Path:
    """Where the benchmarks are: inside an installed wheel, or in a source checkout.

    The wheel carries ``benchmarks/`` as ``realizer/benchmarks/``; a source
    checkout (or an editable install) has it beside the package.
    """
    package = Path(__file__).resolve().parents[1]
    installed = package / "benchmarks"
    return installed if installed.is_dir() else package.parent / "benchmarks"


def available() -> dict[str, Path]:
    directory = benchmarks_dir()
    return {p.stem.removeprefix("bench_"): p for p in sorted(directory.glob("bench_*.py"))}


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("bench", help="run benchmarks and print figures and ratios")
    parser.add_argument("areas", nargs="*", metavar="AREA", help="which benchmarks (default: all)")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, fewer repeats")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    parser.add_argument(
        "--json", metavar="FILE", type=Path, help="also write every area's figures to FILE as JSON"
    )
    parser.add_argument(
        "--port",
        type=int,
        help="service: measure the server already listening on this loopback port "
        "instead of starting one",
    )
    parser.add_argument(
        "--viewers",
        choices=("all", "fap", "int16", "float32"),
        help="service: which viewer format to load the server with (default: fap, then int16)",
    )
    parser.add_argument(
        "--planner-processes",
        type=int,
        metavar="N",
        help="service: start the server with --planner-processes N (0: planner threads)",
    )
    parser.set_defaults(run=run)


def _machine() -> dict[str, Any]:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "loadavg": list(load),
    }


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
    # The benchmarks import their helper as the top-level module `_timing`;
    # import the same module object here to collect what they record.
    sys.path.insert(0, str(benchmarks_dir()))
    timing = importlib.import_module("_timing")
    extras = {
        "port": args.port,
        "viewers": args.viewers,
        "planner_processes": args.planner_processes,
    }
    report: dict[str, Any] = {
        "format": "realizer-bench/1",
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "quick": bool(args.quick),
        "machine": _machine(),
        "areas": {},
    }
    for area in args.areas or list(found):
        spec = importlib.util.spec_from_file_location(f"bench_{area}", found[area])
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        print(f"== {area}", flush=True)
        accepted = inspect.signature(module.run).parameters
        kwargs = {k: v for k, v in extras.items() if v is not None and k in accepted}
        timing.take_figures()
        began = time.perf_counter()
        module.run(quick=args.quick, **kwargs)
        figures, skips = timing.take_figures()
        report["areas"][area] = {
            "seconds": round(time.perf_counter() - began, 3),
            "options": kwargs,
            "figures": figures,
            "skipped": skips,
        }
        sys.stdout.flush()
    if args.json is not None:
        report["machine"]["loadavg_after"] = list(os.getloadavg())
        args.json.write_text(json.dumps(report, indent=1, allow_nan=False) + "\n")
        print(f"wrote {args.json}")
    return 0
