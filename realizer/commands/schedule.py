"""``realizer schedule FILE... [--json]``: the solved sync point times of BML blocks.

Every file holds one block. The files go, in the order given, to one fresh
:class:`realizer.session.Session` at time 0, so composition and cross-block
references work across files as they do in a live session: an APPEND block
starts after every earlier block has ended, a REPLACE block interrupts the
earlier ones (they are still listed, with the times they were planned for,
and marked interrupted in the table),
and ``bml1:nod1:end`` in a later file names a sync point of an earlier one.
All times are global seconds, which here are seconds after the first block
started. Warnings go to stderr as ``path: warning TYPE id: message``.

``--json`` prints ``{"blocks": [{"id", "start", "end", "behaviours": [{"id",
"type", "syncs": {name: seconds}}]}], "warnings": [{"type", "id",
"message"}]}``; a block that failed to schedule is not in ``blocks`` (its
``IMPOSSIBLE_TO_SCHEDULE`` warning is). Exit status: 2 when a file cannot be
read or parsed (``path:line:col: error: message`` on stderr), else 1 when a
block failed to schedule or was refused, else 0.

``--strict`` (for planners' CI): every warning, an unknown reference
included, is an error: it is printed as ``path: error TYPE id: message``,
the block is refused (nothing of it is scheduled, so later files do not see
it) and the exit status is 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from realizer.commands import error_line, plain_text

if TYPE_CHECKING:
    from realizer.feedback import Feedback
    from realizer.scheduler.plan import TimedPlan

#: Times are printed to this many decimals in JSON (a nanosecond), which hides
#: the solver's round-off (``-6e-18`` for 0) without hiding any real timing.
JSON_DECIMALS = 9


@dataclass(frozen=True, slots=True)
class WarningNote:
    """A warning the session reported, as ``warningFeedback`` carries it."""

    type: str
    id: str
    message: str


@dataclass(frozen=True, slots=True)
class ScheduledFile:
    """One file's outcome: its plan (None if it failed or was refused) and warnings."""

    path: Path
    plan: TimedPlan | None
    warnings: tuple[WarningNote, ...]
    #: a later REPLACE block interrupted this one (its times are as planned)
    interrupted: bool = False


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "schedule",
        help="solve BML blocks and print every sync point's time",
        description=plain_text(__doc__.split("\n\n", 1)[1]) if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE")
    parser.add_argument("--json", action="store_true", help="print the schedule as JSON")
    parser.add_argument(
        "--strict", action="store_true", help="every warning is an error (exit status 2)"
    )
    parser.set_defaults(run=run)


def warnings_of(feedback: list[Feedback]) -> tuple[WarningNote, ...]:
    """The warnings among a session's feedback, read back from their XML."""
    # Our own generated XML, so the standard library parser is safe here.
    import xml.etree.ElementTree as ElementTree

    notes = []
    for item in feedback:
        if item.kind != "warning":
            continue
        element = ElementTree.fromstring(item.xml)
        notes.append(
            WarningNote(element.get("type", ""), element.get("id", ""), element.text or "")
        )
    return tuple(notes)


def schedule_files(
    paths: list[Path], *, strict: bool = False
) -> tuple[list[ScheduledFile], list[str]]:
    """Schedule the files in order in one session at time 0.

    Returns the outcome of every file that parsed, and the error lines
    (``path:line:col: error: message``) of those that did not.
    """
    from realizer.bml_parser import BmlError, parse_bml
    from realizer.session import BlockState, Session

    session = Session()
    outcomes: list[ScheduledFile] = []
    errors: list[str] = []
    for path in paths:
        try:
            data = path.read_bytes()
        except OSError as exc:
            errors.append(error_line("schedule", exc, path))
            continue
        try:
            # Parsed here, for the error's position in *this* file (the
            # session would only report it as a warningFeedback); the session
            # takes the parsed block as it is.
            parsed = parse_bml(data, source=str(path), limits=session.limits.parse)
        except BmlError as exc:
            errors.append(str(exc))
            continue
        plan = session.receive_bml(parsed, now=0.0, strict=strict)
        outcomes.append(ScheduledFile(path, plan, warnings_of(session.take_feedback())))

    outcomes = [
        ScheduledFile(
            o.path,
            o.plan,
            o.warnings,
            interrupted=o.plan is not None
            and session.plan(o.plan.id) is o.plan
            and session.state(o.plan.id) is BlockState.INTERRUPTED,
        )
        for o in outcomes
    ]
    return outcomes, errors


