"""``realizer plot-faps FILE.bml -o faps.png``: plot a block's FAP curves and sync points.

Plays the block as ``realizer faps`` does and draws every FAP that moves,
with a dashed line at each sync point the session reported
(``behaviour:sync`` labels). Angular FAPs (eyes, head) get their own axes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from realizer.commands import plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "plot-faps",
        help="plot a BML block's FAP curves with its sync points",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("file", type=Path, metavar="FILE.bml")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the PNG file")
    parser.add_argument("--fps", type=float, default=50.0, help="samples per second (50)")
    parser.add_argument("--max-seconds", type=float, default=120.0, help="stop after (120)")
    parser.set_defaults(run=run)


def run(args: Any) -> int:
    from realizer.extras import require

    require("plots", "realizer plot-faps")
    from realizer.commands.facs import fap_names
    from realizer.commands.faps import recording_for
    from realizer.face.plotting import plot_fap_tracks

    recording = recording_for(args, "plot-faps")
    if recording is None:
        return 2
    drawn = plot_fap_tracks(
        recording.times,
        recording.values,
        recording.mask,
        recording.syncs,
        args.output,
        title=args.file.name,
        names=fap_names(),
    )
    print(f"{args.output}: {len(drawn)} FAPs, {len(recording.syncs)} sync points")
    return 0
