"""The scheduler's fast paths give the schedules of the plain ones.

* Whole blocks (random BML: face lexemes, heads, gestures, gazes tied by
  sync references with offsets, ``<before>``/``<after>``/``<synchronize>``
  constraints, now and then a contradiction) get the same plan from
  :func:`schedule_block` whether the solver takes the dense small-problem
  path or the sparse one: the same behaviours, the same times, the same
  warnings.
* The channel sweep (:func:`realizer.scheduler.plan._overlapping`) finds
  exactly the pairs that comparing every pair finds, touching and
  zero-length spans and the tolerance's edge included.
* The dense path needs no scipy: with scipy made unimportable, a small block
  is scheduled and a block too big for it fails with the ``schedule``
  extra's message.
"""

from __future__ import annotations

import random
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from realizer.bml_parser import BML_NS, parse_bml
from realizer.engines import EngineRegistry
from realizer.scheduler import plan as plan_module
from realizer.scheduler import solver
from realizer.scheduler.plan import (
    CHANNEL_TOLERANCE,
    SchedulingFailed,
    _overlapping,
    schedule_block,
)

REGISTRY = EngineRegistry.standard()
ROOT = Path(__file__).resolve().parents[2]

BEHAVIOURS = (
    ("faceLexeme", 'lexeme="RAISE_BROWS"', ("start", "attackPeak", "relax", "end")),
    ("faceLexeme", 'lexeme="RAISE_MOUTH_CORNERS"', ("start", "attackPeak", "relax", "end")),
    ("head", 'lexeme="NOD"', ("start", "ready", "stroke", "relax", "end")),
    ("head", 'lexeme="SHAKE"', ("start", "ready", "stroke", "relax", "end")),
    ("gesture", 'lexeme="BEAT"', ("start", "ready", "stroke", "relax", "end")),
    ("gaze", 'target="camera"', ("start", "ready", "relax", "end")),
)


def random_block(seed: int) -> str:
    chance = random.Random(seed)
    count = chance.randint(1, 10)
    lines, syncs = [], {}
    for i in range(count):
        kind, attribute, names = chance.choice(BEHAVIOURS)
        refs = []
        for name in chance.sample(names, chance.randint(0, 2)):
            if i and chance.random() < 0.7:
                other = chance.randrange(i)
                offset = chance.choice(["", "+0.5", "-0.3", "+2"])
                refs.append(f'{name}="b{other}:{chance.choice(syncs[other])}{offset}"')
            else:
                refs.append(f'{name}="{round(chance.uniform(0, 3), 2)}"')
        syncs[i] = names
        lines.append(f'<{kind} id="b{i}" {attribute} {" ".join(refs)}/>')
    for c in range(chance.randint(0, 3) if count > 1 else 0):
        a, b = chance.sample(range(count), 2)
        relation = chance.choice(["before", "after", "synchronize"])
        ref = f"b{a}:{chance.choice(syncs[a])}{chance.choice(['', '+0.5', '+1'])}"
        sync = f"b{b}:{chance.choice(syncs[b])}"
        lines.append(
            f'<constraint id="c{c}"><{relation} ref="{ref}"><sync ref="{sync}"/>'
            f"</{relation}></constraint>"
        )
    return f'<bml xmlns="{BML_NS}" id="r{seed}">' + "".join(lines) + "</bml>"


def words(message: str) -> str:
    """A warning without its times: the paths agree on them to round-off, and
    ``2.9175`` may print as 2.917 on one and 2.918 on the other."""
    return re.sub(r"\d+\.\d+", "#", message)


def outcome(text: str) -> object:
    block = parse_bml(text).block
    try:
        plan = schedule_block(block, registry=REGISTRY)
    except SchedulingFailed as failure:
        return ("failed", [words(w.message) for w in failure.warnings])
    return (
        {b.id: b.times for b in plan.behaviours},
        sorted(plan.dropped),
        [(w.type, w.id, words(w.message)) for w in plan.warnings],
    )


def same_outcome(first: object, second: object) -> None:
    if isinstance(second, tuple) and second[0] == "failed":
        assert first == second
        return
    assert isinstance(first, tuple) and isinstance(second, tuple)
    first_times, second_times = first[0], second[0]
    assert isinstance(first_times, dict) and isinstance(second_times, dict)
    assert first[1:] == second[1:]  # the same behaviours dropped, the same warnings
    assert first_times.keys() == second_times.keys()
    for behaviour, times in second_times.items():
        assert first_times[behaviour] == pytest.approx(times, abs=1e-6), behaviour


