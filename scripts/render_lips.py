"""Render the default face's lips seen from the front before and after, one sheet.

Writes ``docs/images/lips_before_after.png``: a row for an earlier face file
(``--before``, e.g. the shipped files of an older commit, written out with
``git show``) and a row for the face in this checkout, each tile a close-up
of the mouth under one of the lip FAPs at the value ``realizer fap-sheet``
shows (the lips between middle and corner, 8..11 and 55..58, and the raised
corners, 12 and 59), with the same renderer. Run from the repository root:

    git show 5367c32:realizer/face/data/default_face/default_face.npz > /tmp/old/default_face.npz
    git show 5367c32:realizer/face/data/default_face/default_face.xml > /tmp/old/default_face.xml
    .venv/bin/python scripts/render_lips.py --before /tmp/old/default_face
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

# run from a checkout: the repository's package wins over an installed one
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: label, FAP values
POSES: tuple[tuple[str, dict[int, float]], ...] = (
    ("neutral", {}),
    ("10 -512", {10: -512}),
    ("57 -512", {57: -512}),
    ("8 512", {8: 512}),
    ("55 -512", {55: -512}),
    ("12 512", {12: 512}),
    ("59 512", {59: 512}),
)
#: the close-up: the height (metres) the camera shows round the lips
HEIGHT_M = 0.058


def main() -> None:
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.paramfile import load_face
    from realizer.face.render import FaceRenderer, Framing

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="the earlier face file (STEM)")
    parser.add_argument("--out", type=Path, default=Path("docs/images/lips_before_after.png"))
    parser.add_argument("--tile", type=int, default=220)
    args = parser.parse_args()
    faces = {"before": load_face(args.before), "after": load_default_face()}
    width, height = args.tile, args.tile * 5 // 8
    label_width, header = 48, 16
    sheet = Image.new("RGB", (label_width + width * len(POSES), header + 2 * height), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for column, (label, _) in enumerate(POSES):
        draw.text((label_width + column * width + 4, 2), label, fill=(230, 230, 230))
    for row, (name, face) in enumerate(faces.items()):
        draw.text((4, header + row * height + height // 2), name, fill=(230, 230, 230))
        top, bottom = face.feature_position("8.1"), face.feature_position("8.2")
        centre = (0.0, float(top[1] + bottom[1]) / 2, float(top[2]))
        renderer = FaceRenderer(face, width, height, framing=Framing(centre, HEIGHT_M))
        try:
            for column, (_, values) in enumerate(POSES):
                vector = np.zeros(68)
                for fap, value in values.items():
                    vector[fap - 1] = value
                image = renderer.render(deform(face, vector))
                sheet.paste(
                    Image.fromarray(image), (label_width + column * width, header + row * height)
                )
        finally:
            renderer.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
