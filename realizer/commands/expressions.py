"""``realizer expressions``: the face's expressions on one sheet.

Four rows on the default face (or ``--face``), each starting with the neutral
face: the six archetypal emotions from their default profiles (Raouzaiou et
al., "Parameterized Facial Expression Synthesis Based on MPEG-4", the middle of
each FAP's range), the six FAP 2 expressions at full intensity and the 15 FAP 1
visemes (Tekalp and Ostermann, "Face and 2-D mesh animation in MPEG-4",
Table 3), and a set of FACS Action Units through the default mapping
("Realization and high level specification of facial expressions for
embodied agents", chapter 5).

Heavy imports (numpy, PIL, the renderer) happen inside the functions; the
framing and the tile rendering are those of ``realizer fap-sheet``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from realizer.face.model import Face

#: The archetypes' words on the measured wheel (``data/emotion/wheels.txt``).
EMOTION_WORDS: tuple[str, ...] = ("joyful", "sad", "angry", "afraid", "disgusted", "surprised")
#: FAP 2's expressions (Tekalp and Ostermann, Table 4), by number.
FAP2_EXPRESSIONS: tuple[tuple[int, str], ...] = (
    (1, "joy"),
    (2, "sadness"),
    (3, "anger"),
    (4, "fear"),
    (5, "disgust"),
    (6, "surprise"),
)
#: Action Units shown (both sides), a set that covers brows, lids, nose, lips and jaw.
ACTION_UNITS: tuple[str, ...] = (
    "1", "2", "4", "5", "6", "7", "9", "10", "12", "15", "17", "18", "20", "23", "25", "26",
)  # fmt: skip
#: Height of the label strip above each tile, pixels.
LABEL_HEIGHT = 16


@dataclass(frozen=True, slots=True)
class Pose:
    """One tile: its label and its 68 FAP values (FAP n at index n - 1)."""

    label: str
    values: Any  # npt.NDArray[np.float64], (68,)


@dataclass(frozen=True, slots=True)
class PoseRow:
    """One row of the sheet: ``kind`` is emotion, fap2, viseme or au."""

    kind: str
    title: str
    poses: tuple[Pose, ...]


def sheet_rows() -> list[PoseRow]:
    """The poses of the sheet, row by row (the neutral tile is not among them)."""
    import numpy as np

    from realizer.face.convert.emotion import load_default_converter
    from realizer.face.convert.facs import facs_to_faps
    from realizer.face.convert.visemes import (
        FAP12_MAX,
        expression_faps,
        load_default_visemes,
        viseme_faps,
    )

    converter = load_default_converter()
    emotions = []
    for word in EMOTION_WORDS:
        values = np.zeros(68)
        for fap, fap_range in converter.for_word(word).ranges:
            values[fap - 1] = fap_range.center
        emotions.append(Pose(word, values))
    expressions = tuple(
        Pose(f"{number} {name}", expression_faps(number, FAP12_MAX).values.copy())
        for number, name in FAP2_EXPRESSIONS
    )
    table = load_default_visemes()
    visemes = tuple(
        Pose(f"v{n} {table.shape(n).label[0]}", viseme_faps(n, 0, FAP12_MAX).values.copy())
        for n in table.numbers()
    )
    aus = tuple(Pose(f"AU {au}", facs_to_faps([au]).values.copy()) for au in ACTION_UNITS)
    return [
        PoseRow("emotion", "emotions (Raouzaiou et al.)", tuple(emotions)),
        PoseRow("fap2", "FAP 2 expressions", expressions),
        PoseRow("viseme", "FAP 1 visemes", visemes),
        PoseRow("au", "FACS Action Units", aus),
    ]


def tile_origin(row: int, column: int, tile: int) -> tuple[int, int]:
    """(x, y) of the top left pixel of a tile of :func:`build_sheet`'s image."""
    return column * tile, LABEL_HEIGHT + row * (tile + 2 * LABEL_HEIGHT) + 2 * LABEL_HEIGHT


def build_sheet(face: Face, tile: int = 192) -> tuple[npt.NDArray[np.uint8], list[PoseRow]]:
    """The sheet as an RGB image, and the rows it shows. Row ``r`` starts with
    its title strip; its tile ``c`` (0: neutral) has its top left corner at
    :func:`tile_origin`, under a strip with its label."""
    import numpy as np
    from PIL import Image, ImageDraw

    from realizer.commands.fap_sheet import face_framing
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer

    rows = sheet_rows()
    columns = 1 + max(len(row.poses) for row in rows)
    step = tile + 2 * LABEL_HEIGHT
    sheet = Image.new("RGB", (columns * tile, LABEL_HEIGHT + len(rows) * step), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    draw.text((4, 2), f"expressions of face '{face.name}'", fill=(230, 230, 230))
    with FaceRenderer(face, tile, tile, framing=face_framing(face)) as renderer:
        neutral = renderer.render(face.vertices)
        for r, row in enumerate(rows):
            y0 = LABEL_HEIGHT + r * step
            draw.text((4, y0 + 2), row.title, fill=(255, 220, 140))
            y0 += LABEL_HEIGHT
            tiles = [("neutral", neutral)]
            tiles += [(p.label, renderer.render(deform(face, p.values))) for p in row.poses]
            for c, (label, image) in enumerate(tiles):
                sheet.paste(Image.fromarray(image), (c * tile, y0 + LABEL_HEIGHT))
                draw.text((c * tile + 3, y0 + 2), label, fill=(230, 230, 230))
    return np.asarray(sheet), rows


def run(args: argparse.Namespace) -> int:
    from realizer.commands.fap_sheet import write_sheet

    return write_sheet(
        "expressions", args.face, args.output, lambda face: build_sheet(face, tile=args.tile)[0]
    )


def register(subparsers: Any) -> None:
    from realizer.commands.fap_sheet import add_sheet_parser

    parser = add_sheet_parser(
        subparsers,
        "expressions",
        "render emotions, FAP 2 expressions, visemes and AUs on one sheet (PNG)",
        __doc__,
        192,
        "tile size in pixels",
    )
    parser.set_defaults(run=run)
