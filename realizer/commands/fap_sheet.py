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

from realizer.commands import load_face_option, plain_text

if TYPE_CHECKING:
    from collections.abc import Callable

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


#: Close-up regions: the feature point groups each frames (Tekalp and Ostermann,
#: figure 2), by the FAP groups shown in it.
REGIONS: dict[str, tuple[set[int], set[str]]] = {
    "mouth": ({2, 6, 8}, {"2", "8", "9.15"}),
    "eyes": ({3, 4}, {"3", "4"}),
    "cheeks": ({5}, {"5", "8", "9.1", "9.2"}),
    "nose": ({9}, {"9", "8.1"}),
    "ears": ({10}, {"10"}),
}


def region_of(fap: int) -> str:
    """The close-up region a FAP is shown in: one of :data:`REGIONS`, "left
    eye" or "right eye" for one side's lid, eyeball or brow, "face" for the
    head's rotations."""
    from realizer.face.faps import FAP_TABLE

    info = FAP_TABLE[fap]
    region = next((name for name, (groups, _) in REGIONS.items() if info.group in groups), "face")
    if region == "eyes":
        # one eye and its brow: odd feature point numbers are on the left
        sides = {int(p.split(".")[1]) % 2 for p in info.feature_points}
        if sides == {1} or (not sides and "_l_" in info.name):
            return "left eye"
        if sides == {0} or (not sides and "_r_" in info.name):
            return "right eye"
    return region


def region_framing(face: Face, region: str) -> Any:
    """A close-up on ``region`` (:func:`region_of`): its feature points with a
    margin; the whole face for "face" or where the points are missing."""
    import numpy as np

    from realizer.face.render import Framing

    if region == "face":
        return face_framing(face)
    side = {"left eye": 1, "right eye": 0}.get(region)
    wanted = REGIONS["eyes" if side is not None else region][1]
    points = [
        p
        for name, p in face.params.feature_points.items()
        if (name in wanted or name.split(".")[0] in wanted)
        and (side is None or int(name.split(".")[1]) % 2 == side)
    ]
    if len(points) < 2:
        return face_framing(face)
    return Framing.of_points(np.asarray(points, dtype=np.float64), margin=0.25)


