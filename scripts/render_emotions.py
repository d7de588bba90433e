"""Render the emotion converter on the default face: docs/images/emotions_*.png.

Two strips (Paul 2010, section 6.4):

- ``emotions_archetypes.png``: the six archetypal emotions, each at its own
  activation with its default profile (realizer/face/data/emotion/wheels.txt),
  in the order of Paul 2010, figure 6.9: joy, sadness, anger, fear, disgust,
  surprise;
- ``emotions_profiles.png``: every archetypal profile of Raouzaiou et al. 2002, Table 5
  at its archetype's activation (one row per archetype), from which the
  default profiles were chosen by eye as Paul 2010, section 6.4 did;
- ``emotions_wheel_walk.png``: Paul 2010's walk over the evenly spaced wheel,
  16 angles 22.5 degrees apart (rows) at activation 1, 3, 5 and 7 (columns),
  labelled with the wheel's emotion names.

Each profile's midpoints are clamped to the FAP ranges of Tekalp and Ostermann 2000, Table 7,
deformed and rendered offscreen (OSMesa or EGL). Run from the repository root:

    .venv/bin/python scripts/render_emotions.py [--out docs/images] [--size 256]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

# run from a checkout: the repository's package wins over an installed one
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ORDER = ("joy", "sadness", "anger", "fear", "disgust", "surprise")
WHEEL_NAMES = (
    "trust", "submission", "fear", "awe", "surprise", "disapproval", "sadness", "remorse",
    "disgust", "contempt", "anger", "aggressiveness", "anticipation", "optimism", "joy", "love",
)  # fmt: skip
ACTIVATIONS = (1.0, 3.0, 5.0, 7.0)


def load_face():  # type: ignore[no-untyped-def]
    """The default face of the realizer (realizer/face/default.py)."""
    from realizer.face.default import load_default_face

    return load_default_face()


def fap_vector(configuration, limits) -> np.ndarray:  # type: ignore[no-untyped-def]
    values = np.where(configuration.mask, configuration.values, 0.0)
    return np.asarray(limits.clamp(values))


def label(image: Image.Image, text: str) -> Image.Image:
    framed = Image.new("RGB", (image.width, image.height + 22), "white")
    framed.paste(image, (0, 22))
    ImageDraw.Draw(framed).text((6, 4), text, fill="black")
    return framed


def save(image: Image.Image, path: Path) -> None:
    """PNG with an adaptive 256-colour palette: smooth shading keeps, files stay small."""
    image.convert("P", palette=Image.Palette.ADAPTIVE, colors=256).save(path, optimize=True)


def grid(tiles: list[list[Image.Image]], gap: int = 4) -> Image.Image:
    width = max(sum(t.width for t in row) + gap * (len(row) - 1) for row in tiles)
    height = sum(max(t.height for t in row) for row in tiles) + gap * (len(tiles) - 1)
    sheet = Image.new("RGB", (width, height), "white")
    y = 0
    for row in tiles:
        x = 0
        for tile in row:
            sheet.paste(tile, (x, y))
            x += tile.width + gap
        y += max(t.height for t in row) + gap
    return sheet


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    parser.add_argument("--size", type=int, default=256)
    args = parser.parse_args()

    from realizer.engines.face import default_limits
    from realizer.face.convert.emotion import load_default_converter
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, Framing

    face = load_face()
    converter = load_default_converter()
    limits = default_limits()
    size = (args.size, args.size)

    # frame the face from chin to brows, not the whole head
    points = np.array([face.feature_position(name) for name in ("2.1", "4.5", "4.6", "4.1")])
    renderer = FaceRenderer(face, *size, framing=Framing.of_points(points, margin=0.22))

    def render(configuration) -> Image.Image:  # type: ignore[no-untyped-def]
        vertices = deform(face, fap_vector(configuration, limits))
        return Image.fromarray(renderer.render(vertices))

    args.out.mkdir(parents=True, exist_ok=True)
    neutral = label(Image.fromarray(renderer.render(None)), "neutral")
    measured = converter.wheel("measured")
    row = [neutral]
    for name in ORDER:
        archetype = measured.archetype(name)
        profile = converter.for_point(archetype.angle, archetype.activation)
        row.append(label(render(profile.configuration()), f"{name} ({profile.sources[0]})"))
    save(grid([row]), args.out / "emotions_archetypes.png")

    sheet = []
    for name in ORDER:
        archetype = measured.archetype(name)
        sheet.append(
            [
                label(
                    render(
                        converter.for_point(
                            archetype.angle, archetype.activation, choices={name: number}
                        ).configuration()
                    ),
                    f"{name.capitalize()} {number}"
                    + (" (default)" if number == archetype.default_profile else ""),
                )
                for number in converter.profiles.numbers(name)
            ]
        )
    save(grid(sheet), args.out / "emotions_profiles.png")

    rows = []
    for index, name in enumerate(WHEEL_NAMES):
        angle = 22.5 * index
        tiles = [
            label(
                render(converter.for_point(angle, activation, wheel="ideal").configuration()),
                f"{angle:g} deg {name}, a={activation:g}",
            )
            for activation in ACTIVATIONS
        ]
        rows.append(tiles)
    # two blocks of 8 angles side by side keep the sheet readable
    half = len(rows) // 2
    joined = [left + right for left, right in zip(rows[:half], rows[half:], strict=True)]
    save(grid(joined), args.out / "emotions_wheel_walk.png")
    renderer.close()
    print(
        f"wrote emotions_archetypes.png, emotions_profiles.png, emotions_wheel_walk.png: {args.out}"
    )


if __name__ == "__main__":
    main()