def sync_columns(plans: list[TimedPlan]) -> list[str]:
    """Sync names of a block's behaviours as table columns, in time order.

    Each behaviour lists its syncs in time order; a name's column sits at
    its mean relative position (start 0, end 1), so ``s1`` of a speech
    falls between ``start`` and ``end`` and ``stroke`` in the middle.
    """
    positions: dict[str, list[float]] = {}
    for plan in plans:
        for scheduled in plan.behaviours:
            names = list(scheduled.times)
            last = max(len(names) - 1, 1)
            for index, name in enumerate(names):
                positions.setdefault(name, []).append(index / last)
    first = {name: order for order, name in enumerate(positions)}
    return sorted(positions, key=lambda n: (sum(positions[n]) / len(positions[n]), first[n]))


def format_table(plan: TimedPlan) -> list[str]:
    """A readable table of one block: a row per behaviour, a column per sync name."""
    columns = sync_columns([plan])
    header = ["behaviour", "type", *columns]
    rows = [
        [
            scheduled.id,
            scheduled.behaviour.type,
            *(
                f"{_seconds(scheduled.times[name]):.3f}" if name in scheduled.times else "-"
                for name in columns
            ),
        ]
        for scheduled in plan.behaviours
    ]
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        text = [cells[0].ljust(widths[0]), cells[1].ljust(widths[1])]
        text += [cell.rjust(width) for cell, width in zip(cells[2:], widths[2:], strict=True)]
        return "  " + "  ".join(text)

    return [line(header), *(line(row) for row in rows)]


def _seconds(value: float) -> float:
    return round(value, JSON_DECIMALS) + 0.0  # + 0.0 turns -0.0 into 0.0


def schedule_json(outcomes: list[ScheduledFile]) -> dict[str, Any]:
    """The ``--json`` document (see the module docstring)."""
    return {
        "blocks": [
            {
                "id": outcome.plan.id,
                "start": _seconds(outcome.plan.start),
                "end": _seconds(outcome.plan.end),
                "behaviours": [
                    {
                        "id": scheduled.id,
                        "type": scheduled.behaviour.type,
                        "syncs": {name: _seconds(t) for name, t in scheduled.times.items()},
                    }
                    for scheduled in outcome.plan.behaviours
                ],
            }
            for outcome in outcomes
            if outcome.plan is not None
        ],
        "warnings": [
            {"type": note.type, "id": note.id, "message": note.message}
            for outcome in outcomes
            for note in outcome.warnings
        ],
    }


def run(args: argparse.Namespace) -> int:
    outcomes, errors = schedule_files(list(args.files), strict=args.strict)
    for error in errors:
        print(error, file=sys.stderr)
    level = "error" if args.strict else "warning"
    for outcome in outcomes:
        for note in outcome.warnings:
            print(f"{outcome.path}: {level} {note.type} {note.id}: {note.message}", file=sys.stderr)
    if args.json:
        json.dump(schedule_json(outcomes), sys.stdout, indent=2)
        print()
    else:
        for outcome in outcomes:
            plan = outcome.plan
            if plan is None:
                print(f"{outcome.path}: not scheduled")
                continue
            flag = "  (interrupted by a later REPLACE block)" if outcome.interrupted else ""
            print(f"{outcome.path}: block {plan.id}  {plan.start:.3f} s to {plan.end:.3f} s{flag}")
            for text in format_table(plan):
                print(text)
    if errors or (args.strict and any(outcome.warnings for outcome in outcomes)):
        return 2
    return 1 if any(outcome.plan is None for outcome in outcomes) else 0
