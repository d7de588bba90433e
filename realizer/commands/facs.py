"""``realizer facs AU...``: the FAP values of FACS Action Units.

Each AU is ``N``, ``NL`` or ``NR`` (left or right side) with an optional
intensity 0..1 after a colon (``12L:0.8``; default 1), converted with the
default mapping (seed 000 chapter 5; ``realizer/face/data/facs/default.map``)
or the one given by ``--mapping``. Prints one ``FAP name value`` line per FAP,
or with ``--json`` an object from FAP number (a string) to value, in
FAPU-scaled units. Unknown AUs: a message on stderr and exit 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

#: FAP names of seed 002 Table 7, for readable output.
_FAP_NAME_TEXT = (
    "viseme expression open_jaw lower_t_midlip raise_b_midlip stretch_l_cornerlip  "
    "stretch_r_cornerlip lower_t_lip_lm lower_t_lip_rm raise_b_lip_lm raise_b_lip_rm  "
    "raise_l_cornerlip raise_r_cornerlip thrust_jaw shift_jaw push_b_lip push_t_lip  "
    "depress_chin close_t_l_eyelid close_t_r_eyelid close_b_l_eyelid close_b_r_eyelid  "
    "yaw_l_eyeball yaw_r_eyeball pitch_l_eyeball pitch_r_eyeball thrust_l_eyeball  "
    "thrust_r_eyeball dilate_l_pupil dilate_r_pupil raise_l_i_eyebrow raise_r_i_eyebrow  "
    "raise_l_m_eyebrow raise_r_m_eyebrow raise_l_o_eyebrow raise_r_o_eyebrow  "
    "squeeze_l_eyebrow squeeze_r_eyebrow puff_l_cheek puff_r_cheek lift_l_cheek  "
    "lift_r_cheek shift_tongue_tip raise_tongue_tip thrust_tongue_tip raise_tongue  "
    "tongue_roll head_pitch head_yaw head_roll lower_t_midlip_o raise_b_midlip_o  "
    "stretch_l_cornerlip_o stretch_r_cornerlip_o lower_t_lip_lm_o lower_t_lip_rm_o  "
    "raise_b_lip_lm_o raise_b_lip_rm_o raise_l_cornerlip_o raise_r_cornerlip_o  "
    "stretch_l_nose stretch_r_nose raise_nose bend_nose raise_l_ear raise_r_ear  "
    "pull_l_ear pull_r_ear"
)
FAP_NAMES = tuple(_FAP_NAME_TEXT.split())


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "facs",
        help="print the FAP values of FACS Action Units",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    parser.add_argument("aus", nargs="+", metavar="AU", help="e.g. 1 2 12L:0.8")
    parser.add_argument("--json", action="store_true", help="print a JSON object")
    parser.add_argument("--mapping", type=Path, help="a mapping file (seed 000 figure 5.2)")
    parser.set_defaults(run=run)


def print_values(values: dict[int, float], as_json: bool) -> None:
    if as_json:
        print(json.dumps({str(fap): round(value, 6) for fap, value in values.items()}))
        return
    for fap, value in values.items():
        print(f"{fap:>2}  {FAP_NAMES[fap - 1]:<22} {value:10.1f}")


def run(args: Any) -> int:
    from realizer.face.convert.errors import ConversionError
    from realizer.face.convert.facs import facs_to_faps, parse_mapping

    try:
        mapping = None
        if args.mapping is not None:
            mapping = parse_mapping(
                args.mapping.read_text(encoding="utf-8"), source=str(args.mapping)
            )
        configuration = facs_to_faps(args.aus, mapping)
    except (ConversionError, OSError) as error:
        print(f"realizer facs: error: {error}", file=sys.stderr)
        return 2
    print_values(configuration.as_dict(), args.json)
    return 0
