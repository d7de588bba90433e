"""``realizer facs AU...``: the FAP values of FACS Action Units.

Each AU is ``N``, ``NL`` or ``NR`` (left or right side) with an optional
intensity 0..1 after a colon (``12L:0.8``; default 1), converted with the
default mapping (Paul 2010, chapter 5; ``realizer/face/data/facs/default.map``)
or the one given by ``--mapping``. Prints one ``FAP name value`` line per FAP,
or with ``--json`` an object from FAP number (a string) to value, in
FAPU-scaled units. Unknown AUs: a message on stderr and exit 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from realizer.commands import error_line, plain_text


def fap_names() -> tuple[str, ...]:
    """FAP names of Tekalp and Ostermann 2000, Table 7 (the face's FAP table).

    FAP n is at index n - 1.
    """
    from realizer.face.faps import FAP_COUNT, FAP_TABLE

    return tuple(FAP_TABLE[n].name for n in range(1, FAP_COUNT + 1))


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "facs",
        help="print the FAP values of FACS Action Units",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("aus", nargs="+", metavar="AU", help="e.g. 1 2 12L:0.8")
    parser.add_argument("--json", action="store_true", help="print a JSON object")
    parser.add_argument("--mapping", type=Path, help="a mapping file (Paul 2010, figure 5.2)")
    parser.set_defaults(run=run)


def print_values(values: dict[int, float], as_json: bool) -> None:
    if as_json:
        print(json.dumps({str(fap): round(value, 6) for fap, value in values.items()}))
        return
    names = fap_names()
    for fap, value in values.items():
        print(f"{fap:>2}  {names[fap - 1]:<22} {value:10.1f}")


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
        print(error_line("facs", error), file=sys.stderr)
        return 2
    print_values(configuration.as_dict(), args.json)
    return 0
