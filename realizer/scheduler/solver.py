"""The scheduling optimisation: one quadratic programme over sync point times.

Paul 2010, section 3.3: sync points are lined up by shifting behaviours and by
scaling their phases, and interlocked behaviours share the stretch through
quadratic cost functions whose sum is minimised; SmartBody's in-order
scheduler cannot handle circular dependencies, this one treats cycles as
ordinary input.

The problem (all times in seconds, relative to the block start, which is 0):

* variables: the time ``t_k`` of every sync point ``k = (behaviour, sync)``;
* equalities ``t_a + k_a = t_b + k_b`` (sync references, ``<synchronize>``,
  times fixed because they are already consumed);
* inequalities ``t_a + k_a <= t_b + k_b`` (``<before>``, ``<after>``),
  phase bounds ``minimum <= t_next - t_prev <= maximum`` (canonical order,
  durations never negative), and ``t_k >= 0`` (nothing before the block);
* objective: the sum of the phase costs ``w (t_next - t_prev - preferred)^2``
  and, as a tie-breaker, a preference for starting early (Paul 2010: "it is
  better to align left").

Every constraint is a difference constraint, which the solver uses twice:
equalities are eliminated up front (connected components of the ties, with
offsets along a breadth-first forest, :func:`_eliminate`), and when the
constraints cannot all hold, a negative cycle in the constraint graph
(Bellman-Ford) names exactly the constraints that conflict.

The start preference is a small quadratic pull (``PULL`` times the mean
phase weight) towards 0 on one start of each group of behaviours that no
fixed time holds. Shifting such a group changes no phase cost, so the pull
only decides the shift; the group is then moved so that its earliest sync
point is at the block start, and once inequalities are involved, the final
working set is solved again without the pull. Groups tied to a fixed time
get no pull, so the result is exactly the optimum of the phase costs.

The QP is solved on the sparse KKT system. Most blocks need one solve: the
optimum without inequalities, each free group shifted to start at 0, already
meets every inequality. Otherwise the primal-dual active-set method
(Hintermüller, Ito and Kunisch 2002) holds every row it predicts active at
once, so an optimum that leans on hundreds of bounds takes a handful of
sparse solves; working rows are kept linearly independent by taking a
spanning forest of them (every row is an edge between two times). Should it
cycle, the primal active-set method (Nocedal and Wright, algorithm 16.3),
which adds one row per step and always ends, takes over from a feasible
point that shortest paths over the difference constraints provide (no such
point: a negative cycle, and so a conflict).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from realizer.errors import RealizerError
from realizer.extras import missing_module
from realizer.scheduler.timing import Phase

try:  # scipy is the [schedule] extra: the core install has none
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from scipy.linalg.lapack import dgesv as _dgesv
    from scipy.sparse.csgraph import (
        NegativeCycleError,
        breadth_first_order,
        connected_components,
        shortest_path,
    )
except ModuleNotFoundError as _error:
    raise missing_module(_error, "schedule", "the scheduler (realizer.scheduler)") from _error

#: A sync point: (behaviour id, sync name). ``BLOCK_START`` is time 0.
Key = tuple[str, str]
BLOCK_START: Key = ("bml", "start")

#: Weight of the start-early pull relative to the mean phase weight.
PULL = 1e-3
#: Constraint tolerance, seconds.
TOLERANCE = 1e-9
#: Steps the primal-dual active-set method may take before the fallback.
PDAS_STEPS = 50


@dataclass(frozen=True, slots=True)
class Source:
    """Where a constraint comes from, so that a conflict can be explained.

    ``kind`` is ``behaviour`` (its own sync attributes and phases),
    ``constraint`` (a ``<constraint>`` element; ``id`` its id or position),
    ``fixed`` (a time already consumed) or ``block`` (nothing before the block).
    """

    kind: str
    id: str
    required: bool = False

    def __str__(self) -> str:
        return f"{self.kind} {self.id}" if self.id else self.kind


BLOCK_SOURCE = Source("block", "", required=True)


class SchedulingError(RealizerError):
    """The solver could not find a schedule."""


class Infeasible(SchedulingError):
    """The constraints contradict each other; ``conflict`` names their sources."""

    def __init__(self, conflict: frozenset[Source], detail: str) -> None:
        super().__init__(detail)
        self.conflict = conflict
        self.detail = detail


@dataclass(slots=True)
class _Relation:
    a: Key
    ka: float
    b: Key
    kb: float
    source: Source


@dataclass(slots=True)
class Problem:
    """Sync points, phases and constraints of one block (or several)."""

    keys: dict[Key, None] = field(default_factory=dict)
    phases: list[tuple[Key, Key, Phase, Source]] = field(default_factory=list)
    equalities: list[_Relation] = field(default_factory=list)
    orderings: list[_Relation] = field(default_factory=list)
    starts: list[Key] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.keys.setdefault(BLOCK_START, None)

    def add_behaviour(
        self, behaviour_id: str, syncs: tuple[str, ...], phases: Iterable[Phase], source: Source
    ) -> None:
        """A behaviour's sync points in order and the phases between them."""
        keys = [(behaviour_id, sync) for sync in syncs]
        phases = tuple(phases)
        if len(phases) != len(keys) - 1:
            raise ValueError(f"{len(keys)} sync points need {len(keys) - 1} phases")
        self.keys.update(dict.fromkeys(keys))  # known keys keep their place
        self.starts.append(keys[0])
        self.phases.extend(zip(keys, keys[1:], phases, itertools.repeat(source)))

    def equal(self, a: Key, ka: float, b: Key, kb: float, source: Source) -> None:
        """``t_a + ka == t_b + kb``."""
        self.keys.setdefault(a, None)
        self.keys.setdefault(b, None)
        self.equalities.append(_Relation(a, ka, b, kb, source))

    def order(self, a: Key, ka: float, b: Key, kb: float, source: Source) -> None:
        """``t_a + ka <= t_b + kb``."""
        self.keys.setdefault(a, None)
        self.keys.setdefault(b, None)
        self.orderings.append(_Relation(a, ka, b, kb, source))

    def fix(self, key: Key, time: float, source: Source) -> None:
        """``t_key == time`` (seconds after the block start)."""
        self.equal(key, 0.0, BLOCK_START, time, source)


