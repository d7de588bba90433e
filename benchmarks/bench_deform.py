"""Deformation speed: frames per second of ``deform`` next to a plain vertex copy.

Goal: a frame within 3x the time of merely copying the vertex
buffer. Heads: the default face when ``realizer.face.default`` exists, the
procedural test head, and the test head subdivided twice (> 100,000
vertices). Frames: a typical talking frame (jaw, lips, brows, lids, gaze,
head), every FAP 3..68 at once, and the neutral frame. Prints figures; asserts
nothing about time.
"""

from __future__ import annotations

import importlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from realizer.face.deform import deform, rig_for
from realizer.face.model import Face
from realizer.face.testhead import build_test_head, subdivide_face

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure


def _default_face() -> Face | None:
    try:
        module = importlib.import_module("realizer.face.default")
    except ImportError:
        return None
    loader = getattr(module, "load_default_face", None)
    return loader() if callable(loader) else None


def _frames() -> dict[str, np.ndarray]:
    talking = np.zeros(68)
    for number, value in {
        3: 250,
        4: 60,
        5: -80,
        51: 50,
        52: -90,
        53: 120,
        54: 120,
        59: 60,
        60: 60,
        12: 40,
        13: 40,
        31: 150,
        32: 150,
        33: 120,
        34: 120,
        19: 200,
        20: 200,
        23: 3000,
        24: 3000,
        25: -1500,
        26: -1500,
        48: 2000,
        49: -3000,
        50: 800,
    }.items():
        talking[number - 1] = value
    every = np.zeros(68)
    every[2:] = 100.0
    return {"talking": talking, "all FAPs": every, "neutral": np.zeros(68)}


def _seconds_per_call(call: Callable[[], object], budget_s: float) -> float:
    """Best (smallest) time of one call over repeats filling ``budget_s``.

    The best, not the mean: on a shared machine the mean measures the other
    processes (means of the same product varied 0.2-47 ms between runs).
    """
    call()  # warm up
    best, start = float("inf"), time.perf_counter()
    count = 0
    while count < 5 or time.perf_counter() - start < budget_s:
        begin = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - begin)
        count += 1
    return best


def run(quick: bool = False) -> None:
    budget = 0.2 if quick else 1.0
    heads: list[Face] = []
    default = _default_face()
    if default is not None:
        heads.append(default)
    test_head = build_test_head()
    heads.append(test_head)
    start = time.perf_counter()
    heads.append(subdivide_face(test_head, 2))
    print(f"subdivided the test head in {time.perf_counter() - start:.2f} s")
    frames = _frames()
    print(
        "best of repeats; deform = full result; "
        "posed = deform_posed (vertices + 4x4 head pose for the GPU)"
    )
    print(
        f"{'head':<22}{'vertices':>10}{'frame':>11}{'fps':>9}{'ms':>8}{'x copy':>8}"
        f"{'posed ms':>10}{'x copy':>8}{'copy ms':>9}"
    )
    for face in heads:
        start = time.perf_counter()
        rig_for(face)
        build = time.perf_counter() - start
        copy_s = _seconds_per_call(face.vertices.copy, budget)
        rig = rig_for(face)
        for name, vector in frames.items():
            per_frame = _seconds_per_call(lambda v=vector, f=face: deform(f, v), budget)
            posed = _seconds_per_call(lambda v=vector, r=rig: r.deform_posed(v), budget)
            print(
                f"{face.name:<22}{face.vertex_count:>10}{name:>11}{1 / per_frame:>9.0f}"
                f"{per_frame * 1e3:>8.3f}{per_frame / copy_s:>8.1f}"
                f"{posed * 1e3:>10.3f}{posed / copy_s:>8.1f}{copy_s * 1e3:>9.3f}"
            )
            figure(
                f"{face.name} ({face.vertex_count} vertices), {name}: deform / vertex copy",
                per_frame / copy_s,
                "x",
                goal=3.0,
                quiet=True,
            )
        print(f"{'':<22}rig built in {build * 1e3:.0f} ms")


if __name__ == "__main__":
    run()
