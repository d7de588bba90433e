"""The scheduler's pure-Python path for blocks of a few behaviours.

:func:`realizer.scheduler.solver.solve` tries :func:`tiny_times` first
for problems of up to ``solver.TINY_KEYS`` sync points: the same
quadratic programme (Paul 2010, section 3.3.3: phase costs
``w (d - p)^2``, difference constraints, a start-early pull on free
groups) and the same method as the numpy paths, with no array at all,
after eliminating the sync points that need no linear algebra (springs
in series, :func:`_chain_plan`). It either returns the optimum or
declines (None) and numpy decides; tests compare the paths on random
problems and blocks (``tests/scheduler/test_solver_paths.py``,
``test_fast_paths.py``).

The module holds plain functions over the problem's index lists and
the small union-find helpers the dense path shares, and imports nothing
of numpy or of the rest of the scheduler at run time, so that it can be
compiled (``realizer.compiled``) as well as run from its source.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from realizer.scheduler.solver import Problem
    from realizer.scheduler.timing import Phase

#: Weight of the start-early pull relative to the mean phase weight.
PULL: Final = 1e-3
#: Constraint tolerance, seconds.
TOLERANCE: Final = 1e-9


# -- union-find helpers (the dense path's too) -----------------------------------


def _find(parent: list[int], offset: list[float], x: int) -> int:
    """The root of ``x`` in a weighted union-find; compresses the path.

    ``offset[y]`` is ``t_y - t_parent(y)``; afterwards every key on the path
    has the root as parent and its offset to the root.
    """
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


def _root(parent: list[int], x: int) -> int:
    """The root of ``x`` in a plain union-find (path halving)."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


def _equality_classes(
    ties: Iterable[tuple[int, int, float]], n_keys: int
) -> tuple[list[int], list[float]] | None:
    """The equality classes of ``t_a - t_b = d`` ties: a weighted union-find
    (parent, offset of each key from its parent), or None when two ties
    contradict each other."""
    parent = list(range(n_keys))
    offset = [0.0] * n_keys
    for a, b, d in ties:
        ra, rb = _find(parent, offset, a), _find(parent, offset, b)
        if ra == rb:
            if abs(offset[a] - offset[b] - d) > TOLERANCE:
                return None
        else:  # t_ra - t_rb = d + offset_b - offset_a (a root's own offset is 0)
            parent[ra] = rb
            offset[ra] = d + offset[b] - offset[a]
    return parent, offset


def _cost_components(
    problem: Problem,
    ties: Sequence[tuple[int, int, float]],
    node: Callable[[int], int],
    n_nodes: int,
    index_of: Mapping[int, int] | Sequence[int] | None,
) -> tuple[list[int], int, list[int]]:
    """The cost components of a problem: a union-find over behaviours (each
    held together by its phases) and keys of no behaviour (``node`` maps a
    key to its node), joined by the ties and the behaviours' links. Returns
    the union-find, the component of the block start, and one start of each
    other component (the starts that get the start-early pull; ``index_of``
    maps a start key to the caller's index, None when they are the same)."""
    group = list(range(n_nodes))
    for a, b, _ in ties:
        ga, gb = _root(group, node(a)), _root(group, node(b))
        if ga != gb:
            group[ga] = gb
    for a, b in problem._links:
        ga, gb = _root(group, a), _root(group, b)
        if ga != gb:
            group[ga] = gb
    pinned_comp = _root(group, node(0))
    pulled: list[int] = []
    seen = {pinned_comp}
    for k in problem._starts:
        if index_of is not None:
            k = index_of[k]
        comp = _root(group, node(k))
        if comp not in seen:
            seen.add(comp)
            pulled.append(k)
    return group, pinned_comp, pulled


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


# -- the tiny path ---------------------------------------------------------------

