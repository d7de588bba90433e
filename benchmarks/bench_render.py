"""Benchmark: offscreen rendering of the default face (realizer.face.render).

Prints images per second for the neutral face and for a deformed face (a new
vertex buffer each frame, as an animation needs), at the sizes a viewer or a
contact sheet uses, with the platform PyOpenGL runs on, and the share of a
frame that deformation takes. Timings are printed, never asserted.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import best_of


def run(quick: bool = False) -> None:
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, RenderUnavailableError, choose_platform

    face = load_default_face()
    platform = choose_platform()
    values = np.zeros(68)
    values[[2, 30, 31, 52, 53]] = (400, 150, 150, 100, 100)
    deformed = deform(face, values)
    repeats = 2 if quick else 5
    number = 3 if quick else 10
    print(
        f"render: default face, {face.vertex_count} vertices, {len(face.faces)} triangles, "
        f"PYOPENGL_PLATFORM={platform}"
    )
    deform_s = best_of(lambda: deform(face, values), repeats=repeats, number=number * 10)
    for size in (128, 256) if quick else (128, 256, 512):
        try:
            renderer = FaceRenderer(face, size, size)
        except RenderUnavailableError as error:
            print(f"  no OpenGL context: {error}")
            return
        with renderer:
            renderer.render()  # first frame compiles shaders
            neutral = best_of(renderer.render, repeats=repeats, number=number)
            animated = best_of(
                lambda r=renderer: r.render(deform(face, values)), repeats=repeats, number=number
            )
            same = best_of(lambda r=renderer: r.render(deformed), repeats=repeats, number=number)
        print(
            f"  {size}x{size} (2x supersampled): neutral {1 / neutral:7.1f} images/s, "
            f"deformed {1 / same:7.1f} images/s, deform+render {1 / animated:7.1f} frames/s; "
            f"deformation is {deform_s / animated:.1%} of a frame"
        )
    print(f"  cpu count {os.cpu_count()}")
