"""Solve time of the scheduler against the number of behaviours in a block.

Generated blocks repeat a unit of six behaviours that holds the three kinds
of structure the scheduler has to handle (Paul 2010, section 3.3):

* a cycle: three face lexemes tied start to end in a ring with a fixed
  overall span of 4 s (Paul 2010, figure 3.7), which an in-order scheduler
  cannot place and the QP solves by sharing the stretch;
* chains: every unit's ring starts at the end of the previous unit, a nod's
  stroke is tied to the ring's last relax, a beat gesture starts with the nod;
* an active inequality: a head shake starts with the beat but must end at
  least 0.5 s after the beat ends (``<after>``), which forces it to stretch,
  so the active-set method has work to do.

For 10, 100, 1,000 and 10,000 behaviours (``quick``: up to 1,000), and the
same blocks without the ``<after>`` constraints (one KKT solve, no active
set), it prints the time of :func:`realizer.scheduler.plan.schedule_block` (timing models,
problem building, solving), the time of
:func:`realizer.scheduler.solver.solve_times` (what schedule_block calls:
the times as a list) alone on the prebuilt problem, the
growth exponent fitted on log-log, and the 1,000-behaviour time against the
goal of 10 ms; then blocks of 1 to 10 behaviours against 100 us. Times are
the CPU time of the thread (:data:`_timing.CPU_CLOCK`), best of several
runs: the cost of the work, which wall time on a shared machine is not.
With active inequalities the primal-dual active-set method takes a few
sparse factorisations whatever their number; should a solver
change make the time grow much faster than linearly again, a size whose
projected time per call exceeds :data:`PROJECTED_LIMIT` is reported, not
timed. The first line says whether the tiny path (``realizer.scheduler.tiny``)
runs compiled or as Python (``REALIZER_PURE=1`` times the sources).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import CPU_CLOCK, best_of, figure

from realizer import compiled
from realizer.bml_parser import BML_NS, Block, parse_bml
from realizer.engines import EngineRegistry
from realizer.scheduler.plan import _Builder, schedule_block
from realizer.scheduler.solver import Problem, solve_times

#: The goal for a block of 1,000 behaviours with cycles (seconds).
GOAL = 0.010
#: The goal for a block of 1 to 10 behaviours (seconds): microseconds, not milliseconds.
SMALL_GOAL = 100e-6
#: The small sizes timed against :data:`SMALL_GOAL`.
SMALL_SIZES = (1, 2, 3, 6, 10)
UNIT = 6


def generated_block(behaviours: int, orderings: bool = True) -> bytes:
    """A block of ``behaviours`` behaviours: rings, chains and (``orderings``) active <after>."""
    lines = [f'<bml xmlns="{BML_NS}" id="bench">']
    constraints = []
    for i in range(behaviours):
        unit, role = divmod(i, UNIT)
        base = unit * UNIT
        previous = f"b{base - 1}:end" if unit else "0"
        if role == 0:  # the ring: a -> b -> c -> a + 4 s
            lines.append(f'  <faceLexeme id="b{i}" lexeme="RAISE_BROWS" start="{previous}"/>')
        elif role == 1:
            lines.append(f'  <faceLexeme id="b{i}" lexeme="WIDEN_EYES" start="b{i - 1}:end"/>')
        elif role == 2:
            lines.append(
                f'  <faceLexeme id="b{i}" lexeme="RAISE_MOUTH_CORNERS" start="b{i - 1}:end" '
                f'end="b{base}:start+4"/>'
            )
        elif role == 3:  # chains
            lines.append(f'  <head id="b{i}" lexeme="NOD" stroke="b{i - 1}:relax"/>')
        elif role == 4:
            lines.append(f'  <gesture id="b{i}" lexeme="BEAT" start="b{i - 1}:start"/>')
        else:  # a short shake that must outlast the beat: an active <after>
            # a shake (head yaw) beside the nod (head pitch): no channel conflict
            lines.append(f'  <head id="b{i}" lexeme="SHAKE" start="b{i - 1}:start"/>')
            if orderings:
                constraints.append(
                    f'  <constraint id="c{i}"><after ref="b{i - 1}:end+0.5">'
                    f'<sync ref="b{i}:end"/></after></constraint>'
                )
    lines += constraints
    lines.append("</bml>")
    return "\n".join(lines).encode()


def prebuilt_problem(block: Block, registry: EngineRegistry) -> Problem:
    """The problem schedule_block hands to the solver (built as it builds it)."""
    models = {b.id: registry.plan(b) for b in block.behaviours}
    return _Builder(block, 0.0, models, {}, {}, []).build(set(), set())


def check_active(block: Block, registry: EngineRegistry) -> int:
    """How many of the <after> constraints hold with equality (are active)."""
    plan = schedule_block(block, registry=registry)
    active = 0
    for constraint in block.constraints:
        (relation,) = constraint.relations
        (sync,) = relation.syncs
        assert relation.ref is not None and relation.ref.behaviour and sync.behaviour
        anchor = plan.time_of(relation.ref.behaviour, "end")
        end = plan.time_of(sync.behaviour, "end")
        assert anchor is not None and end is not None
        active += abs(end - (anchor + relation.ref.offset)) < 1e-6
    return active


#: A size is timed only when the fit of the smaller ones projects one call
#: under this many seconds, so that the default run stays near a minute.
PROJECTED_LIMIT = 8.0


def measure(
    title: str, sizes: list[int], orderings: bool, registry: EngineRegistry, quick: bool
) -> dict[int, tuple[float, float]]:
    """Time schedule_block and solve per size; print a row each and the fitted growth."""
    print(
        f"{title}\n"
        f"{'behaviours':>10} {'syncs':>7} {'active':>9} {'schedule_block':>15} {'solve':>11}"
    )
    timed: dict[int, tuple[float, float]] = {}
    for size in sizes:
        if len(timed) >= 2:
            known = sorted(timed)
            slope = math.log(timed[known[-1]][0] / timed[known[-2]][0]) / math.log(
                known[-1] / known[-2]
            )
            projected = timed[known[-1]][0] * (size / known[-1]) ** max(slope, 1.0)
            if projected > PROJECTED_LIMIT:
                print(f"{size:>10,}  not timed: projected {projected:,.0f} s per call")
                continue
        block = parse_bml(generated_block(size, orderings)).block
        problem = prebuilt_problem(block, registry)

        def solve_it(problem: Problem = problem) -> None:
            solve_times(problem)  # what schedule_block calls: times as a list

        def plan_it(block: Block = block) -> None:
            schedule_block(block, registry=registry)

        one = best_of(solve_it, repeats=1, clock=CPU_CLOCK)
        repeats = 1 if one > 0.5 else (3 if quick or one > 0.05 else 7)
        t_solve = min(one, best_of(solve_it, repeats=repeats, clock=CPU_CLOCK))
        t_plan = best_of(plan_it, repeats=repeats, clock=CPU_CLOCK)
        active = check_active(block, registry)
        timed[size] = (t_plan, t_solve)
        print(
            f"{size:>10,} {len(problem.keys):>7,} {active:>4}/{len(block.constraints):<4} "
            f"{t_plan * 1e3:>12.2f} ms {t_solve * 1e3:>8.2f} ms"
        )
    known = sorted(timed)
    logs = np.log(np.array(known, dtype=float))
    for column, name in enumerate(("schedule_block", "solve")):
        times = np.array([timed[size][column] for size in known])
        slope = float(np.polyfit(logs, np.log(times), 1)[0])
        # The last step says more about large blocks than the overall fit.
        tail = math.log(times[-1] / times[-2]) / math.log(known[-1] / known[-2])
        print(f"  growth exponent of {name}: {slope:.2f} (fit), {tail:.2f} (last two sizes)")
    return timed


def run(quick: bool = False) -> None:
    registry = EngineRegistry.standard()
    # the tiny path compiled (mypyc, scripts/build_compiled.py) or pure Python (REALIZER_PURE=1)
    print(f"compiled modules: {compiled.describe()}")
    results = {}
    for title, orderings, sizes in (
        ("rings of 3 (4 s span) and chains, one <after> per 6 behaviours, all active",
         True, [10, 100, 1000] if quick else [10, 100, 1000, 2000, 10000]),
        ("the same rings and chains without the <after> constraints",
         False, [10, 100, 1000] if quick else [10, 100, 1000, 10000]),
    ):  # fmt: skip
        results[orderings] = measure(title, sizes, orderings, registry, quick)
    for orderings, label in ((True, "with active <after>"), (False, "without inequalities")):
        t_plan, t_solve = results[orderings][1000]
        figure(
            f"1,000 behaviours with cycles, {label}: schedule_block",
            t_plan * 1e3,
            "ms",
            goal=GOAL * 1e3,
            note=f"solve alone {t_solve * 1e3:.2f} ms",
        )
    small(registry, quick)


def small(registry: EngineRegistry, quick: bool) -> None:
    """Time schedule_block on blocks of 1 to 10 behaviours against :data:`SMALL_GOAL`."""
    print("small blocks (the same rings, chains and <after>; 1 behaviour: one face lexeme)")
    for size in SMALL_SIZES:
        block = parse_bml(generated_block(size)).block

        def plan_it(block: Block = block) -> None:
            schedule_block(block, registry=registry)

        plan_it()
        seconds = best_of(plan_it, repeats=10 if quick else 40, number=20, clock=CPU_CLOCK)
        figure(
            f"schedule_block, {size} behaviour{'s' if size > 1 else ''}",
            seconds * 1e6,
            "us",
            goal=SMALL_GOAL * 1e6,
        )


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