# -- difference constraints and conflicts ------------------------------------


def _edges(problem: Problem) -> list[tuple[Key, Key, float, Source]]:
    """Every constraint as ``t_v - t_u <= w``: an edge u -> v of weight w."""
    edges: list[tuple[Key, Key, float, Source]] = []
    for r in problem.equalities:
        edges.append((r.b, r.a, r.kb - r.ka, r.source))
        edges.append((r.a, r.b, r.ka - r.kb, r.source))
    for r in problem.orderings:
        edges.append((r.b, r.a, r.kb - r.ka, r.source))
    for a, b, phase, source in problem.phases:
        edges.append((b, a, -phase.minimum, source))
        if math.isfinite(phase.maximum):
            edges.append((a, b, phase.maximum, source))
    for key in problem.keys:
        if key != BLOCK_START:
            edges.append((key, BLOCK_START, 0.0, BLOCK_SOURCE))
    return edges


def find_conflict(problem: Problem) -> frozenset[Source] | None:
    """The sources of a set of constraints that cannot hold together, or None.

    Bellman-Ford from a virtual source; a negative cycle in the graph of
    difference constraints is an irreducible conflict.
    """
    edges = _edges(problem)
    distance = dict.fromkeys(problem.keys, 0.0)
    parent: dict[Key, tuple[Key, Source]] = {}
    last: Key | None = None
    for _ in range(len(distance) + 1):
        last = None
        for u, v, w, source in edges:
            candidate = distance[u] + w
            if candidate < distance[v] - TOLERANCE:
                distance[v] = candidate
                parent[v] = (u, source)
                last = v
        if last is None:
            return None
    assert last is not None
    node = last
    for _ in range(len(distance)):  # walk back into the cycle
        node = parent[node][0]
    cycle: set[Source] = set()
    start = node
    while True:
        previous, source = parent[node]
        cycle.add(source)
        node = previous
        if node == start:
            break
    return frozenset(cycle)


# -- the QP ----------------------------------------------------------------------


#: Problems with at most this many sync points take the dense path
#: (:func:`solve_dense`): below it, building scipy.sparse objects costs more
#: than the dense linear algebra they would save.
DENSE_KEYS = 160


def solve(problem: Problem) -> dict[Key, float]:
    """The optimal time of every sync point, seconds after the block start.

    Raises :class:`Infeasible` with the conflicting sources when the
    constraints cannot all hold. Small problems (up to :data:`DENSE_KEYS`
    sync points) take :func:`solve_dense`, the others :func:`solve_sparse`;
    both give the same times.
    """
    if len(problem.keys) <= DENSE_KEYS:
        return solve_dense(problem)
    return solve_sparse(problem)


