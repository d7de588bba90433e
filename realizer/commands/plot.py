"""``realizer plot FILE -o timeline.png``: a Gantt chart of a scheduled block.

The block is scheduled as ``realizer schedule`` does (a fresh session at time
0). One row per behaviour, labelled with its id and type; a bar from its
start to its end; a tick and a small label at every sync point. Sync points
the block ties together (sync references and ``<synchronize>``, the equality
groups of :func:`realizer.bml_parser.constraint_groups`) are joined by dashed
connectors (labelled with the offset where the points differ in time);
``<before>``/``<after>`` orderings by dotted arrows in another
colour, from the earlier to the later point. Exit status as for ``realizer
schedule``: 2 for a file that cannot be read or parsed, 1 when the block
cannot be scheduled, else 0.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from realizer.commands import plain_text

if TYPE_CHECKING:
    from realizer.bml_parser.groups import GroupMember
    from realizer.scheduler.plan import TimedPlan

#: Bar colours by behaviour type (matplotlib's colour-blind-safe tab10 tones).
TYPE_COLOURS = {
    "speech": "#1f77b4",
    "head": "#2ca02c",
    "gesture": "#9467bd",
    "faceLexeme": "#ff7f0e",
    "faceFacs": "#e377c2",
    "face": "#e377c2",
    "gaze": "#17becf",
    "posture": "#8c564b",
    "locomotion": "#8c564b",
    "pointing": "#9467bd",
    "wait": "#7f7f7f",
}
OTHER_COLOUR = "#bcbd22"
SYNC_COLOUR = "#3b3b3b"  # equality ties
ORDER_COLOUR = "#d62728"  # before/after
BAR_HEIGHT = 0.3  # in rows
LABEL_POINTS = 6.5  # font size of the sync labels
LANES = 4  # label lanes: above and below the bar, two tiers each


def label_lanes(times: dict[str, float], seconds_per_point: float) -> list[tuple[str, float, int]]:
    """Give each sync label a lane so that neighbouring labels do not overlap.

    Labels go in time order to the first lane (above, below, further above,
    further below) where the previous label has ended; a label's width is
    estimated at 0.6 em per character. When all lanes are taken, the one
    freed earliest is used.
    """
    free_from = [float("-inf")] * LANES  # seconds where each lane is free again
    placed = []
    for name, time in sorted(times.items(), key=lambda item: item[1]):
        half = 0.6 * LABEL_POINTS * len(name) * seconds_per_point / 2 + seconds_per_point
        lane = next(
            (i for i in range(LANES) if free_from[i] <= time - half),
            min(range(LANES), key=free_from.__getitem__),
        )
        free_from[lane] = time + half
        placed.append((name, time, lane))
    return placed


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "plot",
        help="draw a scheduled BML block as a Gantt chart",
        description=plain_text(__doc__.split("\n\n", 1)[1]) if __doc__ else None,
    )
    parser.add_argument("file", type=Path, metavar="FILE")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the PNG file")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from realizer.extras import require

    require("plots", "realizer plot")
    from realizer.commands.schedule import schedule_files

    outcomes, errors = schedule_files([args.file])
    for error in errors:
        print(error, file=sys.stderr)
    if errors:
        return 2
    (outcome,) = outcomes
    for note in outcome.warnings:
        print(f"{outcome.path}: warning {note.type} {note.id}: {note.message}", file=sys.stderr)
    if outcome.plan is None:
        print(f"{outcome.path}: the block cannot be scheduled; nothing drawn", file=sys.stderr)
        return 1
    ties, orders = draw_timeline(outcome.plan, args.output, subtitle=args.file.name)
    syncs = sum(len(s.times) for s in outcome.plan.behaviours)
    print(
        f"{args.output}: {len(outcome.plan.behaviours)} behaviours, {syncs} sync points, "
        f"{ties} ties, {orders} orderings"
    )
    return 0


def draw_timeline(plan: TimedPlan, output: Path, *, subtitle: str = "") -> tuple[int, int]:
    """Draw ``plan`` to a PNG; returns how many ties and orderings were drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from realizer.bml_parser import constraint_groups

    rows = {scheduled.id: index for index, scheduled in enumerate(plan.behaviours)}
    times = {scheduled.id: scheduled.times for scheduled in plan.behaviours}
    first = min([plan.start, *(s.start for s in plan.behaviours)])
    last = max(plan.end, first + 1e-3)
    span = last - first

    def where(member: GroupMember) -> tuple[float, int] | None:
        """(time, row) of a group member drawn on this chart, else None."""
        block, behaviour, sync = member.point
        if block not in (None, plan.id) or behaviour not in rows:
            return None
        name = "stroke" if sync == "stroke:1" else sync
        if name not in times[behaviour]:
            return None
        return times[behaviour][name], rows[behaviour]

    height = 1.4 + 0.8 * max(len(rows), 1)
    # Axes width is about 70 % of the 11-inch figure (the rest: labels, legend).
    seconds_per_point = (span * 1.06) / (11 * 0.7 * 72)
    figure, axes = plt.subplots(figsize=(11, height), dpi=110)
    for scheduled in plan.behaviours:
        y = rows[scheduled.id]
        colour = TYPE_COLOURS.get(scheduled.behaviour.type, OTHER_COLOUR)
        axes.barh(
            y,
            scheduled.end - scheduled.start,
            left=scheduled.start,
            height=BAR_HEIGHT,
            color=colour,
            alpha=0.55,
            edgecolor=colour,
            linewidth=1.2,
            zorder=2,
        )
        for time in scheduled.times.values():
            axes.plot([time, time], [y - BAR_HEIGHT / 2, y + BAR_HEIGHT / 2],
                      color=SYNC_COLOUR, linewidth=1.0, zorder=3)  # fmt: skip
            axes.plot(time, y, marker="o", markersize=3.5, color=SYNC_COLOUR, zorder=4)
        for name, time, lane in label_lanes(scheduled.times, seconds_per_point):
            # Lanes 0 and 2 lie above the bar (the y axis points down), 1 and 3 below.
            above = lane % 2 == 0
            tier = lane // 2
            axes.annotate(
                name,
                (time, y + (-1 if above else 1) * BAR_HEIGHT / 2),
                xytext=(0, (1 if above else -1) * (1.5 + tier * LABEL_POINTS)),
                textcoords="offset points",
                ha="center",
                va="bottom" if above else "top",
                fontsize=LABEL_POINTS,
                color="#222222",
                zorder=5,
            )
    groups, orderings = constraint_groups(plan.block)
    ties = 0
    for group in groups:
        points = sorted(
            (p for p in (where(m) for m in group.members) if p is not None),
            key=lambda p: (p[1], p[0]),
        )
        for (ta, ya), (tb, yb) in itertools.pairwise(points):
            if ya == yb and abs(ta - tb) < 1e-9:
                continue
            axes.plot([ta, tb], [ya, yb], linestyle=(0, (4, 2)), color=SYNC_COLOUR,
                      linewidth=1.1, alpha=0.8, zorder=1)  # fmt: skip
            ties += 1
            if abs(tb - ta) > 1e-6:  # a tie with an offset (``a:start+4``): say how much
                axes.annotate(
                    f"{tb - ta:+.3g} s",
                    ((ta + tb) / 2, (ya + yb) / 2),
                    ha="center",
                    va="center",
                    fontsize=LABEL_POINTS,
                    color=SYNC_COLOUR,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none"},
                    zorder=5,
                )
    orders = 0
    for ordering in orderings:
        earlier, later = where(ordering.earlier), where(ordering.later)
        if earlier is None or later is None:
            continue
        axes.annotate(
            "",
            xy=(later[0], later[1]),
            xytext=(earlier[0], earlier[1]),
            arrowprops={
                "arrowstyle": "->",
                "linestyle": (0, (1.5, 1.5)),
                "color": ORDER_COLOUR,
                "linewidth": 1.3,
                "shrinkA": 3,
                "shrinkB": 3,
            },
            zorder=1,
        )
        orders += 1
    axes.set_yticks(list(rows.values()), [f"{s.id}  ({s.behaviour.type})" for s in plan.behaviours])
    axes.set_ylim(len(rows) - 0.4, -0.6)  # first behaviour on top
    axes.set_xlim(first - 0.03 * span, last + 0.03 * span)
    axes.set_xlabel("time (s)")
    axes.grid(axis="x", color="#dddddd", linewidth=0.6, zorder=0)
    axes.set_axisbelow(True)
    title = f"block {plan.id}"
    axes.set_title(f"{title} ({subtitle})" if subtitle else title, fontsize=11)
    types = sorted({s.behaviour.type for s in plan.behaviours})
    handles: list[Any] = [
        Patch(color=TYPE_COLOURS.get(t, OTHER_COLOUR), alpha=0.55, label=t) for t in types
    ]
    handles.append(Line2D([], [], linestyle=(0, (4, 2)), color=SYNC_COLOUR, label="tied (equal)"))
    handles.append(
        Line2D(
            [], [], linestyle=(0, (1.5, 1.5)), color=ORDER_COLOUR, label="ordered (before/after)"
        )
    )
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
                frameon=False)  # fmt: skip
    figure.tight_layout()
    figure.savefig(output)
    plt.close(figure)
    return ties, orders