#: How often :func:`tiny_times` solves again, keeping the points whose
#: eliminated bounds its last answer broke, before it leaves the problem to numpy.
TINY_ATTEMPTS: Final = 3
#: The most variables :func:`tiny_times` keeps after eliminating chains; a
#: bigger reduced system goes to the numpy path (a pure-Python solve grows
#: with the cube of it).
TINY_VARIABLES: Final = 16
#: A spring of the reduced problem, ``w (x_i - x_j + c)^2``: i, j (-1: the
#: zero node), c, w, and the rows of its phase (None for a spring made by
#: joining two in series).
_Spring = tuple[int, int, float, float, "list[int] | None"]
#: An eliminated variable: (v, u1, d1, u2, d2, share) for ``x_v = x_u1 + d1
#: + share (x_u2 + d2 - x_u1 - d1)``, or (v, u, d, -2, 0, 0) for ``x_v =
#: x_u + d``.
_Step = tuple[int, int, float, int, float, float]


def tiny_times(problem: Problem, pdas_steps: int) -> list[float] | None:
    """``solver._dense_times`` in plain Python for a few behaviours, or None.

    A block of one to ten behaviours costs the numpy path a fixed ~60 array
    calls, more than the arithmetic. Here the same optimum is found with no
    array at all, after eliminating the sync points that need no linear
    algebra:

    * a behaviour's sync points that nothing but its own phases holds: the
      phases between two points that something else holds are springs in
      series, one spring of weight ``1 / sum(1 / w)`` and length the sum
      of the preferred ones, whose stretch the inner phases share in
      proportion to ``1 / w``; the phases after the last such point keep
      their preferred length. This reduction depends only on the model and
      on which of its points are held, so it is made once and cached
      (:func:`_chain_plan`);
    * then, over what is left, equality classes and the block start's
      class, cost components and pulled starts, as the dense path; a
      variable held by one spring only (no ordering, no pull) sits where
      it prefers, and one held by exactly two is again two springs in
      series (:func:`_tiny_reduced`);
    * the optimum without inequalities by Gaussian elimination, the free
      groups shifted to start at 0, as the dense path does; should an
      inequality be violated, the same primal-dual active-set method on
      the reduced problem when no group is free.

    Leaving out the eliminated points' bounds (their phases' bounds,
    t >= 0) relaxes the problem; so the result is checked against every
    row of the full problem, and it is the full problem's optimum when it
    meets them all (it minimises a relaxation and is feasible). A broken
    bound keeps its points the next time (:data:`TINY_ATTEMPTS`). For
    anything else (a contradiction, which the numpy path explains; a
    singular system; an active set that cycles; active inequalities beside
    free groups, where which rows the pulled optimum holds decides where
    the polish leaves a group; more than :data:`TINY_VARIABLES` variables
    left) it returns None and the caller takes the numpy path, whose
    results these equal (tests compare them on random problems and blocks).
    """
    chains = problem._chains
    owner = problem._owner
    held: dict[int, set[int]] = {}
    for k in itertools.chain(problem._tie_a, problem._tie_b, problem._order_upper,
                             problem._order_lower):  # fmt: skip
        chain = owner[k]
        if chain >= 0:
            held.setdefault(chain, set()).add(k)
    full: set[int] = set()
    orphans = [k for k, chain in enumerate(owner) if chain < 0]  # the block start is 0
    for _ in range(TINY_ATTEMPTS):
        # The points left: keys of no behaviour, then each behaviour's.
        kept_keys = orphans[:]
        # Springs between them: key a, key b, preferred, weight, minimum, maximum.
        springs: list[tuple[int, int, float, float, float, float]] = []
        plans: list[tuple[int, _ChainPlan] | None] = []
        for chain, (_, syncs, phases, _, first) in enumerate(chains):
            if isinstance(first, list) or chain in full:
                indices = first if isinstance(first, list) else range(first, first + len(syncs))
                kept_keys.extend(indices)
                for p, phase in enumerate(phases):
                    springs.append((indices[p], indices[p + 1], phase.preferred, phase.weight,
                                    phase.minimum, phase.maximum))  # fmt: skip
                plans.append(None)
                continue
            mine = held.get(chain)
            plan = _chain_plan(phases, tuple(sorted(k - first for k in mine)) if mine else ())
            plans.append((first, plan))
            kept_keys.extend(first + q for q in plan[0])
            for u, v, preferred, weight, low, high in plan[1]:
                springs.append((first + u, first + v, preferred, weight, low, high))
        kept_keys = list(dict.fromkeys(kept_keys))  # chains may share keys
        reduced = _tiny_reduced(problem, kept_keys, springs, pdas_steps)
        if reduced is None:
            return None
        times = [0.0] * problem.size
        for k, t in zip(kept_keys, reduced):
            times[k] = t
        broken = False
        for chain, entry in enumerate(plans):
            if entry is None:
                continue
            first, (_, _, inner, checked) = entry
            for q, u, v, before, share, length in inner:
                low_time = times[first + u] + before
                times[first + q] = (
                    low_time + share * (times[first + v] - times[first + u] - length)
                    if v >= 0
                    else low_time
                )
            for p, low, high in checked:
                duration = times[first + p + 1] - times[first + p]
                if duration < low or duration > high:
                    broken = True
                    full.add(chain)
                    break
        if not broken:
            return times
    return None


