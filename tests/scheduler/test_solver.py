"""The scheduling QP: seed 000's cases with their numbers, and a reference QP."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from realizer.scheduler import solver
from realizer.scheduler.solver import BLOCK_START, Infeasible, Problem, Source, solve
from realizer.scheduler.timing import Phase, TimingModel, TimingModelError


def src(name: str, kind: str = "behaviour", required: bool = False) -> Source:
    return Source(kind, name, required)


def two(problem: Problem, name: str, preferred: float, weight: float = 1.0) -> None:
    problem.add_behaviour(name, ("start", "end"), [Phase(preferred, weight)], src(name))


def test_pure_shift_moves_one_behaviour_and_stretches_nothing() -> None:
    # Seed 000 figure 3.5: B's start is tied to A's end; B is shifted.
    problem = Problem()
    two(problem, "A", 3.0)
    two(problem, "B", 2.0)
    problem.equal(("B", "start"), 0.0, ("A", "end"), 0.0, src("B"))
    times = solve(problem)
    assert times[("A", "start")] == pytest.approx(0.0, abs=1e-9)
    assert times[("A", "end")] == pytest.approx(3.0, abs=1e-9)
    assert times[("B", "start")] == pytest.approx(3.0, abs=1e-9)
    assert times[("B", "end")] == pytest.approx(5.0, abs=1e-9)


def test_two_behaviours_tied_at_two_points_meet_at_the_mean() -> None:
    # Seed 000 figure 3.6 and section 3.3.3: lengths 3 and 2 give t = 2.5.
    problem = Problem()
    two(problem, "A", 3.0)
    two(problem, "B", 2.0)
    problem.equal(("A", "start"), 0.0, ("B", "start"), 0.0, src("B"))
    problem.equal(("A", "end"), 0.0, ("B", "end"), 0.0, src("B"))
    times = solve(problem)
    assert times[("A", "end")] - times[("A", "start")] == pytest.approx(2.5, abs=1e-9)
    assert times[("A", "start")] == pytest.approx(0.0, abs=1e-9)  # aligned left


@pytest.mark.parametrize(("wa", "wb"), [(1.0, 3.0), (5.0, 1.0), (0.2, 0.7)])
def test_unequal_costs_give_the_cost_weighted_optimum(wa: float, wb: float) -> None:
    problem = Problem()
    two(problem, "A", 3.0, wa)
    two(problem, "B", 2.0, wb)
    problem.equal(("A", "start"), 0.0, ("B", "start"), 0.0, src("B"))
    problem.equal(("A", "end"), 0.0, ("B", "end"), 0.0, src("B"))
    times = solve(problem)
    # d minimises wa (d - 3)^2 + wb (d - 2)^2: the seed's -b / 2a of the summed parabola.
    a = wa + wb
    b = -2 * (3.0 * wa + 2.0 * wb)
    assert times[("A", "end")] - times[("A", "start")] == pytest.approx(-b / (2 * a), abs=1e-9)


def test_chain_of_figure_3_7_balances_all_three() -> None:
    # Behaviour 1 spans A..B, behaviour 2 B..C, behaviour 3 A..C.
    p1, p2, p3 = 2.0, 3.0, 4.0
    w1, w2, w3 = 1.0, 2.0, 1.5
    problem = Problem()
    two(problem, "one", p1, w1)
    two(problem, "two", p2, w2)
    two(problem, "three", p3, w3)
    problem.equal(("two", "start"), 0.0, ("one", "end"), 0.0, src("two"))
    problem.equal(("three", "start"), 0.0, ("one", "start"), 0.0, src("three"))
    problem.equal(("three", "end"), 0.0, ("two", "end"), 0.0, src("three"))
    times = solve(problem)
    # Closed form: minimise w1(d1-p1)^2 + w2(d2-p2)^2 + w3(d1+d2-p3)^2.
    matrix = np.array([[w1 + w3, w3], [w3, w2 + w3]])
    rhs = np.array([w1 * p1 + w3 * p3, w2 * p2 + w3 * p3])
    d1, d2 = np.linalg.solve(matrix, rhs)
    assert times[("one", "end")] - times[("one", "start")] == pytest.approx(d1, abs=1e-9)
    assert times[("two", "end")] - times[("two", "start")] == pytest.approx(d2, abs=1e-9)
    # all three stretched or squeezed: none at its preferred length
    assert abs(d1 - p1) > 0.1 and abs(d2 - p2) > 0.1 and abs(d1 + d2 - p3) > 0.1


def test_a_cycle_with_a_fixed_span_is_ordinary_input() -> None:
    # a.end = b.start, b.end = c.start, c.end = a.start + 4 (examples/bml/09_cycle.xml)
    problem = Problem()
    for name in "abc":
        two(problem, name, 2.0)
    problem.fix(("a", "start"), 0.0, src("a"))
    problem.equal(("a", "end"), 0.0, ("b", "start"), 0.0, src("a"))
    problem.equal(("b", "end"), 0.0, ("c", "start"), 0.0, src("b"))
    problem.equal(("c", "end"), 0.0, ("a", "start"), 4.0, src("c"))
    times = solve(problem)
    for name in "abc":
        assert times[(name, "end")] - times[(name, "start")] == pytest.approx(4 / 3, abs=1e-9)


def test_a_fixed_time_pins_a_behaviour_without_pull() -> None:
    problem = Problem()
    problem.add_behaviour("g", ("start", "stroke", "end"), [Phase(1.0), Phase(0.5)], src("g"))
    problem.fix(("g", "stroke"), 5.0, src("g"))
    times = solve(problem)
    assert times[("g", "start")] == pytest.approx(4.0, abs=1e-9)
    assert times[("g", "end")] == pytest.approx(5.5, abs=1e-9)


def test_nothing_starts_before_the_block() -> None:
    problem = Problem()
    problem.add_behaviour("g", ("start", "stroke", "end"), [Phase(1.0), Phase(0.5)], src("g"))
    problem.fix(("g", "stroke"), 0.4, src("g"))
    times = solve(problem)
    assert times[("g", "start")] == pytest.approx(0.0, abs=1e-9)
    assert times[("g", "stroke")] == pytest.approx(0.4, abs=1e-9)


def test_contradictory_fixed_times_name_their_sources() -> None:
    problem = Problem()
    two(problem, "A", 3.0)
    problem.fix(("A", "start"), 2.0, src("A"))
    problem.fix(("A", "end"), 1.0, src("c1", "constraint"))
    with pytest.raises(Infeasible) as caught:
        solve(problem)
    assert caught.value.conflict == {src("A"), src("c1", "constraint")}


def test_orderings_that_cannot_hold_are_a_conflict() -> None:
    problem = Problem()
    for name in "AB":  # each lasts at least 0.1 s, so they cannot both come first
        problem.add_behaviour(name, ("start", "end"), [Phase(1.0, minimum=0.1)], src(name))
    problem.order(("A", "end"), 0.0, ("B", "start"), 0.0, src("c1", "constraint"))
    problem.order(("B", "end"), 0.0, ("A", "start"), 0.0, src("c2", "constraint"))
    with pytest.raises(Infeasible) as caught:
        solve(problem)
    assert {s.id for s in caught.value.conflict} >= {"c1", "c2"}


def test_phase_bounds_hold() -> None:
    problem = Problem()
    problem.add_behaviour("s", ("start", "end"), [Phase(2.0, 10.0, minimum=1.5, maximum=2.5)],
                          src("s"))  # fmt: skip
    problem.fix(("s", "end"), 6.0, src("s"))
    problem.fix(("s", "start"), 5.0, src("c", "constraint"))
    with pytest.raises(Infeasible):
        solve(problem)


def test_timing_models_reject_contradictions() -> None:
    with pytest.raises(TimingModelError):
        Phase(1.0, minimum=2.0, maximum=1.0)
    with pytest.raises(TimingModelError):
        Phase(1.0, weight=0.0)
    with pytest.raises(TimingModelError):
        TimingModel(("start", "end"), ())
    assert Phase(2.0, 3.0).quadratic == (3.0, -12.0, 12.0)


# -- against a reference QP solver (cvxopt, used in tests only) -----------------


def reference(problem: Problem) -> tuple[dict[tuple[str, str], float], bool]:
    """The same QP handed to cvxopt, with equalities kept as equalities.

    The start-early tie-break is a small linear term here, so only the phase
    durations (which the tie-break does not affect) are compared exactly.
    Returns the times and whether cvxopt reached its optimum.
    """
    cvxopt = pytest.importorskip("cvxopt")
    cvxopt.solvers.options["show_progress"] = False
    cvxopt.solvers.options["abstol"] = 1e-10
    cvxopt.solvers.options["reltol"] = 1e-10
    cvxopt.solvers.options["feastol"] = 1e-10
    keys = list(problem.keys)
    index = {k: i for i, k in enumerate(keys)}
    n = len(keys)
    hessian = np.zeros((n, n))
    linear = np.zeros(n)
    for a, b, phase, _ in problem.phases:
        i, j = index[b], index[a]
        for (p, q), sign in (((i, i), 1), ((j, j), 1), ((i, j), -1), ((j, i), -1)):
            hessian[p, q] += 2 * phase.weight * sign
        linear[i] -= 2 * phase.weight * phase.preferred
        linear[j] += 2 * phase.weight * phase.preferred
    for key in problem.starts:
        linear[index[key]] += 1e-6
    rows, bounds = [], []  # G x <= h
    for a, b, phase, _ in problem.phases:
        row = np.zeros(n)
        row[index[a]], row[index[b]] = 1, -1
        rows.append(row)
        bounds.append(-phase.minimum)
        if math.isfinite(phase.maximum):
            rows.append(-row)
            bounds.append(phase.maximum)
    for r in problem.orderings:  # t_a + ka <= t_b + kb
        row = np.zeros(n)
        row[index[r.a]], row[index[r.b]] = 1, -1
        rows.append(row)
        bounds.append(r.kb - r.ka)
    for key in keys:
        row = np.zeros(n)
        row[index[key]] = -1
        rows.append(row)
        bounds.append(0.0)
    eq_rows, eq_bounds = [], []
    for r in problem.equalities:
        row = np.zeros(n)
        row[index[r.a]] += 1
        row[index[r.b]] -= 1
        eq_rows.append(row)
        eq_bounds.append(r.kb - r.ka)
    row = np.zeros(n)
    row[index[BLOCK_START]] = 1
    eq_rows.append(row)
    eq_bounds.append(0.0)
    # cvxopt wants independent equality rows; cycles of ties repeat themselves.
    kept: list[int] = []
    for index_row in range(len(eq_rows)):
        trial = [*kept, index_row]
        if np.linalg.matrix_rank(np.array([eq_rows[i] for i in trial])) == len(trial):
            kept.append(index_row)
        elif not np.isclose(  # a dependent row must agree with the others
            np.linalg.lstsq(np.array([eq_rows[i] for i in kept]).T, eq_rows[index_row],
                            rcond=None)[0] @ np.array([eq_bounds[i] for i in kept]),
            eq_bounds[index_row],
        ):  # fmt: skip
            raise ValueError("contradictory equalities")
    eq_rows = [eq_rows[i] for i in kept]
    eq_bounds = [eq_bounds[i] for i in kept]
    m = cvxopt.matrix
    result = cvxopt.solvers.qp(
        m(hessian + 1e-12 * np.eye(n)), m(linear), m(np.array(rows)), m(np.array(bounds)),
        m(np.array(eq_rows)), m(np.array(eq_bounds)),
    )  # fmt: skip
    # "unknown" is cvxopt stopping short of its (very tight) tolerances; its
    # point is still usable when it is feasible and its gap is tiny.
    usable = result["status"] == "unknown" and (
        result["primal infeasibility"] < 1e-7 and abs(result["relative gap"]) < 1e-6
    )
    if result["status"] != "optimal" and not usable:
        raise ValueError(f"cvxopt: {result['status']}")
    x = np.array(result["x"]).ravel()
    times = {key: float(x[index[key]]) for key in keys}
    return times, result["status"] == "optimal"


def random_problem(seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    problem = Problem()
    count = int(rng.integers(3, 9))
    names = [f"b{i}" for i in range(count)]
    syncs = ("start", "ready", "stroke", "end")
    for name in names:
        phases = [
            Phase(float(rng.uniform(0.2, 2.0)), float(rng.uniform(0.1, 5.0)),
                  minimum=float(rng.uniform(0, 0.1)))
            for _ in range(3)
        ]  # fmt: skip
        problem.add_behaviour(name, syncs, phases, src(name))
    for _ in range(int(rng.integers(1, count))):  # equalities, cycles allowed
        a, b = rng.choice(names, 2, replace=False)
        problem.equal((str(a), str(rng.choice(syncs))), 0.0, (str(b), str(rng.choice(syncs))),
                      float(rng.uniform(-0.5, 0.5)), src(str(a)))  # fmt: skip
    for i in range(int(rng.integers(1, 4))):  # orderings that bind
        a, b = rng.choice(names, 2, replace=False)
        problem.order((str(a), "end"), float(rng.uniform(0, 1)), (str(b), "start"), 0.0,
                      src(f"c{i}", "constraint"))  # fmt: skip
    if rng.random() < 0.5:
        problem.fix((names[0], "stroke"), float(rng.uniform(1, 4)), src(names[0]))
    return problem


def durations(times: dict[tuple[str, str], float], problem: Problem) -> np.ndarray:
    return np.array([times[b] - times[a] for a, b, _, _ in problem.phases])


def cost(times: dict[tuple[str, str], float], problem: Problem) -> float:
    return sum(p.cost(times[b] - times[a]) for a, b, p, _ in problem.phases)


@pytest.mark.parametrize("seed", range(40))
def test_random_problems_match_a_reference_qp(seed: int) -> None:
    problem = random_problem(seed)
    try:
        ours = solve(problem)
    except Infeasible:
        with pytest.raises(ValueError):  # cvxopt finds no optimum either
            reference(problem)
        return
    theirs, exact = reference(problem)
    if exact:
        assert cost(ours, problem) == pytest.approx(cost(theirs, problem), abs=1e-6)
        np.testing.assert_allclose(durations(ours, problem), durations(theirs, problem), atol=1e-5)
    else:  # cvxopt stopped short: ours must be at least as good
        assert cost(ours, problem) <= cost(theirs, problem) + 1e-6
    # every constraint holds
    for r in problem.orderings:
        assert ours[r.a] + r.ka <= ours[r.b] + r.kb + 1e-7
    for r in problem.equalities:
        assert ours[r.a] + r.ka == pytest.approx(ours[r.b] + r.kb, abs=1e-7)
    assert min(ours.values()) >= -1e-9


def test_random_problems_include_binding_inequalities() -> None:
    binding = 0
    for seed in range(40):
        problem = random_problem(seed)
        try:
            times = solve(problem)
        except Infeasible:
            continue
        binding += any(abs(times[r.a] + r.ka - times[r.b] - r.kb) < 1e-7 for r in problem.orderings)
    assert binding >= 10


def test_all_pairs_of_small_shift_problems_are_left_aligned() -> None:
    for a, b in itertools.product([0.5, 1.0, 2.0], repeat=2):
        problem = Problem()
        two(problem, "A", a)
        two(problem, "B", b)
        problem.equal(("B", "end"), 0.0, ("A", "end"), 0.0, src("B"))
        times = solve(problem)
        assert min(times.values()) == pytest.approx(0.0, abs=1e-9)
        assert times[("A", "end")] == pytest.approx(max(a, b), abs=1e-9)


# -- the primal-dual active set, its fallback, and equality elimination ---------


def crowded_problem(seed: int, count: int = 30) -> Problem:
    """Chains and rings of behaviours with many orderings, most of them binding."""
    rng = np.random.default_rng(1000 + seed)
    problem = Problem()
    syncs = ("start", "ready", "stroke", "relax", "end")
    names = [f"b{i}" for i in range(count)]
    for name in names:
        phases = [Phase(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.5, 3.0)))
                  for _ in range(4)]  # fmt: skip
        problem.add_behaviour(name, syncs, phases, src(name))
    for i in range(1, count):  # a chain: each starts at the previous stroke
        problem.equal((names[i], "start"), 0.0, (names[i - 1], "stroke"), 0.0, src(names[i]))
    for i in range(0, count - 2, 3):  # rings: an end tied to a later ready
        problem.equal((names[i], "end"), 0.0, (names[i + 2], "ready"), 0.0, src(names[i]))
    for i in range(int(rng.integers(count // 3, count))):  # orderings, many binding
        a, b = rng.choice(count, 2, replace=False)
        problem.order((names[a], "end"), float(rng.uniform(0, 0.5)), (names[b], "relax"), 0.0,
                      src(f"c{i}", "constraint"))  # fmt: skip
    return problem


def check_against_reference(problem: Problem, ours: dict[tuple[str, str], float]) -> None:
    theirs, exact = reference(problem)
    if exact:
        assert cost(ours, problem) == pytest.approx(cost(theirs, problem), abs=1e-6)
    else:
        assert cost(ours, problem) <= cost(theirs, problem) + 1e-6
    for r in problem.orderings:
        assert ours[r.a] + r.ka <= ours[r.b] + r.kb + 1e-7
    for r in problem.equalities:
        assert ours[r.a] + r.ka == pytest.approx(ours[r.b] + r.kb, abs=1e-7)
    for a, b, phase, _ in problem.phases:
        assert ours[b] - ours[a] >= phase.minimum - 1e-7
    assert min(ours.values()) >= -1e-9


@pytest.mark.parametrize("seed", range(12))
def test_crowded_problems_match_a_reference_qp(seed: int) -> None:
    problem = crowded_problem(seed)
    try:
        ours = solve(problem)
    except Infeasible:
        with pytest.raises(ValueError):
            reference(problem)
        return
    check_against_reference(problem, ours)


@pytest.mark.parametrize("seed", range(6))
def test_the_fallback_active_set_gives_the_same_optimum(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    problem = crowded_problem(seed)
    try:
        fast = solve(problem)
    except Infeasible:
        return
    monkeypatch.setattr(solver, "PDAS_STEPS", 0)  # the primal-dual method gives up at once
    slow = solve(problem)
    assert cost(slow, problem) == pytest.approx(cost(fast, problem), abs=1e-7)
    check_against_reference(problem, slow)


def test_crowded_problems_bind_many_orderings_at_once() -> None:
    # The point of the primal-dual method: several rows enter per solve.
    binding = []
    for seed in range(12):
        problem = crowded_problem(seed)
        try:
            times = solve(problem)
        except Infeasible:
            continue
        binding.append(
            sum(abs(times[r.a] + r.ka - times[r.b] - r.kb) < 1e-7 for r in problem.orderings)
        )
    assert max(binding) >= 5


def chained_rings(count: int) -> Problem:
    """Seven-point behaviours in a chain with rings; many phases want to go negative."""
    rng = np.random.default_rng(count)
    problem = Problem()
    syncs = ("start", "ready", "stroke", "relax", "end")
    for i in range(count):
        phases = [Phase(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.5, 2.0)))
                  for _ in range(4)]  # fmt: skip
        problem.add_behaviour(f"b{i}", syncs, phases, src(f"b{i}"))
    for i in range(1, count):
        problem.equal((f"b{i}", "start"), 0.0, (f"b{i - 1}", "stroke"), 0.0, src(f"b{i}"))
    for i in range(0, count - 3, 3):
        problem.equal((f"b{i}", "end"), 0.0, (f"b{i + 2}", "ready"), 0.0, src(f"b{i}"))
    return problem


@pytest.mark.parametrize("count", [50, 300, 1000])
def test_degenerate_bounds_do_not_make_the_primal_dual_method_cycle(
    count: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Rows that are active with a zero multiplier used to leave the working
    # set, come back violated by 1e-8 and leave again (seen at 1,000).
    def no_fallback(*args: object) -> None:
        raise AssertionError("the primal-dual method should have finished")

    problem = chained_rings(count)
    monkeypatch.setattr(solver, "_active_set", no_fallback)
    times = solve(problem)
    for a, b, phase, _ in problem.phases:
        assert times[b] - times[a] >= phase.minimum - 1e-7
    # some phase is squeezed to its bound: the active-set path ran
    assert any(abs(times[b] - times[a]) < 1e-9 for a, b, _, _ in problem.phases)
    if count <= 50:
        check_against_reference(problem, times)


def test_long_chains_of_ties_get_their_offsets() -> None:
    # 200 behaviours tied end to start with offsets, in scrambled order.
    problem = Problem()
    count = 200
    for i in range(count):
        two(problem, f"b{i}", 1.0)
    order = np.random.default_rng(7).permutation(count - 1)
    for i in order.tolist():
        problem.equal((f"b{i + 1}", "start"), 0.0, (f"b{i}", "end"), 0.25, src(f"b{i + 1}"))
    times = solve(problem)
    for i in range(count):
        assert times[(f"b{i}", "start")] == pytest.approx(1.25 * i, abs=1e-9)


def test_a_ring_of_ties_that_does_not_close_is_a_conflict() -> None:
    problem = Problem()
    for name in "abc":
        two(problem, name, 1.0)
    problem.equal(("b", "start"), 0.0, ("a", "start"), 1.0, src("x", "constraint"))
    problem.equal(("c", "start"), 0.0, ("b", "start"), 1.0, src("y", "constraint"))
    problem.equal(("a", "start"), 0.0, ("c", "start"), 1.0, src("z", "constraint"))
    with pytest.raises(Infeasible) as caught:
        solve(problem)
    assert {s.id for s in caught.value.conflict} == {"x", "y", "z"}


def closed_form(problem: Problem) -> dict[tuple[str, str], float]:
    """The equality-constrained optimum from one dense KKT system (numpy, no bounds)."""
    keys = list(problem.keys)
    index = {k: i for i, k in enumerate(keys)}
    n = len(keys)
    hessian = np.zeros((n, n))
    linear = np.zeros(n)
    for a, b, phase, _ in problem.phases:
        i, j = index[b], index[a]
        hessian[i, i] += 2 * phase.weight
        hessian[j, j] += 2 * phase.weight
        hessian[i, j] -= 2 * phase.weight
        hessian[j, i] -= 2 * phase.weight
        linear[i] -= 2 * phase.weight * phase.preferred
        linear[j] += 2 * phase.weight * phase.preferred
    rows = []
    rhs = []
    for r in problem.equalities:
        row = np.zeros(n)
        row[index[r.a]] += 1
        row[index[r.b]] -= 1
        rows.append(row)
        rhs.append(r.kb - r.ka)
    row = np.zeros(n)
    row[index[BLOCK_START]] = 1
    rows.append(row)
    rhs.append(0.0)
    tie = np.array(rows)
    kkt = np.block([[hessian, tie.T], [tie, np.zeros((len(rows), len(rows)))]])
    # Cycles of ties repeat rows: least squares gives the consistent solution.
    solution = np.linalg.lstsq(kkt, np.concatenate([-linear, rhs]), rcond=None)[0]
    return {key: float(solution[index[key]]) for key in keys}


@pytest.mark.parametrize("seed", range(20))
def test_equality_only_problems_equal_the_closed_form_to_1e_9(seed: int) -> None:
    # Every behaviour is tied to a fixed time (so no start-early pull acts)
    # and ties roughly agree with the preferred lengths (so no bound is
    # active): the optimum is the closed form of the equality-constrained QP.
    rng = np.random.default_rng(500 + seed)
    problem = Problem()
    syncs = ("start", "ready", "stroke", "end")
    count = int(rng.integers(3, 9))
    natural: dict[tuple[str, str], float] = {}  # each sync's time at preferred lengths
    for i in range(count):
        lengths = [float(x) for x in rng.uniform(0.5, 2.0, 3)]
        start = float(rng.uniform(5.0, 8.0))
        for sync, offset in zip(syncs, np.concatenate([[0.0], np.cumsum(lengths)]), strict=True):
            natural[(f"b{i}", sync)] = start + float(offset)
        problem.add_behaviour(
            f"b{i}", syncs, [Phase(p, float(rng.uniform(0.2, 5.0))) for p in lengths], src(f"b{i}")
        )
        problem.fix((f"b{i}", "start"), start, src(f"b{i}"))
    # Ties that nearly hold at the natural times. Cycles through phases are
    # plenty (every behaviour is fixed); a cycle of ties alone would only
    # close by chance, so a tie inside one class of tied points is skipped.
    tied: dict[tuple[str, str], tuple[str, str]] = {}

    def root(key: tuple[str, str]) -> tuple[str, str]:
        while tied.get(key, key) != key:
            key = tied[key]
        return key

    for i in range(count):
        tied[(f"b{i}", "start")] = BLOCK_START
    for _ in range(2 * count):
        a, b = rng.choice(count, 2, replace=False)
        sa, sb = (syncs[int(k)] for k in rng.integers(1, 4, 2))
        ka, kb = root((f"b{a}", sa)), root((f"b{b}", sb))
        if ka == kb:
            continue
        tied[ka] = kb
        offset = natural[(f"b{b}", sb)] - natural[(f"b{a}", sa)] + float(rng.uniform(-0.2, 0.2))
        problem.equal((f"b{a}", sa), offset, (f"b{b}", sb), 0.0, src(f"b{a}"))
    expected = closed_form(problem)
    durations_expected = durations(expected, problem)
    if durations_expected.min() <= 0.01 or min(expected.values()) < -1e-12:
        pytest.skip("a bound would be active; the closed form does not apply")
    ours = solve(problem)
    np.testing.assert_allclose(durations(ours, problem), durations_expected, rtol=0, atol=1e-9)
    for key, time in expected.items():
        assert ours[key] == pytest.approx(time, abs=1e-9)
