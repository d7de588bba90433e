"""Render every Action Unit, viseme and expression of the converters on the default face.

Writes ``docs/images/facs_aus.png``: one tile per AU of Paul 2010, Appendix A at
intensity 1 (both sides), labelled with its FACS name, the way Paul 2010
section 5.3 set FaceEditor screenshots beside the CMU photographs; and
``docs/images/visemes_expressions.png``: the 15 visemes of FAP 1 and the six
expressions of FAP 2 at intensity 63 (Tekalp and Ostermann 2000, Tables 3 and 4). Run from the
repository root:

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

from render_emotions import grid, label, save  # scripts/ is on sys.path when run as a script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    parser.add_argument("--size", type=int, default=160)
    parser.add_argument("--columns", type=int, default=8)
    args = parser.parse_args()

    from realizer.engines.face import default_limits
    from realizer.face.convert.facs import AuKey, facs_to_faps, load_default_mapping
    from realizer.face.convert.visemes import (
        expression_faps,
        load_default_expressions,
        load_default_visemes,
        viseme_faps,
    )
    from realizer.face.default import load_default_face
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, Framing

    face = load_default_face()
    mapping = load_default_mapping()
    limits = default_limits()
    points = np.array([face.feature_position(name) for name in ("2.1", "4.5", "4.6", "4.1")])
    renderer = FaceRenderer(face, args.size, args.size, framing=Framing.of_points(points, 0.22))

    def render(configuration) -> Image.Image:  # type: ignore[no-untyped-def]
        vector = limits.clamp(np.where(configuration.mask, configuration.values, 0.0))
        return Image.fromarray(renderer.render(deform(face, vector)))

    neutral = label(Image.fromarray(renderer.render(None)), "neutral")
    tiles = [neutral]
    for au in mapping.action_units():
        name = mapping.description(AuKey(au)) or mapping.description(AuKey(au, "L"))
        tiles.append(label(render(facs_to_faps([str(au)], mapping)), f"{au} {name.split(' (')[0]}"))
    args.out.mkdir(parents=True, exist_ok=True)
    save(grid(rows_of(tiles, args.columns)), args.out / "facs_aus.png")

    visemes = [
        label(render(viseme_faps(shape.number)), f"viseme {shape.number} {shape.label[0]}")
        for shape in load_default_visemes().shapes
    ]
    expressions = [
        label(render(expression_faps(shape.number, 63)), f"expr. {shape.number} {shape.label[0]}")
        for shape in load_default_expressions().shapes
    ]
    renderer.close()
    sheet = rows_of(visemes, args.columns) + rows_of([neutral, *expressions], args.columns)
    save(grid(sheet), args.out / "visemes_expressions.png")
    print(f"wrote facs_aus.png ({len(tiles) - 1} AUs) and visemes_expressions.png: {args.out}")


def rows_of(tiles: list[Image.Image], columns: int) -> list[list[Image.Image]]:
    return [tiles[i : i + columns] for i in range(0, len(tiles), columns)]


if __name__ == "__main__":
    main()