def solve_sparse(problem: Problem) -> dict[Key, float]:
    """:func:`solve` on sparse matrices, vectorised: the path for big blocks."""
    keys = list(problem.keys)
    key_index = {key: index for index, key in enumerate(keys)}
    # One pass over the phases and one over the equalities (Python loops
    # over thousands of tuples are a large part of a solve).
    table = np.array(
        [(key_index[a], key_index[b], p.weight, p.preferred, p.minimum, p.maximum)
         for a, b, p, _ in problem.phases],
        dtype=float,
    ).reshape(-1, 6)  # fmt: skip
    phase_a = table[:, 0].astype(np.int64)
    phase_b = table[:, 1].astype(np.int64)
    phase_w, phase_p, phase_min, phase_max = table[:, 2], table[:, 3], table[:, 4], table[:, 5]
    ties = np.array(
        [(key_index[r.a], key_index[r.b], r.kb - r.ka) for r in problem.equalities], dtype=float
    ).reshape(-1, 3)
    # A phase whose bounds meet is an equality; as two rows it would make
    # the active-set systems singular. t_a - t_b = d for every equality
    # (sync references, <synchronize>, fixed times, rigid phases).
    rigid = phase_max - phase_min <= TOLERANCE
    eq_a = np.concatenate([ties[:, 0].astype(np.int64), phase_b[rigid]])
    eq_b = np.concatenate([ties[:, 1].astype(np.int64), phase_a[rigid]])
    eq_d = np.concatenate([ties[:, 2], phase_min[rigid]])
    key_class, key_offset = _eliminate(len(keys), eq_a, eq_b, eq_d)
    if eq_a.size and np.abs(key_offset[eq_a] - key_offset[eq_b] - eq_d).max() > TOLERANCE:
        conflict = find_conflict(problem)
        raise Infeasible(conflict or frozenset(), "contradictory equalities")
    n_classes = int(key_class.max(initial=-1)) + 1
    block = key_index[BLOCK_START]
    pinned_class = int(key_class[block])
    # The pinned class's value makes t_block = 0.
    pinned_value = -float(key_offset[block])

    # Cost components: classes linked by phases. Those without the pinned
    # class may shift freely and get the start-early pull.
    linked = sp.csr_matrix(
        (np.ones(phase_a.size), (key_class[phase_a], key_class[phase_b])),
        shape=(n_classes, n_classes),
    )
    _, comp = connected_components(linked, directed=False)
    pinned_comp = int(comp[pinned_class])

    # Variables: every class but the pinned one.
    var_of_class = np.full(n_classes, -1, dtype=np.int64)
    free = np.flatnonzero(np.arange(n_classes) != pinned_class)
    var_of_class[free] = np.arange(free.size)
    n = int(free.size)

    def as_var(key_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Variable index (or -1) and constant part of t for key indices (-1: zero)."""
        present = key_rows >= 0
        safe = np.where(present, key_rows, 0)
        var = np.where(present, var_of_class[key_class[safe]], -1)
        const = np.where(present, key_offset[safe] + np.where(var < 0, pinned_value, 0.0), 0.0)
        return var, const

    # Objective: sum w (x_b - x_a + c)^2 over phase terms and pull terms.
    va, ca = as_var(phase_a)
    vb, cb = as_var(phase_b)
    term_i, term_j = vb, va  # + x_i - x_j
    term_c = cb - ca - phase_p
    term_w = phase_w
    start_rows = np.fromiter((key_index[k] for k in problem.starts), np.int64,
                             len(problem.starts))  # fmt: skip
    start_var, start_const = as_var(start_rows)
    # One pulled start per free component makes the system definite; the
    # polish step removes the pull once a bound pins the shift.
    start_comp = comp[key_class[start_rows]]
    _, first = np.unique(start_comp, return_index=True)
    free_start = np.zeros(start_rows.size, dtype=bool)
    free_start[first[start_comp[first] != pinned_comp]] = True
    pull = PULL * (float(phase_w.mean()) if phase_w.size else 1.0)
    n_pulled = int(free_start.sum())
    term_i = np.concatenate([term_i, start_var[free_start]])
    term_j = np.concatenate([term_j, np.full(n_pulled, -1, dtype=np.int64)])
    term_c = np.concatenate([term_c, start_const[free_start]])
    term_w = np.concatenate([term_w, np.full(n_pulled, pull)])
    hessian, gradient = _quadratic(n, term_i, term_j, term_c, term_w)
    n_phase = phase_w.size
    exact = _quadratic(n, term_i[:n_phase], term_j[:n_phase], term_c[:n_phase], phase_w)

    # Inequalities as rows ``t_upper - t_lower >= minimum`` (key indices, -1: zero).
    stretchy = np.isfinite(phase_max) & (phase_max - phase_min > TOLERANCE)
    order_upper = np.fromiter((key_index[r.b] for r in problem.orderings), np.int64,
                              len(problem.orderings))  # fmt: skip
    order_lower = np.fromiter((key_index[r.a] for r in problem.orderings), np.int64,
                              len(problem.orderings))  # fmt: skip
    order_min = np.array([r.ka - r.kb for r in problem.orderings], dtype=float)
    # t >= 0: per class, only the tightest (the earliest key) matters; the
    # pinned class is a plain check.
    by_class = np.lexsort((key_offset, key_class))
    earliest_key = by_class[np.r_[True, key_class[by_class][1:] != key_class[by_class][:-1]]]
    pinned_keys = key_class == pinned_class
    if np.any(key_offset[pinned_keys] + pinned_value < -TOLERANCE):
        conflict = find_conflict(problem)
        raise Infeasible(conflict or frozenset({BLOCK_SOURCE}), "a fixed time breaks a bound")
    earliest_key = earliest_key[key_class[earliest_key] != pinned_class]
    upper = np.concatenate([order_upper, phase_b, phase_a[stretchy], earliest_key])
    lower = np.concatenate(
        [order_lower, phase_a, phase_b[stretchy], np.full(earliest_key.size, -1, np.int64)]
    )
    minimum = np.concatenate([order_min, phase_min, -phase_max[stretchy],
                              np.zeros(earliest_key.size)])  # fmt: skip
    phase_sources = [source for _, _, _, source in problem.phases]
    sources = (
        [r.source for r in problem.orderings]
        + phase_sources
        + [source for source, keep in zip(phase_sources, stretchy.tolist(), strict=True) if keep]
        + [BLOCK_SOURCE] * int(earliest_key.size)
    )
    ri, ci = as_var(upper)
    rj, cj = as_var(lower)
    b = minimum - ci + cj
    constant = ri == rj  # nothing variable: a plain check
    broken = np.flatnonzero(constant & (b > TOLERANCE))
    if broken.size:
        conflict = find_conflict(problem)
        raise Infeasible(
            conflict or frozenset({sources[int(broken[0])]}), "a fixed time breaks a bound"
        )
    ri, rj, b = ri[~constant], rj[~constant], b[~constant]
    matrix = _rows_matrix(n, ri, rj)

    # Fast path: the optimum without inequalities, each free group moved to
    # start at 0. Most blocks need nothing more.
    x, _ = _kkt(hessian, gradient, matrix, [], b)
    if x is None:
        raise SchedulingError("the scheduler's cost matrix is singular")
    var_comp = comp[free]
    if n:
        key_var = var_of_class[key_class]
        t = np.where(key_var >= 0, x[key_var] + key_offset, key_offset + pinned_value)
        earliest = np.full(n_classes, np.inf)
        np.minimum.at(earliest, comp[key_class], t)
        shift = np.where(var_comp != pinned_comp, -earliest[var_comp], 0.0)
        x = x + shift
    if b.size and (matrix @ x - b).min() < -TOLERANCE:
        pulled = start_var[free_start]
        solved = _primal_dual_active_set(hessian, gradient, matrix, ri, rj, b, x)
        if solved is not None and not pulled.size:
            x = solved[0]  # nothing was pulled: already the exact optimum
        elif solved is not None:
            x = _polish(
                exact, matrix, ri, rj, b, solved[1], solved[0], pulled, var_comp, pinned_comp
            )
        else:
            # The fast method cycled or met a degenerate working set: the
            # primal active-set method from a feasible point always ends.
            start = _feasible_point(n, ri, rj, b)
            if start is None:
                conflict = find_conflict(problem)
                raise Infeasible(conflict or frozenset(), "the constraints cannot all hold")
            solved_x = _active_set(hessian, gradient, matrix, ri, rj, b, start, exact, pulled,
                                   var_comp, pinned_comp)  # fmt: skip
            if solved_x is None:
                raise SchedulingError("the scheduler's active-set method did not converge")
            x = solved_x

    values = np.where(var_of_class >= 0, 0.0, pinned_value)
    values[free] = x
    times = values[key_class] + key_offset
    return dict(zip(keys, times.tolist(), strict=True))


# -- the dense path for small problems -------------------------------------------


def solve_dense(problem: Problem) -> dict[Key, float]:
    """:func:`solve` for small problems: the same method on dense matrices.

    A block of a few behaviours is a few dozen sync points, for which the
    sparse path spends nearly all its time building scipy.sparse objects
    and array temporaries around a tiny system. Here the bookkeeping
    (equality classes by a weighted union-find, cost components, the rows)
    is plain Python over the problem's lists, and the linear algebra is
    numpy's dense solve. The method is the sparse path's step for step (the
    optimum without inequalities shifted to start at 0, then the
    primal-dual active-set method and the polish); should the active-set
    method cycle, the problem goes to :func:`solve_sparse`, whose fallback
    always ends. Results equal the sparse path's (tests compare them on
    random problems).
    """
    keys = list(problem.keys)
    n_keys = len(keys)
    key_index = {key: index for index, key in enumerate(keys)}
    # Equality classes with offsets, t_key = t_root + offset: a weighted
    # union-find over the ties t_a - t_b = d (sync references, fixed times,
    # rigid phases).
    parent = list(range(n_keys))
    offset = [0.0] * n_keys

    def find(x: int) -> int:
        path = []
        while parent[x] != x:
            path.append(x)
            x = parent[x]
        total = 0.0
        for y in reversed(path):  # nearest the root first
            total += offset[y]
            offset[y] = total
            parent[y] = x
        return x

    ties = [(key_index[r.a], key_index[r.b], r.kb - r.ka) for r in problem.equalities]
    phases = [
        (key_index[a], key_index[b], p.weight, p.preferred, p.minimum, p.maximum, source)
        for a, b, p, source in problem.phases
    ]
    ties += [(b, a, low) for a, b, _, _, low, high, _ in phases if high - low <= TOLERANCE]
    for a, b, d in ties:
        ra, rb = find(a), find(b)
        if ra == rb:
            if abs(offset[a] - offset[b] - d) > TOLERANCE:
                conflict = find_conflict(problem)
                raise Infeasible(conflict or frozenset(), "contradictory equalities")
        else:  # t_ra - t_rb = d + offset_b - offset_a
            parent[ra] = rb
            offset[ra] = d + offset[b] - offset[a]  # a root's own offset is 0
    roots = [find(k) for k in range(n_keys)]  # also flattens: offset[k] is to its root
    for k in range(n_keys):
        if roots[k] == k:
            offset[k] = 0.0
    block = key_index[BLOCK_START]
    pinned = roots[block]
    pinned_value = -offset[block]
    # Cost components: classes (roots) linked by phases.
    components = _Forest(n_keys)
    for a, b, *_ in phases:
        components.union(roots[a], roots[b])
    pinned_comp = components.find(pinned)
    # Variables: every class but the pinned one; t_key = x[var[key]] + const[key].
    var_of_root: dict[int, int] = {}
    for root in roots:
        if root != pinned and root not in var_of_root:
            var_of_root[root] = len(var_of_root)
    n = len(var_of_root)
    var = [var_of_root.get(root, -1) for root in roots]
    const = [o + pinned_value if v < 0 else o for o, v in zip(offset, var, strict=True)]

    # Objective: sum w (x_i - x_j + c)^2 over phases (i: the later point)
    # and one start-early pull per free component, as 1/2 x'Hx + g'x.
    pulled: list[int] = []
    seen_comps: set[int] = set()
    for start in problem.starts:
        k = key_index[start]
        comp = components.find(roots[k])
        if comp not in seen_comps:
            seen_comps.add(comp)
            if comp != pinned_comp:
                pulled.append(k)
    var_arr = np.array(var, dtype=np.int64)
    const_arr = np.array(const)
    table = np.array([row[:6] for row in phases], dtype=float).reshape(-1, 6)
    phase_a, phase_b = table[:, 0].astype(np.int64), table[:, 1].astype(np.int64)
    phase_w, phase_min, phase_max = table[:, 2], table[:, 4], table[:, 5]
    pulled_keys = np.array(pulled, dtype=np.int64)
    n_phase, n_pulled = len(phases), len(pulled)
    pull = PULL * (float(phase_w.mean()) if n_phase else 1.0)
    term_i = np.concatenate([var_arr[phase_b], var_arr[pulled_keys]])
    term_j = np.concatenate([var_arr[phase_a], np.full(n_pulled, -1, dtype=np.int64)])
    term_c = np.concatenate(
        [const_arr[phase_b] - const_arr[phase_a] - table[:, 3], const_arr[pulled_keys]]
    )
    term_w = 2.0 * np.concatenate([phase_w, np.full(n_pulled, pull)])
    hessian, gradient = _dense_quadratic(n, term_i, term_j, term_c, term_w)

    # Rows x_i - x_j >= b: orderings, phase bounds, and t >= 0 on the earliest
    # key of every class (the pinned class: a plain check).
    earliest: dict[int, int] = {}
    for k, root in enumerate(roots):
        if root == pinned:
            if offset[k] + pinned_value < -TOLERANCE:
                conflict = find_conflict(problem)
                raise Infeasible(
                    conflict or frozenset({BLOCK_SOURCE}), "a fixed time breaks a bound"
                )
        elif root not in earliest or offset[k] < offset[earliest[root]]:
            earliest[root] = k
    orderings = problem.orderings
    stretchy = np.isfinite(phase_max) & (phase_max - phase_min > TOLERANCE)
    earliest_keys = np.array(list(earliest.values()), dtype=np.int64)
    upper = np.concatenate(
        [
            np.array([key_index[r.b] for r in orderings], dtype=np.int64),
            phase_b,
            phase_a[stretchy],
            earliest_keys,
        ]
    )
    lower = np.concatenate(
        [
            np.array([key_index[r.a] for r in orderings], dtype=np.int64),
            phase_a,
            phase_b[stretchy],
        ]
    )
    minimum = np.concatenate(
        [np.array([r.ka - r.kb for r in orderings]), phase_min, -phase_max[stretchy]]
    )
    n_plain = lower.size  # the rows after these are t >= 0 on earliest keys
    row_i = var_arr[upper]
    row_j = np.concatenate([var_arr[lower], np.full(earliest_keys.size, -1, dtype=np.int64)])
    b_all = np.concatenate(
        [minimum - const_arr[upper[:n_plain]] + const_arr[lower], -const_arr[earliest_keys]]
    )
    constant = row_i == row_j
    if constant.any():
        broken = np.flatnonzero(constant & (b_all > TOLERANCE))
        if broken.size:
            sources = [r.source for r in orderings] + [row[6] for row in phases]
            first_broken = int(broken[0])
            conflict = find_conflict(problem)
            raise Infeasible(
                conflict or frozenset({sources[min(first_broken, len(sources) - 1)]}),
                "a fixed time breaks a bound",
            )
        keep = ~constant
        row_i, row_j, b_all = row_i[keep], row_j[keep], b_all[keep]
    m = b_all.size
    matrix = _incidence(row_i, row_j, n)
    b_rows = b_all

    x, _ = _dense_kkt(hessian, gradient, matrix, [], b_rows)
    if x is None:
        raise SchedulingError("the scheduler's cost matrix is singular")
    # Each free component moved so that its earliest point is at the block start.
    comp_of_var = [0] * n
    for root, v in var_of_root.items():
        comp_of_var[v] = components.find(root)
    values = x.tolist()
    first: dict[int, float] = {}
    for v, c in zip(var, const, strict=True):
        if v >= 0:
            comp = comp_of_var[v]
            if comp != pinned_comp:
                t = values[v] + c
                if comp not in first or t < first[comp]:
                    first[comp] = t
    if first:
        x = x - np.array([first.get(comp, 0.0) for comp in comp_of_var])
    if m and float((matrix @ x - b_rows).min()) < -TOLERANCE:
        solved = _primal_dual_active_set(
            hessian, gradient, matrix, row_i, row_j, b_rows, x, kkt=_dense_kkt
        )
        if solved is None:
            return solve_sparse(problem)
        if not pulled:
            x = solved[0]  # nothing was pulled: already the exact optimum
        else:
            exact = _dense_quadratic(
                n, term_i[:n_phase], term_j[:n_phase], term_c[:n_phase], term_w[:n_phase]
            )
            pulled_vars = var_arr[pulled_keys]
            comp_array = np.array(comp_of_var, dtype=np.int64)
            x = _polish(
                exact, matrix, row_i, row_j, b_rows, solved[1], solved[0], pulled_vars,
                comp_array, pinned_comp, kkt=_dense_kkt,
            )  # fmt: skip
    values = x.tolist()
    return {
        key: (values[v] + c if v >= 0 else c) for key, v, c in zip(keys, var, const, strict=True)
    }


def _dense_quadratic(
    n: int, i: np.ndarray, j: np.ndarray, c: np.ndarray, w2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Dense H and g of sum w2/2 (x_i - x_j + c)^2 as 1/2 x'Hx + g'x (index -1: absent).

    Summed by ``bincount``, not as D'WD: a matrix product goes to the
    threaded BLAS, which on a busy machine costs a hundred times more.
    """
    has_i, has_j = i >= 0, j >= 0
    both = has_i & has_j
    ii, jj, bi, bj = i[has_i], j[has_j], i[both], j[both]
    wi, wj, wb = w2[has_i], w2[has_j], w2[both]
    flat = np.concatenate([ii * (n + 1), jj * (n + 1), bi * n + bj, bj * n + bi])
    hessian = np.bincount(flat, np.concatenate([wi, wj, -wb, -wb]), n * n).reshape(n, n)
    gradient = np.bincount(ii, wi * c[has_i], n) - np.bincount(jj, wj * c[has_j], n)
    return hessian, gradient