#: A behaviour's model reduced to the points something else holds: the
#: positions kept; the springs between kept positions (u, v, preferred,
#: weight, minimum, maximum); each other position q as (q, u, v, preferred
#: length from u, share of the stretch, preferred length of the spring), v
#: -1 after the last kept point; and the phases whose bounds must be checked
#: (position, minimum - TOLERANCE, maximum + TOLERANCE).
_ChainPlan = tuple[
    tuple[int, ...],
    list[tuple[int, int, float, float, float, float]],
    list[tuple[int, int, int, float, float, float]],
    tuple[tuple[int, float, float], ...],
]
#: (id of a model's phases, positions held) -> (those phases, the plan).
_CHAIN_PLANS: dict[tuple[int, tuple[int, ...]], tuple[tuple[Phase, ...], _ChainPlan]] = {}
#: At most this many plans are kept (then the cache starts again).
CHAIN_PLANS: Final = 4096


def _chain_plan(phases: tuple[Phase, ...], held: tuple[int, ...]) -> _ChainPlan:
    """The series reduction of one behaviour whose points ``held`` something else holds.

    Kept: the start, the held points and both ends of a rigid phase (a
    tie). Between two kept points the phases are springs in series; after
    the last one they keep their preferred lengths. Cached by the phases'
    identity (engines hand out one model per shape) and the held points.
    """
    entry = _CHAIN_PLANS.get((id(phases), held))
    if entry is not None and entry[0] is phases:
        return entry[1]
    positions = {0, *held}
    for p, phase in enumerate(phases):
        if phase.maximum - phase.minimum <= TOLERANCE:
            positions.update((p, p + 1))
    kept = tuple(sorted(positions))
    springs: list[tuple[int, int, float, float, float, float]] = []
    inner: list[tuple[int, int, int, float, float, float]] = []
    checked: list[int] = []
    for u, v in itertools.pairwise(kept):
        if v == u + 1:
            phase = phases[u]
            springs.append((u, v, phase.preferred, phase.weight, phase.minimum, phase.maximum))
            continue
        run = phases[u:v]
        length = sum(phase.preferred for phase in run)
        compliance = sum(1.0 / phase.weight for phase in run)
        springs.append((u, v, length, 1.0 / compliance, sum(phase.minimum for phase in run),
                        sum(phase.maximum for phase in run)))  # fmt: skip
        before = share = 0.0
        for q in range(u + 1, v):
            before += phases[q - 1].preferred
            share += 1.0 / phases[q - 1].weight
            inner.append((q, u, v, before, share / compliance, length))
        checked.extend(range(u, v))
    last = kept[-1]
    before = 0.0
    for q in range(last + 1, len(phases) + 1):
        before += phases[q - 1].preferred
        inner.append((q, last, -1, before, 0.0, 0.0))
    checked.extend(range(last, len(phases)))
    bounds = tuple(
        (p, phases[p].minimum - TOLERANCE, phases[p].maximum + TOLERANCE) for p in checked
    )
    plan: _ChainPlan = (kept, springs, inner, bounds)
    if len(_CHAIN_PLANS) >= CHAIN_PLANS:
        _CHAIN_PLANS.clear()
    _CHAIN_PLANS[(id(phases), held)] = (phases, plan)
    return plan


