"""The dense small-problem path and the sparse path of the solver give the same schedule.

Random problems hold every kind of constraint the planner makes: behaviours
of 2 to 6 sync points with weighted phases (some bounded, some rigid),
sync-point ties between behaviours, fixed times, ``<before>``/``<after>``
orderings, and, now and then, contradictions.
"""

from __future__ import annotations

import math
import random

import pytest

from realizer.scheduler import solver
from realizer.scheduler.solver import BLOCK_START, Infeasible, Problem, Source
from realizer.scheduler.timing import Phase


def random_problem(seed: int) -> Problem:
    chance = random.Random(seed)
    problem = Problem()
    keys: list[tuple[str, str]] = []
    for b in range(chance.randint(1, 8)):
        name = f"b{b}"
        syncs = tuple(f"s{i}" for i in range(chance.randint(2, 6)))
        phases = []
        for _ in syncs[1:]:
            preferred = round(chance.uniform(0.0, 1.5), 3)
            low = 0.0 if chance.random() < 0.7 else round(chance.uniform(0, preferred), 3)
            roll = chance.random()
            high = (
                math.inf
                if roll < 0.6
                else low
                if roll < 0.7
                else round(chance.uniform(max(low, preferred * 0.5), 2 * preferred + 0.1), 3)
            )
            high = max(high, low)
            phases.append(Phase(preferred, round(chance.uniform(0.2, 4.0), 3), low, high))
        source = Source("behaviour", name, chance.random() < 0.2)
        problem.add_behaviour(name, syncs, phases, source)
        keys += [(name, s) for s in syncs]
    for index in range(chance.randint(0, 5)):
        a, b = chance.sample(keys, 2) if len(keys) > 1 else (keys[0], keys[0])
        if a[0] == b[0]:
            continue
        problem.equal(a, 0.0, b, round(chance.uniform(-0.5, 0.8), 3),
                      Source("constraint", f"tie{index}"))  # fmt: skip
    for index in range(chance.randint(0, 4)):
        a, b = chance.sample(keys, 2) if len(keys) > 1 else (keys[0], keys[0])
        problem.order(a, round(chance.uniform(-0.3, 1.0), 3), b, 0.0,
                      Source("constraint", f"order{index}"))  # fmt: skip
    if chance.random() < 0.3:
        problem.fix(chance.choice(keys), round(chance.uniform(0.0, 3.0), 3),
                    Source("fixed", "f", True))  # fmt: skip
    return problem


def outcome(path: object, problem: Problem) -> dict[tuple[str, str], float] | frozenset[Source]:
    try:
        return path(problem)  # type: ignore[operator, no-any-return]
    except Infeasible as error:
        return error.conflict


@pytest.mark.parametrize("seed", range(400))
def test_dense_and_sparse_paths_agree_on_random_problems(seed: int) -> None:
    problem = random_problem(seed)
    dense = outcome(solver.solve_dense, problem)
    sparse = outcome(solver.solve_sparse, problem)
    if isinstance(sparse, frozenset):
        assert dense == sparse  # the same conflict named
        return
    assert isinstance(dense, dict)
    assert dense.keys() == sparse.keys()
    for key, time in sparse.items():
        assert dense[key] == pytest.approx(time, abs=1e-6), key


def test_both_paths_ran_feasible_and_infeasible_problems_with_active_rows() -> None:
    # The random set above is only worth something if it holds every case.
    feasible = infeasible = leaning = 0
    for seed in range(400):
        problem = random_problem(seed)
        result = outcome(solver.solve_sparse, problem)
        if isinstance(result, frozenset):
            infeasible += 1
            continue
        feasible += 1
        leaning += any(
            abs(result[r.b] + r.kb - result[r.a] - r.ka) < 1e-7 for r in problem.orderings
        )
    assert feasible > 200 and infeasible > 10 and leaning > 20


def test_solve_takes_the_dense_path_for_small_problems_and_sparse_for_big(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    taken: list[str] = []
    monkeypatch.setattr(solver, "solve_dense", lambda p: taken.append("dense") or {})
    monkeypatch.setattr(solver, "solve_sparse", lambda p: taken.append("sparse") or {})
    small, big = Problem(), Problem()
    small.add_behaviour("a", ("start", "end"), [Phase(1.0)], Source("behaviour", "a"))
    for i in range(solver.DENSE_KEYS):
        big.add_behaviour(f"b{i}", ("start", "end"), [Phase(1.0)], Source("behaviour", f"b{i}"))
    solver.solve(small)
    solver.solve(big)
    assert taken == ["dense", "sparse"]
    assert BLOCK_START in small.keys
