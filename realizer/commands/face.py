"""``realizer face``: render one pose of a face to a PNG.

``realizer face --faps "3=400 31=200" -o face.png`` sets FAPs by number (or
name) and value (FAPU-scaled units, Tekalp and Ostermann 2000, Table 7) on the default face (or
``--face PATH``) and renders it from the fixed frontal camera of
:mod:`realizer.face.render`. ``realizer face FILE.fap -o face.png`` takes the
first frame of a .fap file (:mod:`realizer.face.fapfile`; ``--frame N``
picks another).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from realizer.commands import error_line, load_face_option

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt


def parse_fap_assignments(text: str) -> npt.NDArray[np.float64]:
    """``"3=400 open_jaw=200 31=-50"`` -> a (68,) FAP vector. Raises ValueError."""
    import numpy as np

    from realizer.face.faps import FAP_TABLE

    by_name = {info.name: number for number, info in FAP_TABLE.items()}
    vector = np.zeros(68)
    for item in text.replace(",", " ").split():
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"expected FAP=VALUE, got {item!r}")
        number = int(key) if key.isdigit() else by_name.get(key, 0)
        if not 1 <= number <= 68:
            raise ValueError(f"unknown FAP {key!r}")
        try:
            number_value = float(value)
        except ValueError:
            number_value = math.nan
        if not math.isfinite(number_value):
            raise ValueError(f"FAP {key}: {value!r} is not a finite number")
        vector[number - 1] = number_value
    return vector


def fap_file_frame(path: str, frame: int) -> npt.NDArray[np.float64]:
    """The FAP vector of frame ``frame`` (from 0) of a .fap file
    (:mod:`realizer.face.fapfile`) or of an MPEG-4 coded FAP file
    (:mod:`realizer.face.fapcoding`). Raises ValueError for a missing frame."""
    import numpy as np

    from realizer.face.fapcoding import read_any_fap_file

    fap = read_any_fap_file(path)  # text .fap, or MPEG-4 coded (realizer faps --coded)
    frames = fap.values.shape[0]
    if not 0 <= frame < frames:
        raise ValueError(f"{path} has {frames} frames, no frame {frame}")
    return np.where(fap.mask[frame], fap.values[frame], 0.0).astype(np.float64)


def run(args: argparse.Namespace) -> int:
    from realizer.extras import require

    require("render", "realizer face")
    from realizer.errors import RealizerError
    from realizer.face.deform import deform
    from realizer.face.render import FaceRenderer, RenderUnavailableError, save_png

    try:
        if args.file:
            values = fap_file_frame(args.file, args.frame)
        else:
            values = parse_fap_assignments(args.faps or "")
    except (ValueError, OSError, RealizerError) as error:
        print(error_line("face", error), file=sys.stderr)
        return 2
    face = load_face_option(args.face)
    try:
        with FaceRenderer(face, args.size, args.size) as renderer:
            image = renderer.render(deform(face, values), view=args.view)
    except RenderUnavailableError as error:
        print(f"realizer face: {error}")
        return 1
    save_png(image, args.output)
    print(f"wrote {args.output}")
    return 0


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("face", help="render one FAP pose of a face to a PNG")
    parser.add_argument("file", nargs="?", help="a .fap file (its first frame, or --frame)")
    parser.add_argument("--faps", help='FAP values, e.g. "3=400 31=200" or "open_jaw=400"')
    parser.add_argument("--frame", type=int, default=0, help="frame of the .fap file (0)")
    parser.add_argument("--face", help="a face file (STEM, STEM.npz or STEM.xml)")
    parser.add_argument("--size", type=int, default=512, help="image size in pixels (512)")
    parser.add_argument("--view", choices=("front", "left", "right"), default="front")
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    parser.set_defaults(run=run)
