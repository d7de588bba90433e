"""``realizer fap-sheet``: every FAP of a face on one contact sheet.

The evaluation method of Paul 2010, section 4.4.2 (figure 4.20): for each FAP
3..68, the neutral face, the face with the FAP set (and, for bidirectional
FAPs, with minus that value), and the difference between pose and neutral
drawn over the neutral face, blurred and at 25 % intensity, so that one sees
where the face moved. The values, and the view for motions along the depth
axis, come from ``realizer/face/data/fap_sheet.csv`` (documented there).

Heavy imports (numpy, PIL, the renderer) happen inside the functions.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from realizer.commands import plain_text

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from realizer.face.model import Face

#: Intensity of the blurred neutral face under the differences (Paul 2010, 4.4.2).
UNDERLAY_INTENSITY = 0.25
#: Radius (pixels) of the Gaussian blur of the underlay.
UNDERLAY_BLUR = 3.0
#: Differences are multiplied by this so that small motions show.
DIFFERENCE_GAIN = 3.0


@dataclass(frozen=True, slots=True)
class SheetEntry:
    """One row of ``fap_sheet.csv``."""

    fap: int
    value: float
    view: Literal["front", "left", "right"]
    jaw_open: float


def load_sheet_entries() -> list[SheetEntry]:
    text = resources.files("realizer.face").joinpath("data/fap_sheet.csv").read_text("utf-8")
    rows = csv.DictReader(line for line in text.splitlines() if not line.startswith("#"))
    entries = []
    for row in rows:
        view = row["view"]
        if view not in ("front", "left", "right"):
            raise ValueError(f"fap_sheet.csv: FAP {row['fap']}: unknown view {view!r}")
        entries.append(
            SheetEntry(
                int(row["fap"]),
                float(row["value"]),
                view,  # type: ignore[arg-type]
                float(row["jaw_open"]),
            )
        )
    return entries


def difference_over_underlay(
    neutral: npt.NDArray[np.uint8], pose: npt.NDArray[np.uint8]
) -> npt.NDArray[np.uint8]:
    """Paul 2010, figure 4.20, last panel: |pose - neutral| (times
    :data:`DIFFERENCE_GAIN`) over the neutral image blurred and dimmed to
    :data:`UNDERLAY_INTENSITY`. The background is black, so it stays black."""
    import numpy as np
    from PIL import Image, ImageFilter

    difference = np.abs(pose.astype(np.float32) - neutral.astype(np.float32)) * DIFFERENCE_GAIN
    blurred = Image.fromarray(neutral).filter(ImageFilter.GaussianBlur(UNDERLAY_BLUR))
    underlay = np.asarray(blurred, dtype=np.float32) * UNDERLAY_INTENSITY
    result: npt.NDArray[np.uint8] = np.clip(underlay + difference, 0, 255).astype(np.uint8)
    return result


def face_framing(face: Face) -> Any:
    """Frame the face proper (feature points of the chin, lips, eyes, brows,
    cheeks, nose and ears), or the whole mesh if those are missing."""
    import numpy as np

    from realizer.face.render import Framing

    points = [
        p
        for name, p in face.params.feature_points.items()
        if name.split(".")[0] in {"2", "3", "4", "5", "8", "9", "10"}
    ]
    if len(points) < 4:
        return Framing.of_points(np.asarray(face.vertices))
    return Framing.of_points(np.asarray(points, dtype=np.float64), margin=0.16)


def build_sheet(face: Face, tile: int = 256) -> npt.NDArray[np.uint8]:
    """The contact sheet as an RGB image: one row per FAP, in two columns,
    each row: label, neutral, +value, difference, -value, difference."""
    import numpy as np
    from PIL import Image, ImageDraw

    from realizer.face.deform import deform
    from realizer.face.faps import FAP_TABLE
    from realizer.face.render import FaceRenderer

    entries = load_sheet_entries()
    label_width = 150
    row_width = label_width + 5 * tile
    columns = 2
    rows_per_column = (len(entries) + columns - 1) // columns
    header = 28
    sheet = Image.new("RGB", (columns * row_width, header + rows_per_column * tile), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    draw.text(
        (6, 6),
        f"FAP contact sheet of face '{face.name}': neutral | +value | "
        "difference over blurred neutral (Paul 2010, fig. 4.20) | -value | difference",
        fill=(230, 230, 230),
    )
    neutrals: dict[tuple[str, float], npt.NDArray[np.uint8]] = {}
    with FaceRenderer(face, tile, tile, framing=face_framing(face)) as renderer:

        def render(values: npt.NDArray[np.float64], view: Any) -> npt.NDArray[np.uint8]:
            return renderer.render(deform(face, values), view=view)

        for k, entry in enumerate(entries):
            base = np.zeros(68)
            base[2] = entry.jaw_open
            key = (entry.view, entry.jaw_open)
            if key not in neutrals:
                neutrals[key] = render(base, entry.view)
            neutral = neutrals[key]
            info = FAP_TABLE[entry.fap]
            tiles = [neutral]
            for sign in (1.0, -1.0):
                if sign < 0 and info.unidirectional:
                    tiles += [np.zeros_like(neutral)] * 2
                    continue
                values = base.copy()
                values[entry.fap - 1] += sign * entry.value
                pose = render(values, entry.view)
                tiles += [pose, difference_over_underlay(neutral, pose)]
            x0 = (k // rows_per_column) * row_width
            y0 = header + (k % rows_per_column) * tile
            for t, image in enumerate(tiles):
                sheet.paste(Image.fromarray(image), (x0 + label_width + t * tile, y0))
            sign_text = "+" if info.unidirectional else "+/-"
            lines = [
                f"{entry.fap} {info.name}",
                f"{sign_text}{entry.value:g} {info.unit}",
                f"{info.direction}" + (f", {entry.view} view" if entry.view != "front" else ""),
            ]
            if entry.jaw_open:
                lines.append(f"jaw open {entry.jaw_open:g}")
            for i, line in enumerate(lines):
                draw.text((x0 + 6, y0 + 8 + 16 * i), line, fill=(230, 230, 230))
    return np.asarray(sheet)


def run(args: argparse.Namespace) -> int:
    from realizer.extras import require

    require("render", "realizer fap-sheet")
    from realizer.face.render import RenderUnavailableError, save_png

    if args.face:
        from realizer.face.paramfile import load_face

        face = load_face(args.face)
    else:
        from realizer.face.default import load_default_face

        face = load_default_face()
    try:
        image = build_sheet(face, tile=args.tile)
    except RenderUnavailableError as error:
        print(f"realizer fap-sheet: {error}")
        return 1
    save_png(image, args.output)
    print(f"wrote {args.output} ({image.shape[1]}x{image.shape[0]})")
    return 0


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "fap-sheet",
        help="render every FAP 3..68 of a face on one contact sheet (PNG)",
        description=plain_text(__doc__.split("\n\n")[0]) if __doc__ else None,
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    parser.add_argument(
        "--face",
        help="a face file (STEM, STEM.npz or STEM.xml); default: the built-in default face",
    )
    parser.add_argument(
        "--tile", type=int, default=256, help="tile size in pixels (256: lid and lip defects show)"
    )
    parser.set_defaults(run=run)
