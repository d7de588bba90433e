"""The scheduling optimisation: one quadratic programme over sync point times.

Seed 000 section 3.3: sync points are lined up by shifting behaviours and by
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
  and, as a tie-breaker, a preference for starting early (seed 000: "it is
  better to align left").

Every constraint is a difference constraint, which the solver uses twice:
equalities are eliminated up front by a union-find with offsets, and when the
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
meets every inequality. Otherwise a primal active-set method (Nocedal and
Wright, algorithm 16.3) starts from a feasible point that shortest paths over
the difference constraints provide (no such point: a negative cycle, and so
a conflict).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import NegativeCycleError, shortest_path

from realizer.errors import RealizerError
from realizer.scheduler.timing import Phase

#: A sync point: (behaviour id, sync name). ``BLOCK_START`` is time 0.
Key = tuple[str, str]
BLOCK_START: Key = ("bml", "start")

#: Weight of the start-early pull relative to the mean phase weight.
PULL = 1e-3
#: Constraint tolerance, seconds.
TOLERANCE = 1e-9


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
        for key in keys:
            self.keys.setdefault(key, None)
        self.starts.append(keys[0])
        for (a, b), phase in zip(itertools.pairwise(keys), phases, strict=True):
            self.phases.append((a, b, phase, source))

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

    def without(self, dropped: set[Source], behaviours: set[str] = frozenset()) -> Problem:  # type: ignore[assignment]
        """A copy without the constraints of ``dropped`` and the named behaviours."""

        def keep(relation: _Relation) -> bool:
            return (
                relation.source not in dropped
                and relation.a[0] not in behaviours
                and relation.b[0] not in behaviours
            )

        problem = Problem()
        for key in self.keys:
            if key[0] not in behaviours:
                problem.keys.setdefault(key, None)
        problem.phases = [p for p in self.phases if p[0][0] not in behaviours]
        problem.equalities = [r for r in self.equalities if keep(r)]
        problem.orderings = [r for r in self.orderings if keep(r)]
        problem.starts = [k for k in self.starts if k[0] not in behaviours]
        return problem


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


# -- equality elimination ------------------------------------------------------


class _Classes:
    """Union-find with offsets: ``t_key = r_class + offset``."""

    def __init__(self, keys: Iterable[Key]) -> None:
        self.parent = {key: key for key in keys}
        self.delta = dict.fromkeys(self.parent, 0.0)  # t_key = t_parent + delta

    def find(self, key: Key) -> tuple[Key, float]:
        path = []
        while self.parent[key] != key:
            path.append(key)
            key = self.parent[key]
        root, total = key, 0.0
        for node in reversed(path):
            total += self.delta[node]
            self.delta[node] = total
            self.parent[node] = root
        return root, (self.delta[path[0]] if path else 0.0)

    def union(self, a: Key, ka: float, b: Key, kb: float) -> bool:
        """Tie ``t_a + ka = t_b + kb``; False if that contradicts earlier ties."""
        ra, da = self.find(a)
        rb, db = self.find(b)
        # t_a = t_ra + da, t_b = t_rb + db
        if ra == rb:
            return abs((da + ka) - (db + kb)) <= TOLERANCE
        self.parent[rb] = ra
        self.delta[rb] = da + ka - kb - db
        return True


# -- the QP ----------------------------------------------------------------------


def solve(problem: Problem) -> dict[Key, float]:
    """The optimal time of every sync point, seconds after the block start.

    Raises :class:`Infeasible` with the conflicting sources when the
    constraints cannot all hold.
    """
    classes = _Classes(problem.keys)
    # A phase whose bounds meet is an equality; as two rows it would make
    # the active-set systems singular.
    rigid = [
        _Relation(b, 0.0, a, phase.minimum, source)
        for a, b, phase, source in problem.phases
        if phase.maximum - phase.minimum <= TOLERANCE
    ]
    for r in [*problem.equalities, *rigid]:
        if not classes.union(r.a, r.ka, r.b, r.kb):
            conflict = find_conflict(problem)
            raise Infeasible(conflict or frozenset({r.source}), "contradictory equalities")

    roots: dict[Key, int] = {}
    key_class = np.empty(len(problem.keys), dtype=np.int64)
    key_offset = np.empty(len(problem.keys))
    key_index = {}
    for index, key in enumerate(problem.keys):
        root, offset = classes.find(key)
        key_index[key] = index
        key_class[index] = roots.setdefault(root, len(roots))
        key_offset[index] = offset
    n_classes = len(roots)
    block = key_index[BLOCK_START]
    pinned_class = key_class[block]
    # The pinned class's value makes t_block = 0.
    pinned_value = -key_offset[block]

    # Cost components (classes linked by phases): those without the pinned
    # class may shift freely and get the start-early pull.
    comp = list(range(n_classes))

    def comp_find(x: int) -> int:
        while comp[x] != x:
            comp[x] = comp[comp[x]]
            x = comp[x]
        return x

    phase_a = np.array([key_index[a] for a, _, _, _ in problem.phases], dtype=np.int64)
    phase_b = np.array([key_index[b] for _, b, _, _ in problem.phases], dtype=np.int64)
    phase_w = np.array([p.weight for _, _, p, _ in problem.phases])
    phase_p = np.array([p.preferred for _, _, p, _ in problem.phases])
    for a, b in zip(key_class[phase_a].tolist(), key_class[phase_b].tolist(), strict=True):
        ra, rb = comp_find(a), comp_find(b)
        if ra != rb:
            comp[rb] = ra
    pinned_comp = comp_find(int(pinned_class))

    # Variables: every class but the pinned one.
    var_of_class = np.full(n_classes, -1, dtype=np.int64)
    free = [c for c in range(n_classes) if c != pinned_class]
    var_of_class[free] = np.arange(len(free))
    n = len(free)

    def as_var(key_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Variable index (or -1) and constant part of t for key indices."""
        cls = key_class[key_rows]
        var = var_of_class[cls]
        const = key_offset[key_rows] + np.where(var < 0, pinned_value, 0.0)
        return var, const

    # Objective: sum w (x_b - x_a + c)^2 over phase terms and pull terms.
    va, ca = as_var(phase_a)
    vb, cb = as_var(phase_b)
    term_i, term_j = vb, va  # + x_i - x_j
    term_c = cb - ca - phase_p
    term_w = phase_w
    start_rows = np.array([key_index[k] for k in problem.starts], dtype=np.int64)
    if start_rows.size:
        start_var, start_const = as_var(start_rows)
        # One pulled start per free component makes the system definite; the
        # polish step removes the pull once a bound pins the shift.
        seen: set[int] = set()
        free_start = np.zeros(start_rows.size, dtype=bool)
        for position, cls in enumerate(key_class[start_rows].tolist()):
            group = comp_find(int(cls))
            if group != pinned_comp and group not in seen:
                seen.add(group)
                free_start[position] = True
        pull = PULL * (float(phase_w.mean()) if phase_w.size else 1.0)
        term_i = np.concatenate([term_i, start_var[free_start]])
        term_j = np.concatenate([term_j, np.full(int(free_start.sum()), -1)])
        term_c = np.concatenate([term_c, start_const[free_start]])
        term_w = np.concatenate([term_w, np.full(int(free_start.sum()), pull)])
    hessian, gradient = _quadratic(n, term_i, term_j, term_c, term_w)
    n_phase = phase_w.size
    exact = _quadratic(n, term_i[:n_phase], term_j[:n_phase], term_c[:n_phase], phase_w)

    # Inequalities as rows: coef_i * x_i - coef_j * x_j >= bound.
    rows_i: list[int] = []
    rows_j: list[int] = []
    bounds: list[float] = []
    sources: list[Source] = []

    def add_row(upper: int, lower: int, minimum: float, source: Source) -> None:
        """t_upper - t_lower >= minimum, keys given by index (-1: zero)."""
        vi, ci = (var_of_class[key_class[upper]], key_offset[upper]) if upper >= 0 else (-1, 0.0)
        vj, cj = (var_of_class[key_class[lower]], key_offset[lower]) if lower >= 0 else (-1, 0.0)
        if upper >= 0 and vi < 0:
            ci += pinned_value
        if lower >= 0 and vj < 0:
            cj += pinned_value
        bound = minimum - ci + cj
        if vi == vj:  # nothing variable: a plain check
            if bound - TOLERANCE > 0:
                raise _RowInfeasible(source)
            return
        rows_i.append(int(vi))
        rows_j.append(int(vj))
        bounds.append(bound)
        sources.append(source)

    try:
        for r in problem.orderings:  # t_b + kb - t_a - ka >= 0
            add_row(key_index[r.b], key_index[r.a], r.ka - r.kb, r.source)
        for (_, _, phase, source), ia, ib in zip(
            problem.phases, phase_a.tolist(), phase_b.tolist(), strict=True
        ):
            add_row(ib, ia, phase.minimum, source)
            if math.isfinite(phase.maximum) and phase.maximum - phase.minimum > TOLERANCE:
                add_row(ia, ib, -phase.maximum, source)
        # t >= 0: per class, only the tightest (the earliest key) matters.
        lowest: dict[int, int] = {}
        for index in range(len(key_class)):
            cls = int(key_class[index])
            if cls == pinned_class:
                if key_offset[index] + pinned_value < -TOLERANCE:
                    raise _RowInfeasible(BLOCK_SOURCE)
                continue
            best = lowest.get(cls)
            if best is None or key_offset[index] < key_offset[best]:
                lowest[cls] = index
        for index in lowest.values():
            add_row(index, -1, 0.0, BLOCK_SOURCE)
    except _RowInfeasible as exc:
        conflict = find_conflict(problem)
        raise Infeasible(
            conflict or frozenset({exc.source}), "a fixed time breaks a bound"
        ) from None

    ri = np.asarray(rows_i, dtype=np.int64)
    rj = np.asarray(rows_j, dtype=np.int64)
    b = np.asarray(bounds, dtype=float)
    matrix = _rows_matrix(n, ri, rj)

    # Fast path: the optimum without inequalities, each free group moved to
    # start at 0. Most blocks need nothing more.
    x, _ = _kkt(hessian, gradient, matrix, [], b)
    if x is None:
        raise SchedulingError("the scheduler's cost matrix is singular")
    var_comp = np.array([comp_find(c) for c in free], dtype=np.int64)
    if n:
        t = x[var_of_class[key_class]] + key_offset
        t = np.where(var_of_class[key_class] >= 0, t, key_offset + pinned_value)
        key_comp = np.array([comp_find(int(c)) for c in key_class], dtype=np.int64)
        earliest = np.full(n_classes, np.inf)
        np.minimum.at(earliest, key_comp, t)
        shift = np.where(var_comp != pinned_comp, -earliest[var_comp], 0.0)
        x = x + shift
    if b.size and (matrix @ x - b).min() < -TOLERANCE:
        start = _feasible_point(n, ri, rj, b)
        if start is None:
            conflict = find_conflict(problem)
            raise Infeasible(conflict or frozenset(), "the constraints cannot all hold")
        pulled = start_var[free_start] if start_rows.size else np.zeros(0, dtype=np.int64)
        solved = _active_set(hessian, gradient, matrix, b, start, exact, pulled, var_comp)
        if solved is None:
            raise SchedulingError("the scheduler's active-set method did not converge")
        x = solved

    values = np.where(var_of_class >= 0, 0.0, pinned_value)
    values[free] = x
    times = values[key_class] + key_offset
    return {key: float(times[index]) for key, index in key_index.items()}


