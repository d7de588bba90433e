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

from realizer.scheduler import solver, tiny
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


def test_solve_tries_the_tiny_path_then_dense_for_small_problems_and_sparse_for_big(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    taken: list[str] = []
    monkeypatch.setattr(solver, "_tiny_times", lambda p: taken.append("tiny"))  # declines
    monkeypatch.setattr(solver, "solve_dense", lambda p: taken.append("dense") or {})
    monkeypatch.setattr(solver, "solve_sparse", lambda p: taken.append("sparse") or {})
    small, big = Problem(), Problem()
    small.add_behaviour("a", ("start", "end"), [Phase(1.0)], Source("behaviour", "a"))
    for i in range(solver.DENSE_KEYS):
        big.add_behaviour(f"b{i}", ("start", "end"), [Phase(1.0)], Source("behaviour", f"b{i}"))
    solver.solve(small)
    solver.solve(big)
    assert taken == ["tiny", "dense", "sparse"]
    assert BLOCK_START in small.keys


# -- the pure-Python path for tiny problems ------------------------------------------


def pinned_problem(seed: int) -> Problem:
    """A random problem whose every behaviour is tied to the block start.

    The behaviours of :func:`random_problem`, each started at a fixed time
    or at a point of an earlier one, and orderings between random points.
    With no free group, the tiny path also runs its active-set method
    (beside free groups it leaves active inequalities to numpy), so these
    problems are where its orderings and squeezed phases are tested.
    """
    chance = random.Random(seed)
    problem = Problem()
    keys: list[tuple[str, str]] = []
    for behaviour_id, syncs, phases, source, _ in random_problem(seed)._chains:
        problem.add_behaviour(behaviour_id, syncs, phases, source)
        start = (behaviour_id, syncs[0])
        if keys and chance.random() < 0.6:
            problem.equal(start, 0.0, chance.choice(keys), round(chance.uniform(0.0, 0.6), 3),
                          source)  # fmt: skip
        else:
            problem.fix(start, round(chance.uniform(0.0, 2.0), 3),
                        Source("fixed", behaviour_id, True))  # fmt: skip
        keys += [(behaviour_id, sync) for sync in syncs]
    for index in range(chance.randint(1, 5) if len(keys) > 2 else 0):
        a, b = chance.sample(keys, 2)
        problem.order(a, round(chance.uniform(-0.3, 1.0), 3), b, 0.0,
                      Source("constraint", f"order{index}"))  # fmt: skip
    return problem


@pytest.mark.parametrize("make", [random_problem, pinned_problem])
@pytest.mark.parametrize("seed", range(300))
def test_the_tiny_path_gives_the_dense_paths_times_or_declines(seed: int, make: object) -> None:
    problem = make(seed)  # type: ignore[operator]
    dense = outcome(solver.solve_dense, problem)
    tiny = solver.solve_tiny(problem)
    if isinstance(dense, frozenset):
        assert tiny is None  # conflicts are named by the numpy path
        return
    if tiny is None:
        return
    assert tiny.keys() == dense.keys()
    for key, time in dense.items():
        assert tiny[key] == pytest.approx(time, abs=1e-6), key


def test_the_tiny_path_took_most_feasible_problems_with_active_rows_and_squeezed_phases() -> None:
    taken = leaning = squeezed = feasible = 0
    for seed in range(300):
        for make in (random_problem, pinned_problem):
            problem = make(seed)
            if isinstance(outcome(solver.solve_dense, problem), frozenset):
                continue
            feasible += 1
            tiny = solver.solve_tiny(problem)
            if tiny is None:
                continue
            taken += 1
            leaning += any(
                abs(tiny[r.b] + r.kb - tiny[r.a] - r.ka) < 1e-7 for r in problem.orderings
            )
            squeezed += any(
                abs(tiny[b] - tiny[a] - phase.minimum) < 1e-7 < phase.preferred - phase.minimum
                for a, b, phase, _ in problem.phases
            )
    assert taken > feasible // 3 and leaning > 30 and squeezed > 20, (taken, leaning, squeezed)


def test_a_chain_held_at_its_ends_is_one_spring_in_series() -> None:
    phases = (Phase(0.5, 2.0), Phase(1.0, 0.5), Phase(0.3, 1.0, 0.1, 0.6), Phase(0.2))
    kept, springs, inner, checked = solver._chain_plan(phases, (3,))
    assert kept == (0, 3)
    ((u, v, length, weight, low, high),) = springs
    assert (u, v) == (0, 3) and length == pytest.approx(1.8)
    assert weight == pytest.approx(1 / (1 / 2.0 + 1 / 0.5 + 1 / 1.0))
    assert (low, high) == (pytest.approx(0.1), math.inf)
    # inner points share the stretch by compliance; the tail keeps its length
    assert inner[0][:3] == (1, 0, 3) and inner[0][3] == pytest.approx(0.5)
    assert inner[0][4] == pytest.approx(0.5 / 3.5)
    assert inner[-1][:3] == (4, 3, -1) and inner[-1][3] == pytest.approx(0.2)
    assert [p for p, _, _ in checked] == [0, 1, 2, 3]
    assert checked[2][1:] == (pytest.approx(0.1), pytest.approx(0.6))  # the bounds, checked
    # cached: asked again, the plan is not made again (compiled, the module
    # hands out equal tuples, not the same object)
    made = len(tiny._CHAIN_PLANS)
    assert solver._chain_plan(phases, (3,)) == solver._chain_plan(phases, (3,))
    assert len(tiny._CHAIN_PLANS) == made
    rigid = (Phase(0.5), Phase(0.4, 1.0, 0.4, 0.4), Phase(0.5))
    assert solver._chain_plan(rigid, ())[0] == (0, 1, 2)  # a rigid phase is a tie: kept


# -- band solves on the sparse path ----------------------------------------------------


def test_band_solves_equal_superlu_and_decline_wide_or_singular_systems() -> None:
    sp = pytest.importorskip("scipy.sparse")
    spla = pytest.importorskip("scipy.sparse.linalg")
    np = pytest.importorskip("numpy")
    chance = np.random.default_rng(7)
    size = 300
    # A shuffled chain Laplacian plus a diagonal: definite, bandwidth 1 once reordered.
    order = chance.permutation(size)
    weight = chance.uniform(0.1, 3.0, size - 1)
    rows = np.concatenate([order[:-1], order[1:], order[:-1], order[1:], order])
    cols = np.concatenate([order[1:], order[:-1], order[:-1], order[1:], order])
    data = np.concatenate([-weight, -weight, weight, weight, np.full(size, 1e-3)])
    hessian = sp.csc_matrix((data, (rows, cols)), shape=(size, size))
    rhs = chance.normal(size=size)
    banded = solver._band_solve(hessian, rhs, definite=True)
    assert banded is not None
    np.testing.assert_allclose(banded, spla.splu(hessian).solve(rhs), atol=1e-8)
    # A KKT system with two held rows (indefinite).
    held = sp.csr_matrix(([1.0, -1.0, 1.0], ([0, 0, 1], [order[3], order[9], order[20]])),
                         shape=(2, size))  # fmt: skip
    kkt = sp.bmat([[hessian, -held.T], [held, None]], format="csc")
    rhs2 = np.concatenate([rhs, [0.5, 1.0]])
    banded = solver._band_solve(kkt, rhs2, definite=False)
    assert banded is not None
    np.testing.assert_allclose(banded, spla.splu(kkt).solve(rhs2), atol=1e-8)
    # A star (every point tied to one): too wide for a band, SuperLU decides.
    star = sp.csc_matrix(
        (np.concatenate([np.full(size - 1, -1.0), np.full(size - 1, -1.0), np.full(size, 2.0)]),
         (np.concatenate([np.zeros(size - 1, int), np.arange(1, size), np.arange(size)]),
          np.concatenate([np.arange(1, size), np.zeros(size - 1, int), np.arange(size)]))),
        shape=(size, size),
    )  # fmt: skip
    assert solver._band_solve(star, rhs, definite=True) is None
    # Singular (a Laplacian without the diagonal): declined, not a wrong answer.
    singular = sp.csc_matrix((data[:-size], (rows[:-size], cols[:-size])), shape=(size, size))
    assert solver._band_solve(singular, rhs, definite=True) is None


@pytest.mark.parametrize("seed", range(60))
def test_the_sparse_path_gives_the_same_times_with_and_without_band_solves(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    problem = random_problem(seed) if seed % 2 else pinned_problem(seed)
    banded = outcome(solver.solve_sparse, problem)
    monkeypatch.setattr(solver, "BAND_LIMIT", -1)  # SuperLU for every system
    plain = outcome(solver.solve_sparse, problem)
    if isinstance(plain, frozenset):
        assert banded == plain
        return
    assert isinstance(banded, dict)
    for key, time in plain.items():
        assert banded[key] == pytest.approx(time, abs=1e-6), key


# -- the working rows held as ties (one band Cholesky instead of a KKT LU) ---------------


def test_tied_kkt_equals_the_kkt_lu_and_declines_cycles_and_other_rows(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sp = pytest.importorskip("scipy.sparse")
    np = pytest.importorskip("numpy")
    chance = np.random.default_rng(11)
    size = 40
    order = chance.permutation(size)
    weight = chance.uniform(0.1, 3.0, size - 1)
    rows = np.concatenate([order[:-1], order[1:], order[:-1], order[1:], order])
    cols = np.concatenate([order[1:], order[:-1], order[:-1], order[1:], order])
    data = np.concatenate([-weight, -weight, weight, weight, np.full(size, 1e-3)])
    hessian = sp.csc_matrix((data, (rows, cols)), shape=(size, size))
    gradient = chance.normal(size=size)
    # x3 - x9 >= 0.5, x20 >= 1 (the zero node), x9 - x30 >= -0.2, x3 - x30 >= 0 (a cycle
    # with the first and third), and a row that is no difference (2 x5 >= 0).
    matrix = sp.csr_matrix(
        ([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0, 2.0],
         ([0, 0, 1, 2, 2, 3, 3, 4], [3, 9, 20, 9, 30, 3, 30, 5])),
        shape=(5, size),
    )  # fmt: skip
    b = np.array([0.5, 1.0, -0.2, 0.0, 0.0])
    working = [0, 1, 2]
    tied = solver._tied_kkt(hessian, gradient, matrix, working, b)
    assert tied is not None
    monkeypatch.setattr(solver, "_tied_kkt", lambda *args: None)  # the KKT LU
    x, lam = solver._kkt(hessian, gradient, matrix, working, b)
    assert x is not None and lam is not None
    np.testing.assert_allclose(tied[0], x, atol=1e-9)
    np.testing.assert_allclose(tied[1], lam, atol=1e-9)
    np.testing.assert_allclose(matrix[working] @ tied[0], b[working], atol=1e-12)
    monkeypatch.undo()
    assert solver._tied_kkt(hessian, gradient, matrix, [0, 2, 3], b) is None  # dependent
    assert solver._tied_kkt(hessian, gradient, matrix, [0, 4], b) is None  # 2 x5
    # Both declined systems still get the KKT LU's answer through _kkt.
    x, _ = solver._kkt(hessian, gradient, matrix, [0, 4], b)
    assert x is not None and x[5] == pytest.approx(0.0, abs=1e-9)


def test_the_sparse_path_gives_the_same_times_with_and_without_tied_kkt(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    tied = solver._tied_kkt
    taken = 0

    def counting(*args: object) -> object:
        nonlocal taken
        result = tied(*args)  # type: ignore[arg-type]
        taken += result is not None
        return result

    for seed in range(400):
        problem = random_problem(seed)
        monkeypatch.setattr(solver, "_tied_kkt", counting)
        with_ties = outcome(solver.solve_sparse, problem)
        monkeypatch.setattr(solver, "_tied_kkt", lambda *args: None)
        plain = outcome(solver.solve_sparse, problem)
        if isinstance(plain, frozenset):
            assert with_ties == plain, seed  # the same conflict named
            continue
        assert isinstance(with_ties, dict)
        for key, time in plain.items():
            assert with_ties[key] == pytest.approx(time, abs=1e-6), (seed, key)
    assert taken > 40  # the tied solve ran, not only its fallback