def _tiny_reduced(
    problem: Problem,
    kept_keys: list[int],
    phase_springs: list[tuple[int, int, float, float, float, float]],
    pdas_steps: int,
) -> list[float] | None:
    """The times of ``kept_keys``, the problem's phases replaced by ``phase_springs``.

    Keys are the problem's indices; ties and orderings are the problem's
    (they only name kept keys). None: leave it to the numpy path.
    """
    index_of = {k: r for r, k in enumerate(kept_keys)}
    n_keys = len(kept_keys)
    n_phases = len(problem._phase_a)
    flat = problem._phase_table
    tie_a = [index_of[k] for k in problem._tie_a]
    tie_b = [index_of[k] for k in problem._tie_b]
    phase_a = [index_of[spring[0]] for spring in phase_springs]
    phase_b = [index_of[spring[1]] for spring in phase_springs]
    # Equality classes, as _dense_times.
    ties = list(zip(tie_a, tie_b, problem._tie_d))
    for a, b, spring in zip(phase_a, phase_b, phase_springs):
        if spring[5] - spring[4] <= TOLERANCE:
            ties.append((b, a, spring[4]))
    classes = _equality_classes(ties, n_keys)
    if classes is None:
        return None  # contradictory: the numpy path names the conflict
    parent, offset = classes
    for k in range(n_keys):
        up = parent[k]
        if parent[up] != up:  # not yet a child of its root
            _find(parent, offset, k)
    pinned = parent[0]
    pinned_value = -offset[0]
    roots = [k for k in range(n_keys) if parent[k] == k and k != pinned]
    n = len(roots)
    var_of_root = dict(zip(roots, range(n)))
    var_of_root[pinned] = -1
    var = [var_of_root[r] for r in parent]
    const = [o + pinned_value if r == pinned else o for r, o in zip(parent, offset)]
    earliest: dict[int, int] = {}
    for k in range(n_keys):
        r = parent[k]
        if r == pinned:
            if const[k] < -TOLERANCE:
                return None
        elif offset[k] < offset[earliest.get(r, r)]:
            earliest[r] = k
    earliest_keys = [earliest.get(r, r) for r in roots]

    # Cost components and pulled starts, as _dense_times.
    owner, n_chains = problem._owner, problem._behaviours
    node = [owner[k] if owner[k] >= 0 else n_chains + k for k in kept_keys].__getitem__
    group, pinned_comp, pulled = _cost_components(
        problem, ties, node, n_chains + problem.size, index_of
    )

    # Every row x_i - x_j >= b of the full problem (index -1: zero), the
    # springs w (x_i - x_j + c)^2 (i: the later point), and which rows a
    # spring's phase owns.
    rows: list[tuple[int, int, float]] = []
    for u, lo, m in zip(problem._order_upper, problem._order_lower, problem._order_min,
                        ):  # fmt: skip
        u, lo = index_of[u], index_of[lo]
        rows.append((var[u], var[lo], m - const[u] + const[lo]))
    springs: list[_Spring] = []
    for a, b, (_, _, preferred, w, low, high) in zip(phase_a, phase_b, phase_springs,
                                                     ):  # fmt: skip
        vi, vj = var[b], var[a]
        shift = const[b] - const[a]
        own = [len(rows)]
        rows.append((vi, vj, low - shift))
        if high - low > TOLERANCE and high < math.inf:
            own.append(len(rows))
            rows.append((vj, vi, shift - high))
        if vi != vj:
            springs.append((vi, vj, shift - preferred, w, own))
    for k in earliest_keys:
        rows.append((var[k], -1, -const[k]))
    for i, j, bound in rows:
        if i == j and bound > TOLERANCE:
            return None  # a fixed time breaks a bound: the numpy path explains

    # Eliminate, solve, check; a point whose eliminated bound turns out
    # to be active is kept the next time (a phase squeezed to its minimum).
    keep = [False] * n
    for i, j, _ in rows[: len(problem._order_min)]:
        if i >= 0:
            keep[i] = True
        if j >= 0:
            keep[j] = True
    pulled_vars = [var[k] for k in pulled]
    for v in pulled_vars:
        keep[v] = True
    comp_of_var = [_root(group, node(r)) for r in roots] if pulled else []
    key_comp = [_root(group, node(k)) for k in range(n_keys)] if pulled else []
    pull2 = 2.0 * PULL * (sum(flat[0::4]) / n_phases if n_phases else 1.0)
    for _ in range(TINY_ATTEMPTS):
        x = _tiny_attempt(
            keep, springs, rows, len(problem._order_min), earliest_keys, var, const, pulled,
            pull2, comp_of_var, key_comp, pinned_comp, pdas_steps,
        )  # fmt: skip
        if x is None:
            return None
        slack = [x[i] - x[j] - b for i, j, b in rows]
        if not slack or min(slack) >= -TOLERANCE:
            return [x[v] + c for v, c in zip(var, const)]
        more = False
        for (i, j, _), value in zip(rows, slack):
            if value < -TOLERANCE:
                for v in (i, j):
                    if v >= 0 and not keep[v]:
                        keep[v] = more = True
        if not more:
            return None
    return None


