"""Benchmark: offscreen rendering of the default face (realizer.face.render).

Prints frames per second of ``realizer render``'s loop (deform + render +
read back) at 640x480, its ratio to the 30 frames/s goal, and the same for a
still face and other sizes, with the platform PyOpenGL runs on, the OpenGL
multisampling, the CPU time per frame (all threads of the process, so a busy
machine's waiting does not count) and the share of a frame that deformation
takes. Timings are printed, never asserted.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import best_of

#: ``realizer render`` must keep up with 30 frames/s at 640x480 on the CPU.
GOAL_FPS = 30.0


def _cpu_per_call(function: object, number: int) -> float:
    start = time.process_time()
    for _ in range(number):
        function()  # type: ignore[operator]
    return (time.process_time() - start) / number


def run(quick: bool = False) -> None:
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, RenderUnavailableError, choose_platform

    face = load_default_face()
    platform = choose_platform()
    values = np.zeros(68)
    values[[2, 18, 19, 30, 31, 52, 53]] = (400, 300, 300, 150, 150, 100, 100)
    repeats = 2 if quick else 5
    number = 5 if quick else 20
    print(
        f"render: default face, {face.vertex_count} vertices, {len(face.faces)} triangles, "
        f"PYOPENGL_PLATFORM={platform}, load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cpus"
    )
    deform_s = best_of(lambda: deform(face, values), repeats=repeats, number=number * 10)
    sizes = ((640, 480), (256, 256)) if quick else ((640, 480), (512, 512), (256, 256))
    for width, height in sizes:
        try:
            renderer = FaceRenderer(face, width, height)
        except RenderUnavailableError as error:
            print(f"  no OpenGL context: {error}")
            return
        with renderer:
            renderer.render()  # the first frame compiles the shaders

            def frame(r: FaceRenderer = renderer) -> None:
                values[2] = 400 - values[2]  # a new pose every frame
                r.render(deform(face, values))

            neutral = best_of(renderer.render, repeats=repeats, number=number)
            animated = best_of(frame, repeats=repeats, number=number)
            cpu = _cpu_per_call(frame, number)
        fps = 1 / animated
        print(
            f"  {width}x{height} ({renderer.samples}x MSAA): deform+render {fps:6.1f} frames/s "
            f"= {fps / GOAL_FPS:.2f}x the {GOAL_FPS:g} fps goal; still face "
            f"{1 / neutral:6.1f} images/s; {cpu * 1e3:.1f} ms CPU per frame; "
            f"deformation is {deform_s / animated:.1%} of a frame"
        )
