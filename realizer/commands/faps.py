"""``realizer faps FILE.bml [--fps 25] -o out.fap``: a block's FAP stream as a .fap file.

Runs the block in a realizer session (parse, plan, schedule, face engine) on
a simulated clock from 0, one frame every 1/fps seconds, until the block
ends (its ``blockProgress`` end feedback) or ``--max-seconds`` pass, and
writes the frames in the Xface/Greta ``.fap`` text format
(:mod:`realizer.face.fapfile`). Warnings go to stderr. Bad BML or an
unreadable file: a message on stderr and exit 2.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from realizer.commands import error_line, plain_text

if TYPE_CHECKING:  # numpy is imported when a recording is made, not by `realizer --help`
    import numpy as np
    import numpy.typing as npt


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "faps",
        help="write a BML block's FAP stream to a .fap file",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("file", type=Path, metavar="FILE.bml")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the .fap file")
    parser.add_argument("--fps", type=float, default=25.0, help="frames per second (25)")
    parser.add_argument("--max-seconds", type=float, default=120.0, help="stop after (120)")
    parser.add_argument(
        "--coded",
        choices=("dct", "lowdelay"),
        default=None,
        help="write MPEG-4 coded FAPs instead of text: dct (16-frame DCT segments, for "
        "recordings) or lowdelay (the viewer stream's arithmetic coding)",
    )
    parser.add_argument(
        "--fap-quant", type=int, default=10, help="FAP_QUANT 1..31 for --coded (10)"
    )
    parser.add_argument(
        "--arkit",
        action="store_true",
        help="write the 52 ARKit blendshape weights as CSV (one row per frame) instead",
    )
    parser.set_defaults(run=run)


@dataclass(frozen=True, slots=True, eq=False)
class BlockRecording:
    """A block played on a simulated clock: per frame ``values``/``mask`` (n, 68),
    ``times`` (n,) seconds; ``syncs`` (label, seconds) as the session reported
    them; ``warnings`` the warning feedback texts."""

    times: npt.NDArray[np.float64]
    values: npt.NDArray[np.float64]
    mask: npt.NDArray[np.bool_]
    syncs: tuple[tuple[str, float], ...]
    warnings: tuple[str, ...]


def _feedback_id(xml: str) -> str:
    from lxml import etree

    try:
        element = etree.fromstring(xml.encode("utf-8"))
    except etree.XMLSyntaxError:
        return ""
    return str(element.get("id", ""))


def record_block(text: str | bytes, fps: float, max_seconds: float) -> BlockRecording:
    """Play ``text`` in a fresh session from time 0 (see the module docstring)."""
    import numpy as np

    from realizer.session import Session

    if not fps > 0:
        raise ValueError("--fps must be positive")
    session = Session(character_id="realizer", face=None)
    session.receive_bml(text, 0.0)
    times: list[float] = []
    values: list[npt.NDArray[np.float64]] = []
    masks: list[npt.NDArray[np.bool_]] = []
    syncs: list[tuple[str, float]] = []
    warnings: list[str] = []
    ended_at: float | None = None
    number = 0
    while True:
        now = number / fps
        session.tick(now)
        for feedback in session.take_feedback():
            if feedback.kind == "warning":
                warnings.append(feedback.xml)
            elif feedback.kind == "syncPointProgress":
                syncs.append((_feedback_id(feedback.xml), float(feedback.time)))
            elif feedback.kind == "blockProgress" and _feedback_id(feedback.xml).endswith(":end"):
                ended_at = float(feedback.time)
        frame = session.frame(now)
        times.append(now)
        values.append(np.asarray(frame.values, dtype=np.float64))
        masks.append(np.asarray(frame.mask, dtype=bool))
        if (ended_at is not None and now >= ended_at) or now >= max_seconds:
            break
        number += 1
    return BlockRecording(
        np.array(times), np.stack(values), np.stack(masks), tuple(syncs), tuple(warnings)
    )


def recording_for(args: Any, command: str) -> BlockRecording | None:
    """Record ``args.file`` for ``realizer COMMAND``; report problems on stderr."""
    from realizer.bml_parser import BmlError, parse_bml
    from realizer.errors import RealizerError

    try:
        data = args.file.read_bytes()
        # A file that is no BML reads as every command's parse error
        # (path:line:col: error: ...), not as an empty recording.
        parse_bml(data, source=str(args.file))
        recording = record_block(data, args.fps, args.max_seconds)
    except BmlError as error:
        print(str(error), file=sys.stderr)
        return None
    except ImportError:  # a missing extra: the command line names it
        raise
    except (OSError, ValueError, RealizerError) as error:
        print(error_line(command, error, args.file), file=sys.stderr)
        return None
    for warning in recording.warnings:
        print(f"realizer {command}: warning: {warning}", file=sys.stderr)
    return recording


def run(args: Any) -> int:
    from realizer.face.fapfile import FapFile, write_fap_file

    recording = recording_for(args, "faps")
    if recording is None:
        return 2
    if args.arkit:
        from realizer.face.arkit import write_arkit_csv
        from realizer.face.default import load_default_face

        write_arkit_csv(
            args.output, load_default_face(), recording.times, recording.values, recording.mask
        )
        print(f"{args.output}: ARKit weights of {len(recording.times)} frames at {args.fps:g} fps")
        return 0
    if args.coded is not None:
        from realizer.face.fapcoding import encode_dct_file, encode_stream_file

        encode = encode_dct_file if args.coded == "dct" else encode_stream_file
        data = encode(recording.values, recording.mask, args.fps, args.fap_quant)
        args.output.write_bytes(data)
        seconds = len(recording.times) / args.fps
        print(
            f"{args.output}: {len(recording.times)} frames at {args.fps:g} fps, "
            f"{args.coded} coded: {len(data)} bytes, {len(data) * 8 / seconds / 1000:.2f} kbit/s"
        )
        return 0
    write_fap_file(args.output, FapFile(args.file.stem, args.fps, recording.values, recording.mask))
    print(f"{args.output}: {len(recording.times)} frames at {args.fps:g} fps")
    return 0