def _tiny_attempt(
    keep: list[bool],
    base_springs: list[_Spring],
    rows: list[tuple[int, int, float]],
    n_orderings: int,
    earliest_keys: list[int],
    var: list[int],
    const: list[float],
    pulled: list[int],
    pull2: float,
    comp_of_var: list[int],
    key_comp: list[int],
    pinned_comp: int,
    pdas_steps: int,
) -> list[float] | None:
    """One elimination and solve of :func:`tiny_times` with the points ``keep`` kept.

    Returns every variable's value (and 0.0 for index -1), which the
    caller checks against every row, or None (numpy decides).
    """
    n = len(keep)
    keep = keep[:]
    springs = base_springs[:]  # combined springs are appended; none is changed
    # Eliminate dangling ends and springs in series.
    touching: list[list[int]] = [[] for _ in range(n)]
    for s, spring in enumerate(springs):
        i, j = spring[0], spring[1]
        if i >= 0:
            touching[i].append(s)
        if j >= 0:
            touching[j].append(s)
    live = [True] * len(springs)
    # (v, other, delta, -2, 0, 0) for x_v = x_other + delta, or (v, u1, d1,
    # u2, d2, share) for x_v = u1 + d1 + share (u2 + d2 - u1 - d1), undone
    # in reverse order.
    steps: list[_Step] = []
    gone = [False] * n
    work = [v for v in range(n) if not keep[v]]
    while work:
        v = work.pop()
        if gone[v] or keep[v]:
            continue
        mine = [s for s in touching[v] if live[s]]
        if len(mine) > 2 or not mine:
            continue  # mine empty: no cost holds v (singular): numpy decides
        ends = []
        for s in mine:
            i, j, c, w, _ = springs[s]
            # x_v - other ~ delta with weight w
            ends.append((j, -c, w) if i == v else (i, c, w))
        if len(mine) == 1:
            other, delta, _ = ends[0]
            steps.append((v, other, delta, -2, 0.0, 0.0))
            live[mine[0]] = False
            gone[v] = True
            if other >= 0 and not keep[other]:
                work.append(other)
            continue
        (u1, d1, w1), (u2, d2, w2) = ends
        share = w2 / (w1 + w2)
        steps.append((v, u1, d1, u2, d2, share))
        live[mine[0]] = live[mine[1]] = False
        gone[v] = True
        if u1 != u2:
            springs.append((u1, u2, d1 - d2, w1 * w2 / (w1 + w2), None))
            live.append(True)
            for u in (u1, u2):
                if u >= 0:
                    touching[u].append(len(springs) - 1)
        for u in (u1, u2):
            if u >= 0 and not keep[u]:
                work.append(u)
    kept = [v for v in range(n) if not gone[v]]
    m = len(kept)
    if m > TINY_VARIABLES:
        return None
    index = [-1] * n
    for position, v in enumerate(kept):
        index[v] = position

    # The reduced quadratic 1/2 y'Hy + g'y, with and without the pull.
    hessian = [[0.0] * m for _ in range(m)]
    gradient = [0.0] * m
    reduced_rows: list[tuple[int, int, float]] = []
    for s, (i, j, c, w, own) in enumerate(springs):
        if not live[s]:
            continue
        ri, rj = (index[i] if i >= 0 else -1), (index[j] if j >= 0 else -1)
        w2 = 2.0 * w
        if ri >= 0:
            hessian[ri][ri] += w2
            gradient[ri] += w2 * c
        if rj >= 0:
            hessian[rj][rj] += w2
            gradient[rj] -= w2 * c
        if ri >= 0 and rj >= 0:
            hessian[ri][rj] -= w2
            hessian[rj][ri] -= w2
        if own is not None:
            for r in own:
                reduced_rows.append(rows[r])
    for i, j, b in rows[:n_orderings]:
        reduced_rows.append((i, j, b))
    for k in earliest_keys:
        if not gone[var[k]]:
            reduced_rows.append((var[k], -1, -const[k]))
    reduced_rows = [
        (index[i] if i >= 0 else -1, index[j] if j >= 0 else -1, b)
        for i, j, b in reduced_rows
        if i != j
    ]
    if pulled:
        for k in pulled:
            r = index[var[k]]
            hessian[r][r] += pull2
            gradient[r] += pull2 * const[k]

    y = _tiny_kkt(hessian, gradient, reduced_rows, [])
    if y is None:
        return None
    x = _tiny_expand(y, kept, steps, n)
    if pulled:
        first: dict[int, float] = {}
        for k, comp in enumerate(key_comp):
            t = x[var[k]] + const[k]
            if t < first.get(comp, math.inf):
                first[comp] = t
        x = [
            value - first[comp] if comp != pinned_comp else value
            for value, comp in zip(x, comp_of_var)
        ] + [0.0]
    y = [x[v] for v in kept]
    y.append(0.0)  # index -1
    if reduced_rows and min([y[i] - y[j] - b for i, j, b in reduced_rows]) < -TOLERANCE:
        # Inequalities: the active-set method on the reduced problem. With
        # free groups, which rows the pulled optimum holds decides where
        # the polish leaves them, and the reduced problem may hold others:
        # numpy decides (the same method on the same rows).
        if pulled:
            return None
        del y[-1]
        solved = _tiny_active_set(hessian, gradient, reduced_rows, y, pdas_steps)
        if solved is None:
            return None
        x = _tiny_expand(solved[0], kept, steps, n)
    return x