@pytest.mark.parametrize("seed", range(120))
def test_tiny_dense_and_sparse_paths_schedule_random_blocks_alike(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    text = random_block(seed)
    tiny = outcome(text)  # the tiny path where it takes the problem, else dense
    monkeypatch.setattr(solver, "TINY_KEYS", -1)  # numpy only
    dense = outcome(text)
    monkeypatch.setattr(solver, "DENSE_KEYS", -1)  # every problem takes the sparse path
    sparse = outcome(text)
    same_outcome(dense, sparse)
    same_outcome(tiny, dense)


def test_the_tiny_path_schedules_most_random_blocks() -> None:
    taken = 0
    original = solver._tiny_times

    def counted(problem: solver.Problem) -> list[float] | None:
        nonlocal taken
        times = original(problem)
        taken += times is not None
        return times

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(solver, "_tiny_times", counted)
        for seed in range(120):
            outcome(random_block(seed))
    assert taken > 40


def test_random_blocks_hold_what_the_comparison_needs() -> None:
    # Conflicts, warnings and active inequalities must all occur, or the
    # comparison above proves little.
    warned = failed = 0
    for seed in range(120):
        result = outcome(random_block(seed))
        if isinstance(result, tuple) and result[0] == "failed":
            failed += 1
        elif isinstance(result, tuple) and result[2]:
            warned += 1
    assert warned >= 10 and failed + warned < 110


def brute_force(spans: list[tuple[float, float]]) -> list[tuple[int, int]]:
    return [
        (later, earlier)
        for later in range(len(spans))
        for earlier in range(later)
        if min(spans[later][1], spans[earlier][1]) - max(spans[later][0], spans[earlier][0])
        > CHANNEL_TOLERANCE
    ]


@pytest.mark.parametrize("seed", range(200))
def test_the_channel_sweep_finds_exactly_the_overlapping_pairs(seed: int) -> None:
    chance = random.Random(seed)
    spans = []
    for _ in range(chance.randint(0, 14)):
        start = chance.choice([0.0, 1.0, 2.0, round(chance.uniform(0, 4), 1)])
        length = chance.choice([0.0, CHANNEL_TOLERANCE, 2 * CHANNEL_TOLERANCE, 1.0,
                                round(chance.uniform(0, 2), 1)])  # fmt: skip
        spans.append((start, start + length))
    assert _overlapping(spans) == brute_force(spans)


def test_a_chain_of_thousands_on_one_channel_is_swept_not_compared_pairwise() -> None:
    # 3,000 nods one after another share the head-pitch channel; none overlap.
    spans = [(float(i), float(i + 1)) for i in range(3000)]
    assert _overlapping(spans) == []
    assert plan_module._overlapping is _overlapping


SCRIPT = textwrap.dedent(
    """
    import sys

    class NoScipy:
        def find_spec(self, name, path=None, target=None):
            if name == "scipy" or name.startswith("scipy."):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, NoScipy())
    from realizer.bml_parser import BML_NS, parse_bml
    from realizer.engines import EngineRegistry
    from realizer.extras import MissingExtraError
    from realizer.scheduler.plan import schedule_block

    registry = EngineRegistry.standard()
    small = parse_bml(
        f'<bml xmlns="{BML_NS}" id="s"><head id="n" lexeme="NOD" start="1"/>'
        '<faceLexeme id="f" lexeme="RAISE_BROWS" start="n:stroke" end="n:end+1"/></bml>'
    ).block
    plan = schedule_block(small, registry=registry)
    print("small", round(plan.time_of("f", "start") - plan.time_of("n", "stroke"), 9))
    big = parse_bml(
        f'<bml xmlns="{BML_NS}" id="b">'
        + "".join(f'<head id="n{i}" lexeme="NOD" start="{i}"/>' for i in range(60))
        + "</bml>"
    ).block
    try:
        schedule_block(big, registry=registry)
    except MissingExtraError as error:
        print("big", error.extra, error.module)
    print("scipy imported:", any(m == "scipy" or m.startswith("scipy.") for m in sys.modules))
    """
)


def test_small_blocks_need_no_scipy_and_big_ones_name_the_extra() -> None:
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=120,
        check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:3] == ["small 0.0", "big schedule scipy",
                                             "scipy imported: False"]  # fmt: skip