def build_sheet(
    face: Face, tile: int = 256, *, close_up: bool = False, profile: bool = False
) -> npt.NDArray[np.uint8]:
    """The contact sheet as an RGB image: one row per FAP, in two columns,
    each row: label, neutral, +value, difference, -value, difference; with
    ``profile`` also the neutral, +value and -value seen from the left (the
    right for FAPs of the right side's feature points: the row's view if it
    is a side view). ``close_up`` frames each row on its FAP's region
    (:func:`region_of`) instead of the whole face."""
    import numpy as np
    from PIL import Image, ImageDraw

    from realizer.face.deform import deform
    from realizer.face.faps import FAP_TABLE
    from realizer.face.render import FaceRenderer

    entries = load_sheet_entries()
    label_width = 150
    row_width = label_width + (8 if profile else 5) * tile
    columns = 2
    rows_per_column = (len(entries) + columns - 1) // columns
    header = 28
    sheet = Image.new("RGB", (columns * row_width, header + rows_per_column * tile), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    draw.text(
        (6, 6),
        f"FAP contact sheet of face '{face.name}': neutral | +value | "
        "difference over blurred neutral (Paul 2010, fig. 4.20) | -value | difference"
        + (" | profile: neutral | +value | -value" if profile else "")
        + (" (close-ups of each FAP's region)" if close_up else ""),
        fill=(230, 230, 230),
    )
    regions = sorted({region_of(e.fap) if close_up else "face" for e in entries})
    # renders of the neutral face (or of FAP 3 alone) by region, view and jaw opening
    neutrals: dict[tuple[str, str, float], npt.NDArray[np.uint8]] = {}
    for region in regions:
        framing = region_framing(face, region)
        with FaceRenderer(face, tile, tile, framing=framing) as renderer:

            def render(
                values: npt.NDArray[np.float64], view: Any, region: str = region
            ) -> npt.NDArray[np.uint8]:
                only_jaw = not np.any(np.delete(values, 2))
                key = (region, str(view), float(values[2])) if only_jaw else None
                if key is not None and key in neutrals:
                    return neutrals[key]
                image = renderer.render(deform(face, values), view=view)
                if key is not None:
                    neutrals[key] = image
                return image

            for k, entry in enumerate(entries):
                if close_up and region_of(entry.fap) != region:
                    continue
                base = np.zeros(68)
                base[2] = entry.jaw_open
                neutral = render(base, entry.view)
                info = FAP_TABLE[entry.fap]
                side = entry.view if entry.view != "front" else "left"
                tiles = [neutral]
                side_tiles = [render(base, side)]
                for sign in (1.0, -1.0):
                    if sign < 0 and info.unidirectional:
                        tiles += [np.zeros_like(neutral)] * 2
                        side_tiles.append(np.zeros_like(neutral))
                        continue
                    values = base.copy()
                    values[entry.fap - 1] += sign * entry.value
                    pose = render(values, entry.view)
                    tiles += [pose, difference_over_underlay(neutral, pose)]
                    if profile:
                        side_tiles.append(render(values, side))
                if profile:
                    tiles += side_tiles
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
                if close_up:
                    lines.append(f"close-up: {region}")
                for i, line in enumerate(lines):
                    draw.text((x0 + 6, y0 + 8 + 16 * i), line, fill=(230, 230, 230))
    return np.asarray(sheet)


def write_sheet(
    command: str, face_option: str | None, output: Path, build: Callable[[Face], Any]
) -> int:
    """What the sheet commands share: load the ``--face``, ``build`` the sheet
    image on it, write it as a PNG and say so; 1 when no OpenGL is at hand."""
    from realizer.extras import require

    require("render", f"realizer {command}")
    from realizer.face.render import RenderUnavailableError, save_png

    face = load_face_option(face_option)
    try:
        image = build(face)
    except RenderUnavailableError as error:
        print(f"realizer {command}: {error}")
        return 1
    save_png(image, output)
    print(f"wrote {output} ({image.shape[1]}x{image.shape[0]})")
    return 0


def run(args: argparse.Namespace) -> int:
    return write_sheet(
        "fap-sheet",
        args.face,
        args.output,
        lambda face: build_sheet(
            face, tile=args.tile, close_up=args.close_up, profile=args.profile
        ),
    )


def add_sheet_parser(
    subparsers: Any, name: str, help_: str, doc: str | None, tile: int, tile_help: str
) -> Any:
    """The sub-command ``name`` of a sheet command, with the options every
    sheet has: ``-o``, ``--face`` and ``--tile`` (default ``tile``)."""
    parser = subparsers.add_parser(
        name, help=help_, description=plain_text(doc.split("\n\n")[0]) if doc else None
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    parser.add_argument(
        "--face",
        help="a face file (STEM, STEM.npz or STEM.xml); default: the built-in default face",
    )
    parser.add_argument("--tile", type=int, default=tile, help=tile_help)
    return parser


def register(subparsers: Any) -> None:
    parser = add_sheet_parser(
        subparsers,
        "fap-sheet",
        "render every FAP 3..68 of a face on one contact sheet (PNG)",
        __doc__,
        256,
        "tile size in pixels (256: lid and lip defects show)",
    )
    parser.add_argument(
        "--close-up",
        action="store_true",
        help="frame each FAP on its region (mouth, eyes and brows, cheeks, nose, ears)",
    )
    parser.add_argument(
        "--profile",
        action="store_true",
        help="add the neutral, +value and -value seen from the side (z motion shows)",
    )
    parser.set_defaults(run=run)
