"""Benchmark: face converters, the mixer and .fap writing (realizer.face.convert, tracks).

Prints how long one conversion or one mixed frame takes, and how many frames
a second the mixer sustains against a 25 fps stream. Timings are printed,
never asserted.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure


def _per_call(function: Callable[[], object], repeats: int) -> float:
    function()  # warm caches (data files are read once)
    begin = time.perf_counter()
    for _ in range(repeats):
        function()
    return (time.perf_counter() - begin) / repeats


def run(quick: bool = False) -> None:
    from realizer.face.convert.emotion import load_default_converter
    from realizer.face.convert.facs import facs_to_faps
    from realizer.face.convert.lexemes import lexeme_faps
    from realizer.face.fapfile import FapFile, format_fap_file
    from realizer.face.tracks import Envelope, FapAnimation, mix, sample

    repeats = 200 if quick else 2000
    converter = load_default_converter()
    figures = {
        "facs 1 2 12L:0.8": _per_call(lambda: facs_to_faps(["1", "2", "12L:0.8"]), repeats),
        "faceLexeme RAISE_BROWS": _per_call(lambda: lexeme_faps("RAISE_BROWS", 0.7), repeats),
        "emotion word guilty": _per_call(lambda: converter.for_word("guilty"), repeats),
        "emotion wheel point": _per_call(lambda: converter.for_point(261.0, 3.8), repeats),
    }
    for name, seconds in figures.items():
        figure(name, seconds * 1e6, "us per call")

    for count in (4, 16, 64):
        animations = [
            FapAnimation(
                lexeme_faps("RAISE_MOUTH_CORNERS", 0.5), Envelope(i * 0.02, i * 0.02 + 0.3, 5, 6)
            )
            for i in range(count)
        ]
        per_frame = _per_call(lambda a=animations: mix(a, 2.0), repeats // 4)
        figure(
            f"mix {count} animations",
            per_frame * 1e6,
            "us per frame",
            note=f"{1 / per_frame / 25:,.0f}x a 25 fps stream",
        )

    frames = 250 if quick else 2500
    animations = [FapAnimation(lexeme_faps("RAISE_BROWS", 1.0), Envelope(0, 1, 8, 10))]
    begin = time.perf_counter()
    values, mask = sample(animations, np.arange(frames) / 25.0)
    sampled = time.perf_counter() - begin
    begin = time.perf_counter()
    text = format_fap_file(FapFile("bench", 25, values, mask))
    written = time.perf_counter() - begin
    print(
        f"sample {frames} frames          {sampled * 1e3:9.1f} ms; "
        f".fap text {written * 1e3:.1f} ms ({len(text) / 1e6:.2f} MB)"
    )
