"""Render the default face's lower-face fixes before and after, one sheet.

Writes ``docs/images/lower_face_before_after.png``: a row for an earlier
face file (``--before``, e.g. the shipped files of an older commit, written
out with ``git show``) and a row for the face in this checkout, each tile a
pose of the jaw, chin, cheeks, nose wings or lips close up (profile views
for motion along the depth axis), with the same renderer. Run from the
repository root:

    git show 28acb96:realizer/face/data/default_face/default_face.npz > /tmp/old/default_face.npz
    git show 28acb96:realizer/face/data/default_face/default_face.xml > /tmp/old/default_face.xml
    .venv/bin/python scripts/render_lower_face.py --before /tmp/old/default_face

``--set mouth`` draws the mouth's fixes instead (the tongue, the lips pushed
out and their outer middles, the chin, the nostril wings) into
``docs/images/mouth_before_after.png``, side views framed on the lips;
``--set eyes`` the lids' and brows' (the upper lid widened, the lower lid
raised, the outer brow lowered and the brows squeezed, front and side
close-ups of the left eye) into ``docs/images/eyes_before_after.png``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

# run from a checkout: the repository's package wins over an installed one
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: label, close-up region (realizer fap-sheet's), view, FAP values
POSES: tuple[tuple[str, str, str, dict[int, float]], ...] = (
    ("open_jaw 512 (side)", "mouth", "left", {3: 512}),
    ("shift_jaw 128 (side)", "mouth", "left", {15: 128}),
    ("depress_chin -512", "mouth", "left", {18: -512}),
    ("puff cheeks 96 (side)", "cheeks", "left", {39: 96, 40: 96}),
    ("stretch nose 96", "cheeks", "front", {61: 96, 62: 96}),
    ("raise_b_lip_lm 800", "mouth", "front", {10: 800}),
    ("lower_t_lip_lm -800", "mouth", "front", {8: -800}),
)


#: the mouth's fixes (``--set mouth``): the tongue with the jaw open 900 as on
#: the FAP sheet, the rest at the sheet's values
MOUTH_POSES: tuple[tuple[str, str, str, dict[int, float]], ...] = (
    ("tongue tip up 512", "mouth", "front", {3: 900, 44: 512}),
    ("tongue down -512", "mouth", "front", {3: 900, 46: -512}),
    ("push_b_lip 512 (side)", "mouth", "left", {16: 512}),
    ("push_t_lip 512 (side)", "mouth", "left", {17: 512}),
    ("depress_chin -512", "mouth", "front", {18: -512}),
    ("raise_b_midlip_o -512", "mouth", "front", {52: -512}),
    ("stretch_l_nose 96", "nose", "front", {61: 96}),
)


#: the lids' and brows' fixes (``--set eyes``): close-ups of the left eye,
#: front and from the left, at the sheet's values
EYE_POSES: tuple[tuple[str, str, str, dict[int, float]], ...] = (
    ("close_t_l -512", "left eye", "front", {19: -512}),
    ("close_t_l -512 (side)", "left eye", "left", {19: -512}),
    ("close_b_l 512", "left eye", "front", {21: 512}),
    ("close_b_l 512 (side)", "left eye", "left", {21: 512}),
    ("raise_l_o_brow -128 (side)", "left eye", "left", {35: -128}),
    ("squeeze_l_brow 96 (side)", "left eye", "left", {37: 96}),
)


def main() -> None:
    from realizer.commands.fap_sheet import region_framing
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.paramfile import load_face
    from realizer.face.render import FaceRenderer, Framing

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="the earlier face file (STEM)")
    parser.add_argument("--out", type=Path, help="default: docs/images/SET_before_after.png")
    parser.add_argument("--tile", type=int, default=200)
    parser.add_argument("--set", choices=("lower_face", "mouth", "eyes"), default="lower_face")
    args = parser.parse_args()
    poses = {"mouth": MOUTH_POSES, "eyes": EYE_POSES}.get(args.set, POSES)
    out = args.out or Path(f"docs/images/{args.set}_before_after.png")
    faces = {"before": load_face(args.before), "after": load_default_face()}
    tile, label_width, header = args.tile, 56, 18
    sheet = Image.new("RGB", (label_width + tile * len(poses), header + 2 * tile), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for column, (label, *_) in enumerate(poses):
        draw.text((label_width + column * tile + 4, 3), label, fill=(230, 230, 230))
    for row, (name, face) in enumerate(faces.items()):
        draw.text((4, header + row * tile + tile // 2), name, fill=(230, 230, 230))
        renderers: dict[str, FaceRenderer] = {}
        try:
            for column, (_, region, view, values) in enumerate(poses):
                key = f"{region} {view}"
                if key not in renderers:
                    framing = region_framing(face, region)
                    if args.set == "mouth":
                        # closer, and side views centred on the lips
                        height = framing.height / (2.6 if region == "nose" else 1.8)
                        x, y, z = framing.centre
                        z += 0.45 * height if view != "front" else 0.0
                        framing = Framing((x, y, z), height)
                    renderers[key] = FaceRenderer(face, tile, tile, framing=framing)
                vector = np.zeros(68)
                for fap, value in values.items():
                    vector[fap - 1] = value
                image = renderers[key].render(deform(face, vector), view=view)
                corner = (label_width + column * tile, header + row * tile)
                sheet.paste(Image.fromarray(image), corner)
        finally:
            for renderer in renderers.values():
                renderer.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
