"""Render every Action Unit of the default FACS mapping on the default face.

Writes ``docs/images/facs_aus.png``: one tile per AU of seed 000 Appendix A at
intensity 1 (both sides), labelled with its FACS name, the way seed 000
section 5.3 set FaceEditor screenshots beside the CMU photographs. Run from
the repository root:

    .venv/bin/python scripts/render_facs.py [--out docs/images] [--size 160]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image

# run from a checkout: the repository's package wins over an installed one
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from render_emotions import grid, label  # scripts/ is on sys.path when run as a script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    parser.add_argument("--size", type=int, default=160)
    parser.add_argument("--columns", type=int, default=8)
    args = parser.parse_args()

    from realizer.face.convert.facs import AuKey, facs_to_faps, load_default_mapping
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.engine import default_limits
    from realizer.face.render import FaceRenderer, Framing

    face = load_default_face()
    mapping = load_default_mapping()
    limits = default_limits()
    points = np.array([face.feature_position(name) for name in ("2.1", "4.5", "4.6", "4.1")])
    renderer = FaceRenderer(face, args.size, args.size, framing=Framing.of_points(points, 0.22))
    tiles = [label(Image.fromarray(renderer.render(None)), "neutral")]
    for au in mapping.action_units():
        configuration = facs_to_faps([str(au)], mapping)
        vector = limits.clamp(np.where(configuration.mask, configuration.values, 0.0))
        name = mapping.description(AuKey(au)) or mapping.description(AuKey(au, "L"))
        name = name.split(" (")[0]
        tiles.append(label(Image.fromarray(renderer.render(deform(face, vector))), f"{au} {name}"))
    renderer.close()
    rows = [tiles[i : i + args.columns] for i in range(0, len(tiles), args.columns)]
    args.out.mkdir(parents=True, exist_ok=True)
    grid(rows).save(args.out / "facs_aus.png")
    print(f"wrote {args.out / 'facs_aus.png'} ({len(tiles) - 1} AUs)")


if __name__ == "__main__":
    main()
