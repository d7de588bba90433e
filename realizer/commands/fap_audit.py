"""realizer fap-audit: check every FAP displacement of a face on its mesh.

For each of the 127 displacements of FAPs 3..68 (each direction of a
bidirectional FAP on its own, at the values ``realizer fap-sheet`` shows)
prints whether the skin folds over, whether the FAP's probe point moves the
way "Face and 2-D mesh animation in MPEG-4", Table 7 says, whether a one-sided
FAP leaves the other side, and whether the motion is large enough to see
(:mod:`realizer.face.audit`). ``--range`` checks the jaw, lip, cheek and
nose FAPs at a quarter, half, three quarters and all of their practical
range (``PRACTICAL_RANGE``) instead. Exits 1 when any displacement fails.

``--scores`` prints instead the weighted score of the thesis's evaluation by
eye ("Realization and high level specification of facial expressions for
embodied agents", section 4.4) from the default face's scores
(:mod:`realizer.face.evaluation`); ``--scores --every`` also lists every
displacement that scored below 3 with what was seen.
"""

from __future__ import annotations

import argparse
from typing import Any

from realizer.commands import load_face_option, plain_text


def run(args: argparse.Namespace) -> int:
    if args.scores:
        from realizer.face.evaluation import format_scores, load_scores

        print(format_scores(load_scores(), every=args.every))
        return 0
    from realizer.commands.fap_sheet import load_sheet_entries
    from realizer.face.audit import audit_face, audit_range, format_audit

    face = load_face_option(args.face)
    if args.range:
        rows = audit_range(face)
    else:
        poses = [(e.fap, e.value, e.jaw_open) for e in load_sheet_entries()]
        rows = audit_face(face, poses)
    print(format_audit(rows))
    return 0 if all(r.ok for r in rows) else 1


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "fap-audit",
        help="check every FAP displacement of a face: folds, direction, side, size",
        description=plain_text(__doc__.split("\n\n")[0]) if __doc__ else None,
    )
    parser.add_argument(
        "--face",
        help="a face file (STEM, STEM.npz or STEM.xml); default: the built-in default face",
    )
    parser.add_argument(
        "--range",
        action="store_true",
        help="the jaw, lip, cheek and nose FAPs at 1/4..1 of their practical range instead",
    )
    parser.add_argument(
        "--scores",
        action="store_true",
        help="print the default face's scores by eye (thesis section 4.4) and their weighted mean",
    )
    parser.add_argument(
        "--every", action="store_true", help="with --scores: list each displacement below 3"
    )
    parser.set_defaults(run=run)