def _tiny_expand(y: list[float], kept: list[int], steps: list[_Step], n: int) -> list[float]:
    """Every variable's value (and a last 0.0 for index -1) from the kept ones."""
    x = [0.0] * (n + 1)
    for v, value in zip(kept, y):
        x[v] = value
    for v, u1, d1, u2, d2, share in reversed(steps):
        low = x[u1] + d1
        x[v] = low if u2 == -2 else low + share * (x[u2] + d2 - low)
    return x


def _tiny_solve(matrix: list[list[float]], rhs: list[float]) -> list[float] | None:
    """Gaussian elimination with partial pivoting on a small dense system (None: singular)."""
    size = len(rhs)
    a = [[*line, value] for line, value in zip(matrix, rhs)]
    for col in range(size):
        pivot, largest = col, abs(a[col][col])
        for r in range(col + 1, size):
            value = abs(a[r][col])
            if value > largest:
                pivot, largest = r, value
        if largest < 1e-13:
            return None
        if pivot != col:
            a[col], a[pivot] = a[pivot], a[col]
        top = a[col]
        inverse = 1.0 / top[col]
        for r in range(col + 1, size):
            line = a[r]
            factor = line[col] * inverse
            if factor:
                for c in range(col, size + 1):
                    line[c] -= factor * top[c]
    solution = [0.0] * size
    for r in range(size - 1, -1, -1):
        line = a[r]
        total = line[size]
        for c in range(r + 1, size):
            total -= line[c] * solution[c]
        solution[r] = total / line[r]
    return solution