def _incidence(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """The dense m x n matrix of rows ``x_i - x_j`` (index -1: absent)."""
    columns = np.arange(n)
    matrix: np.ndarray = (columns == i[:, None]).astype(float) - (columns == j[:, None])
    return matrix


def _dense_kkt(
    hessian: Any,
    gradient: np.ndarray,
    matrix: Any,
    working: list[int],
    b: np.ndarray,
    quiet: bool = False,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:func:`_kkt` on dense matrices, by LAPACK's LU solve (a singular system gives None)."""
    n = hessian.shape[0]
    if n == 0:
        return np.zeros(0), (np.zeros(len(working)) if working else None)
    if not working:
        *_, solution, info = _dgesv(hessian, -gradient)
        return (solution, None) if info == 0 and np.isfinite(solution).all() else (None, None)
    active = matrix[working]
    k = len(working)
    kkt = np.zeros((n + k, n + k))
    kkt[:n, :n] = hessian
    kkt[:n, n:] = -active.T
    kkt[n:, :n] = active
    *_, solution, info = _dgesv(kkt, np.concatenate([-gradient, b[working]]))
    if info != 0 or not np.isfinite(solution).all():
        return None, None
    return solution[:n], solution[n : n + k]


def _eliminate(
    n_keys: int, eq_a: np.ndarray, eq_b: np.ndarray, eq_d: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Equality classes with offsets: ``t_key = r_class + offset``, vectorised.

    The ties ``t_a - t_b = d`` are edges of a graph; its connected
    components are the classes. A breadth-first forest from one root per
    class gives each key its parent, and the offsets follow by pointer
    jumping (log depth array steps, no Python loop over keys). Ties that
    the forest does not use are checked by the caller: a tie that
    disagrees with the forest is a contradiction.
    """
    if eq_a.size == 0:
        return np.arange(n_keys, dtype=np.int64), np.zeros(n_keys)
    # Both directions, the first tie of parallel ones kept (a sparse matrix
    # would add them up).
    rows = np.concatenate([eq_a, eq_b])
    cols = np.concatenate([eq_b, eq_a])
    weight = np.concatenate([eq_d, -eq_d])  # t_row - t_col
    order = np.lexsort((cols, rows))
    rows, cols, weight = rows[order], cols[order], weight[order]
    first = np.r_[True, (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1])]
    rows, cols, weight = rows[first], cols[first], weight[first]
    graph = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n_keys, n_keys))
    _, labels = connected_components(graph, directed=False)
    # A virtual root n_keys joined to the first key of every class.
    _, representative = np.unique(labels, return_index=True)
    rooted = sp.csr_matrix(
        (
            np.ones(rows.size + representative.size),
            (
                np.concatenate([rows, np.full(representative.size, n_keys)]),
                np.concatenate([cols, representative]),
            ),
        ),
        shape=(n_keys + 1, n_keys + 1),
    )
    _, parent = breadth_first_order(rooted, n_keys, directed=True, return_predecessors=True)
    parent = parent[:n_keys]
    # The weight of the tree edge (parent -> key): t_key - t_parent.
    lookup = sp.csr_matrix((np.arange(1, rows.size + 1), (rows, cols)), shape=(n_keys, n_keys))
    tree = parent != n_keys
    child = np.flatnonzero(tree)
    offset = np.zeros(n_keys)
    if child.size:
        position = np.asarray(lookup[child, parent[child]]).ravel() - 1
        offset[child] = weight[position]
    # Pointer jumping: after k steps each key holds its offset to the
    # ancestor 2^k levels up (or to its class root).
    # Roots have offset 0, so adding a root's offset changes nothing.
    ancestor = np.where(tree, parent, np.arange(n_keys))
    while True:
        moving = ancestor != ancestor[ancestor]
        if not moving.any():
            break
        offset = offset + np.where(moving, offset[ancestor], 0.0)
        ancestor = ancestor[ancestor]
    return labels.astype(np.int64), offset


class _Forest:
    """Disjoint sets over ``0 .. size - 1`` (path halving)."""

    def __init__(self, size: int) -> None:
        self.parent = list(range(size))

    def find(self, a: int) -> int:
        parent = self.parent
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def union(self, a: int, b: int) -> bool:
        """Join the sets of ``a`` and ``b``; False if they were one already."""
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return False
        self.parent[ra] = rb
        return True


def _independent(ri: np.ndarray, rj: np.ndarray, rows: Iterable[int], n: int) -> list[int]:
    """The rows of ``rows`` that form a spanning forest (so are linearly independent).

    Every row is ``x_i - x_j`` (index -1: the zero node ``n``); rows are
    dependent exactly when their edges close a cycle, and a row that closes a
    cycle of rows held as equalities is implied by them (or contradicts them,
    which the caller sees as a violated row).
    """
    forest = _Forest(n + 1)
    return [
        int(row)
        for row in rows
        if forest.union(int(ri[row]) if ri[row] >= 0 else n, int(rj[row]) if rj[row] >= 0 else n)
    ]


def _primal_dual_active_set(
    hessian: sp.csc_matrix,
    gradient: np.ndarray,
    matrix: sp.csr_matrix,
    ri: np.ndarray,
    rj: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    kkt: Callable[..., tuple[np.ndarray | None, np.ndarray | None]] | None = None,
) -> tuple[np.ndarray, list[int]] | None:
    """The primal-dual active-set method (Hintermüller, Ito and Kunisch 2002).

    Each step holds every row predicted active (violated, or with a positive
    multiplier) as an equality and solves one sparse KKT system, so a block
    whose optimum leans on hundreds of bounds needs a handful of solves
    rather than one per bound. The Hessian is a graph Laplacian plus a
    diagonal (an M-matrix), the case where the method converges fast; it
    can still cycle on general rows, so it gives up (None) on a repeated
    working set or after :data:`PDAS_STEPS` steps, and the caller falls
    back to the primal active-set method. Returns x and the working rows.
    ``kkt``: the KKT solver (:func:`_kkt`, or :func:`_dense_kkt` on dense matrices).
    """
    kkt = kkt or _kkt
    n = x.size
    active = (matrix @ x - b) < -TOLERANCE
    seen: set[bytes] = set()
    multipliers = np.zeros(b.size)
    for _ in range(PDAS_STEPS):
        working = _independent(ri, rj, np.flatnonzero(active).tolist(), n)
        solution, lam = kkt(hessian, gradient, matrix, working, b, quiet=True)
        if solution is None:
            return None
        multipliers[:] = 0.0
        if working:
            assert lam is not None
            multipliers[working] = lam
        slack = matrix @ solution - b
        scale = 1e-9 * (1.0 + float(np.abs(multipliers).max(initial=0.0)))
        # A held row stays unless its multiplier is clearly negative: rows
        # that are active with a zero multiplier (degenerate) would otherwise
        # leave, be violated by round-off and come back, for ever.
        predicted = (active & (multipliers >= -scale)) | (slack < -TOLERANCE)
        if np.array_equal(predicted, active):
            if slack.min(initial=0.0) >= -TOLERANCE and multipliers.min(initial=0.0) >= -scale:
                return solution, working
            return None
        signature = np.packbits(predicted).tobytes()
        if signature in seen:
            return None
        seen.add(signature)
        active = predicted
    return None


def _quadratic(
    n: int, i: np.ndarray, j: np.ndarray, c: np.ndarray, w: np.ndarray
) -> tuple[sp.csc_matrix, np.ndarray]:
    """H and g of sum w (x_i - x_j + c)^2 / 2-scaled: 1/2 x'Hx + g'x (index -1: absent)."""
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    vals: list[np.ndarray] = []
    gradient = np.zeros(n)
    has_i, has_j = i >= 0, j >= 0
    # d/dx of w (x_i - x_j + c)^2 = 2w(...) ; H = 2w [[1,-1],[-1,1]]
    for mask, a, b, sign in ((has_i, i, i, 1.0), (has_j, j, j, 1.0)):
        rows.append(a[mask])
        cols.append(b[mask])
        vals.append(2 * w[mask] * sign)
    both = has_i & has_j
    rows += [i[both], j[both]]
    cols += [j[both], i[both]]
    vals += [-2 * w[both], -2 * w[both]]
    np.add.at(gradient, i[has_i], 2 * w[has_i] * c[has_i])
    np.add.at(gradient, j[has_j], -2 * w[has_j] * c[has_j])
    hessian = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
    return hessian, gradient


def _rows_matrix(n: int, ri: np.ndarray, rj: np.ndarray) -> sp.csr_matrix:
    """The m x n matrix of rows ``x_i - x_j`` (index -1: absent)."""
    m = ri.size
    row_index = np.arange(m)
    has_i, has_j = ri >= 0, rj >= 0
    return sp.csr_matrix(
        (
            np.concatenate([np.ones(int(has_i.sum())), -np.ones(int(has_j.sum()))]),
            (
                np.concatenate([row_index[has_i], row_index[has_j]]),
                np.concatenate([ri[has_i], rj[has_j]]),
            ),
        ),
        shape=(m, n),
    )


def _feasible_point(n: int, ri: np.ndarray, rj: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """A point meeting every row ``x_i - x_j >= b``, by shortest paths; None if none exists.

    Each row is the difference constraint ``x_j - x_i <= -b``: an edge i -> j
    of weight -b (index n is the zero node, n + 1 a source joined to all).
    """
    zero, source = n, n + 1
    u = np.where(ri >= 0, ri, zero)
    v = np.where(rj >= 0, rj, zero)
    weight = -b
    # Keep the tightest of parallel edges (a sparse matrix would add them).
    order = np.lexsort((weight, v, u))
    u, v, weight = u[order], v[order], weight[order]
    first = np.ones(u.size, dtype=bool)
    first[1:] = (u[1:] != u[:-1]) | (v[1:] != v[:-1])
    u, v, weight = u[first], v[first], weight[first]
    u = np.concatenate([u, np.full(n + 1, source)])
    v = np.concatenate([v, np.arange(n + 1)])
    weight = np.concatenate([weight, np.zeros(n + 1)])
    graph = sp.csr_matrix((weight, (u, v)), shape=(n + 2, n + 2))
    try:
        distance = shortest_path(graph, method="BF", directed=True, indices=source)
    except NegativeCycleError:
        return None
    return np.asarray(distance[:n] - distance[zero], dtype=float)


def _active_set(
    hessian: sp.csc_matrix,
    gradient: np.ndarray,
    matrix: sp.csr_matrix,
    ri: np.ndarray,
    rj: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    exact: tuple[sp.csc_matrix, np.ndarray],
    pulled: np.ndarray,
    var_comp: np.ndarray,
    pinned_comp: int,
) -> np.ndarray | None:
    """Primal active-set method from the feasible point ``x`` (Nocedal & Wright 16.3).

    Minimises 1/2 x'Hx + g'x subject to ``matrix @ x >= b``. ``hessian`` and
    ``gradient`` include the start-early pull, which makes H definite; at the
    end the solution is polished with ``exact`` (no pull) on the final
    working set, whose bounds now pin every shift, so the result is the exact
    optimum of the phase costs.
    """
    m = b.size
    working: list[int] = []
    in_working = np.zeros(m, dtype=bool)
    for _ in range(10 * m + 50):
        step, multipliers = _kkt(hessian, hessian @ x + gradient, matrix, working, np.zeros(m))
        if step is None:
            return None
        size = float(np.abs(step).max(initial=0.0))
        if size <= 1e-10 * (1 + np.abs(x).max(initial=0.0)):
            if not working or multipliers is None or multipliers.min() >= -1e-12:
                return _polish(exact, matrix, ri, rj, b, working, x, pulled, var_comp, pinned_comp)
            drop = working.pop(int(np.argmin(multipliers)))
            in_working[drop] = False
            continue
        change = matrix @ step
        slack = matrix @ x - b
        # Rows the step hardly moves along cannot block it; a tiny threshold
        # would admit rows dependent on the working set (a singular system).
        blocking = np.flatnonzero((change < -1e-9 * size) & ~in_working)
        alpha, block = 1.0, -1
        if blocking.size:
            ratios = np.maximum(slack[blocking], 0.0) / -change[blocking]
            index = int(np.argmin(ratios))
            if ratios[index] < 1.0:
                alpha, block = float(ratios[index]), int(blocking[index])
        x = x + alpha * step
        if block >= 0:
            working.append(block)
            in_working[block] = True
    return None


def _polish(
    exact: tuple[sp.csc_matrix, np.ndarray],
    matrix: sp.csr_matrix,
    ri: np.ndarray,
    rj: np.ndarray,
    b: np.ndarray,
    working: list[int],
    x: np.ndarray,
    pulled: np.ndarray,
    var_comp: np.ndarray,
    pinned_comp: int,
    kkt: Callable[..., tuple[np.ndarray | None, np.ndarray | None]] | None = None,
) -> np.ndarray:
    """Solve the final working set again without the pull.

    The working rows link cost components to each other and to the zero
    node (the block start and fixed times). A group of components that no
    chain of working rows ties to the zero node keeps the shift the pull
    gave it: one pulled start of the group is held where it is (holding
    more would repeat the same tie). In every other group the rows pin the
    shift, and the pull's small force is removed, which makes the result
    the exact optimum of the phase costs.
    """
    n = x.size
    # The pinned component (the block start's) is the zero node's group: its
    # phases tie it to the block start already.
    zero = pinned_comp
    forest = _Forest(max(int(var_comp.max(initial=-1)), pinned_comp) + 1)
    for row in working:
        i, j = int(ri[row]), int(rj[row])
        forest.union(int(var_comp[i]) if i >= 0 else zero, int(var_comp[j]) if j >= 0 else zero)
    hold: list[int] = []
    held: set[int] = {forest.find(zero)}
    for v in pulled.tolist():
        group = forest.find(int(var_comp[v]))
        if group not in held:
            held.add(group)
            hold.append(int(v))
    augmented: Any
    if kkt is None:
        extra = sp.csr_matrix(
            (np.ones(len(hold)), (np.arange(len(hold)), np.asarray(hold, dtype=np.int64))),
            shape=(len(hold), n),
        )
        augmented = sp.vstack([matrix, extra], format="csr")
    else:  # dense
        augmented = np.vstack([matrix, np.eye(n)[hold]])
    bounds = np.concatenate([b, x[hold]])
    rows = working + list(range(b.size, b.size + len(hold)))
    polished, _ = (kkt or _kkt)(exact[0], exact[1], augmented, rows, bounds, quiet=True)
    if polished is not None and (matrix @ polished - b).min(initial=0.0) >= -1e-7:
        return polished
    return x


def _kkt(
    hessian: sp.csc_matrix,
    gradient: np.ndarray,
    matrix: sp.csr_matrix,
    working: list[int],
    b: np.ndarray,
    quiet: bool = False,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Solve min 1/2 x'Hx + g'x with the working rows as equalities; x and multipliers.

    ``quiet``: a singular system gives None rather than a least-squares answer.
    """
    n = hessian.shape[0]
    if not working:
        if n == 0:
            return np.zeros(0), None
        try:
            return spla.splu(hessian.tocsc()).solve(-gradient).reshape(n), None
        except RuntimeError:
            return None, None
    active = matrix[working]
    k = len(working)
    kkt = sp.bmat([[hessian, -active.T], [active, None]], format="csc")
    rhs = np.concatenate([-gradient, b[working]])
    try:
        solution = spla.splu(kkt).solve(rhs)
    except RuntimeError:
        if quiet:
            return None, None
        # Dependent active rows: least squares finds a consistent solution.
        dense = kkt.toarray()
        solution, *_ = np.linalg.lstsq(dense, rhs, rcond=None)
        if np.linalg.norm(dense @ solution - rhs) > 1e-6 * (1 + np.linalg.norm(rhs)):
            return None, None
    if not np.all(np.isfinite(solution)):
        return None, None
    return solution[:n], solution[n : n + k]
