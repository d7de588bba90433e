"""``realizer emotion``: the FAP profile of an emotion word or a wheel point.

``--word W`` takes the word's activation and Plutchik angle from the emotion
vocabulary (Raouzaiou et al. 2002, Table 6); ``--angle DEG --activation A`` is a point on
the wheel (``--wheel measured``, the default: Raouzaiou et al. 2002's angles;
``--wheel ideal``: Paul 2010's evenly spaced wheel). ``--profile fear=8``
picks an archetypal profile by its number in Raouzaiou et al. 2002, Table 5 (defaults in
``realizer/face/data/emotion/wheels.txt``). Prints each FAP's range and the
midpoint that is animated, or with ``--json`` an object from FAP number (a
string) to ``[low, high]``. Errors: a message on stderr and exit 2.
"""

from __future__ import annotations

import json
import sys
from typing import Any

from realizer.commands import plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "emotion",
        help="print the FAP profile of an emotion",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--word", help="an emotion word, e.g. guilty")
    which.add_argument("--angle", type=float, help="Plutchik wheel angle in degrees")
    parser.add_argument("--activation", type=float, help="Whissell activation (about 1..7)")
    parser.add_argument("--wheel", default=None, help="measured (default) or ideal")
    parser.add_argument(
        "--profile",
        action="append",
        default=[],
        metavar="ARCHETYPE=K",
        help="archetypal profile by its number in Raouzaiou et al. 2002, Table 5 (repeatable)",
    )
    parser.add_argument(
        "--weighting",
        choices=("interpolate", "as-printed"),
        default="interpolate",
        help="angular weights between archetypes (docs/emotion.md)",
    )
    parser.add_argument("--json", action="store_true", help="print a JSON object")
    parser.set_defaults(run=run)


def run(args: Any) -> int:
    import dataclasses

    from realizer.engines.face import parse_profile_choices
    from realizer.face.convert.emotion import load_default_converter
    from realizer.face.convert.errors import ConversionError

    try:
        choices = parse_profile_choices(" ".join(args.profile))
        converter = dataclasses.replace(load_default_converter(), weighting=args.weighting)
        if args.word is not None:
            profile = converter.for_word(args.word, activation=args.activation, choices=choices)
        else:
            if args.activation is None:
                raise ConversionError("--angle needs --activation")
            profile = converter.for_point(
                args.angle, args.activation, wheel=args.wheel, choices=choices
            )
    except ConversionError as error:
        print(f"realizer emotion: error: {error}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({str(fap): [r.low, r.high] for fap, r in profile.ranges}))
        return 0
    print(
        f"# {profile.rule} of {' and '.join(profile.sources)} at angle {profile.angle:g} deg, "
        f"activation {profile.activation:g}"
    )
    from realizer.commands.facs import fap_names

    names = fap_names()

    for fap, r in profile.ranges:
        print(f"{fap:>2}  {names[fap - 1]:<22} [{r.low:8.1f}, {r.high:8.1f}]  mid {r.center:8.1f}")
    return 0