def _tiny_kkt(
    hessian: list[list[float]],
    gradient: list[float],
    rows: list[tuple[int, int, float]],
    working: list[int],
) -> list[float] | None:
    """min 1/2 y'Hy + g'y with the working rows as equalities (``solver._row_kkt``).

    Returns y followed by the multipliers of the working rows; None if the
    system is singular.
    """
    m = len(gradient)
    k = len(working)
    if m == 0:
        return [0.0] * k
    size = m + k
    matrix = [line[:] + [0.0] * k for line in hessian]
    matrix += [[0.0] * size for _ in range(k)]
    rhs = [-g for g in gradient] + [0.0] * k
    for line, row in enumerate(working):
        i, j, b = rows[row]
        at = m + line
        if i >= 0:
            matrix[at][i] = 1.0
            matrix[i][at] = -1.0
        if j >= 0:
            matrix[at][j] = -1.0
            matrix[j][at] = 1.0
        rhs[at] = b
    return _tiny_solve(matrix, rhs)


def _tiny_active_set(
    hessian: list[list[float]],
    gradient: list[float],
    rows: list[tuple[int, int, float]],
    y: list[float],
    pdas_steps: int,
) -> tuple[list[float], list[int]] | None:
    """The numpy paths' primal-dual active-set loop (``solver._pdas_steps``) in
    plain Python: the same predictions, tolerances and limits (``pdas_steps``: at
    most this many solves)."""
    m = len(y)
    extended = [*y, 0.0]
    active = [extended[i] - extended[j] - b < -TOLERANCE for i, j, b in rows]
    signatures: set[tuple[bool, ...]] = set()
    for _ in range(pdas_steps):
        forest = _Forest(m + 1)
        working = [
            r for r, on in enumerate(active)
            if on and forest.union(rows[r][0] % (m + 1), rows[r][1] % (m + 1))
        ]  # fmt: skip
        solution = _tiny_kkt(hessian, gradient, rows, working)
        if solution is None:
            return None
        y = solution[:m]
        multipliers = [0.0] * len(rows)
        for r, value in zip(working, solution[m:]):
            multipliers[r] = value
        scale = 1e-9 * (1.0 + (max([abs(value) for value in multipliers]) if multipliers else 0.0))
        extended = [*y, 0.0]
        slack = [extended[i] - extended[j] - b for i, j, b in rows]
        predicted = [
            (on and mu >= -scale) or s < -TOLERANCE for on, mu, s in zip(active, multipliers, slack)
        ]
        if predicted == active:
            if (not slack or min(slack) >= -TOLERANCE) and (
                not multipliers or min(multipliers) >= -scale
            ):
                return y, working
            return None
        signature = tuple(predicted)
        if signature in signatures:
            return None
        signatures.add(signature)
        active = predicted
    return None