class _RowInfeasible(Exception):
    def __init__(self, source: Source) -> None:
        self.source = source


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
    b: np.ndarray,
    x: np.ndarray,
    exact: tuple[sp.csc_matrix, np.ndarray],
    pulled: np.ndarray,
    var_comp: np.ndarray,
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
                return _polish(exact, matrix, b, working, x, pulled, var_comp)
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
    b: np.ndarray,
    working: list[int],
    x: np.ndarray,
    pulled: np.ndarray,
    var_comp: np.ndarray,
) -> np.ndarray:
    """Solve the final working set again without the pull.

    Groups that no active row holds keep the shift the pull gave them (their
    pulled start is then at 0 and the pull exerts no force); in the others
    the active rows pin the shift, and the pull's small force on them is
    removed, which makes the result the exact optimum of the phase costs.
    """
    touched = set(var_comp[matrix[working].indices].tolist()) if working else set()
    hold = [int(v) for v in pulled if int(var_comp[v]) not in touched]
    n = x.size
    extra = sp.csr_matrix(
        (np.ones(len(hold)), (np.arange(len(hold)), np.asarray(hold, dtype=np.int64))),
        shape=(len(hold), n),
    )
    augmented = sp.vstack([matrix, extra], format="csr")
    bounds = np.concatenate([b, x[hold]])
    rows = working + list(range(b.size, b.size + len(hold)))
    polished, _ = _kkt(exact[0], exact[1], augmented, rows, bounds, quiet=True)
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
