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
import operator
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from realizer.errors import RealizerError
from realizer.extras import missing_module
from realizer.scheduler.timing import Phase, TimingModel
from realizer.scheduler.tiny import (
    PULL,
    TOLERANCE,
    _cost_components,
    _equality_classes,
    _find,
    _Forest,
    _root,
    tiny_times,
)
from realizer.scheduler.tiny import (
    _chain_plan as _chain_plan,  # the tests read it here
)

if TYPE_CHECKING:  # scipy is imported by the sparse path only (_scipy)
    import scipy.sparse as sp

#: A sync point: (behaviour id, sync name). ``BLOCK_START`` is time 0.
Key = tuple[str, str]
BLOCK_START: Key = ("bml", "start")

# PULL (the start-early pull's weight relative to the mean phase weight)
# and TOLERANCE (seconds) are defined in realizer.scheduler.tiny, which the
# dense path shares helpers with, and are this module's too.
#: Steps the primal-dual active-set method may take before the fallback.
PDAS_STEPS = 50


class Source(NamedTuple):
    """Where a constraint comes from, so that a conflict can be explained.

    ``kind`` is ``behaviour`` (its own sync attributes and phases),
    ``constraint`` (a ``<constraint>`` element; ``id`` its id or position),
    ``fixed`` (a time already consumed) or ``block`` (nothing before the block).
    A named tuple (immutable, hashable, compared by value), which the planner
    makes for every behaviour of every block at a third of a frozen
    dataclass's cost.
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


#: A phase's numbers as the solvers read them: weight, preferred, minimum, maximum.
_PHASE_FIELDS = operator.attrgetter("weight", "preferred", "minimum", "maximum")


@dataclass(slots=True)
class Problem:
    """Sync points, phases and constraints of one block (or several).

    ``keys`` maps every sync point to its index (the order of first
    mention; :data:`BLOCK_START` is 0); it is made when read, since the
    solvers need only the number of keys (:attr:`size`): a behaviour added
    with new keys (the usual case) is recorded as the index of its first
    key and its sync names' positions, not as one entry per sync point.
    ``phases``, ``equalities``,
    ``orderings`` and ``starts`` say what was added, in the caller's terms;
    they are made on demand (only a conflict, a test or a tool reads them)
    from what the methods record. The solvers read the index lists (the
    private fields), so a problem is only ever changed through the methods.
    """

    #: how many keys (sync points) there are; they are 0 .. size - 1
    size: int = field(default=0, init=False)
    #: the keys with an entry of their own: the block start, keys named
    #: before (or without) their behaviour, and those of behaviours whose
    #: keys were not all new; the others are found by :attr:`_first`
    _named: dict[Key, int] = field(default_factory=dict, repr=False)
    #: the behaviour ids of :attr:`_named`'s keys
    _named_ids: set[str] = field(default_factory=set, repr=False)
    #: behaviour id -> its sync names' positions, for those in :attr:`_first`
    _positions: dict[str, Mapping[str, int]] = field(default_factory=dict, repr=False)
    #: :attr:`keys` as last made (valid while it has :attr:`size` entries)
    _keys: dict[Key, int] = field(default_factory=dict, repr=False)
    #: each behaviour as added: id, sync names, phases, source, and the index
    #: of its first key (consecutive keys) or the list of its key indices
    _chains: list[tuple[str, tuple[str, ...], tuple[Phase, ...], Source, int | list[int]]] = field(
        default_factory=list, repr=False
    )
    #: each equality and ordering as given: a, ka, b, kb, source
    _tie_given: list[tuple[Key, float, Key, float, Source]] = field(
        default_factory=list, repr=False
    )
    _order_given: list[tuple[Key, float, Key, float, Source]] = field(
        default_factory=list, repr=False
    )
    # The same in key indices, in step with the lists above.
    _phase_a: list[int] = field(default_factory=list, repr=False)
    _phase_b: list[int] = field(default_factory=list, repr=False)
    #: weight, preferred, minimum, maximum of each phase, one after the other
    _phase_table: list[float] = field(default_factory=list, repr=False)
    #: t_a - t_b = d of each equality: a, b, d
    _tie_a: list[int] = field(default_factory=list, repr=False)
    _tie_b: list[int] = field(default_factory=list, repr=False)
    _tie_d: list[float] = field(default_factory=list, repr=False)
    #: t_upper - t_lower >= minimum of each ordering
    _order_upper: list[int] = field(default_factory=list, repr=False)
    _order_lower: list[int] = field(default_factory=list, repr=False)
    _order_min: list[float] = field(default_factory=list, repr=False)
    _starts: list[int] = field(default_factory=list, repr=False)
    #: the behaviour (its number in add order) each key belongs to, or -1;
    #: phases tie a behaviour's keys into one cost component
    _owner: list[int] = field(default_factory=list, repr=False)
    #: pairs of behaviours that share a key (so one cost component)
    _links: list[tuple[int, int]] = field(default_factory=list, repr=False)
    _behaviours: int = field(default=0, repr=False)
    #: behaviour id -> the index of its first key, for behaviours whose keys
    #: got consecutive indices (the usual case): their times are one slice
    _first: dict[str, int] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self._index(BLOCK_START)

    @property
    def keys(self) -> dict[Key, int]:
        """Every sync point and its index, in index order."""
        made = self._keys
        if len(made) == self.size:
            return made
        names: list[Key] = [BLOCK_START] * self.size
        first_of = self._first
        for behaviour_id, syncs, _, _, first in self._chains:
            if isinstance(first, int) and first_of.get(behaviour_id) == first:
                names[first : first + len(syncs)] = [(behaviour_id, sync) for sync in syncs]
        for key, index in self._named.items():
            names[index] = key
        made = self._keys = dict(zip(names, range(self.size), strict=True))
        return made

    def index_of(self, key: Key) -> int | None:
        """The index of ``key``, or None if the problem does not have it."""
        behaviour_id, sync = key
        first = self._first.get(behaviour_id)
        if first is not None:
            position = self._positions[behaviour_id].get(sync)
            if position is not None:
                return first + position
        return self._named.get(key)

    @property
    def phases(self) -> list[tuple[Key, Key, Phase, Source]]:
        """Every phase as (earlier key, later key, phase, source), in add order."""
        found: list[tuple[Key, Key, Phase, Source]] = []
        for behaviour_id, syncs, phases, source, _ in self._chains:
            keys = [(behaviour_id, sync) for sync in syncs]
            found.extend(zip(keys, keys[1:], phases, itertools.repeat(source)))
        return found

    @property
    def starts(self) -> list[Key]:
        """The first key of every behaviour, in add order."""
        return [(behaviour_id, syncs[0]) for behaviour_id, syncs, *_ in self._chains]

    @property
    def equalities(self) -> list[_Relation]:
        """``t_a + ka == t_b + kb`` as given, in add order."""
        return [_Relation(*given) for given in self._tie_given]

    @property
    def orderings(self) -> list[_Relation]:
        """``t_a + ka <= t_b + kb`` as given, in add order."""
        return [_Relation(*given) for given in self._order_given]

    def _index(self, key: Key) -> int:
        index = self.index_of(key)
        if index is None:
            index = self._named[key] = self.size
            self.size = index + 1
            self._named_ids.add(key[0])
            self._owner.append(-1)
        return index

    def add_behaviour(
        self, behaviour_id: str, syncs: tuple[str, ...], phases: Iterable[Phase], source: Source
    ) -> None:
        """A behaviour's sync points in order and the phases between them."""
        phases = tuple(phases)
        if len(phases) != len(syncs) - 1:
            raise ValueError(f"{len(syncs)} sync points need {len(syncs) - 1} phases")
        table = list(itertools.chain.from_iterable(map(_PHASE_FIELDS, phases)))
        syncs = tuple(syncs)
        positions = {sync: position for position, sync in enumerate(syncs)}
        self._add(behaviour_id, syncs, phases, table, source, positions)

    def add_model(self, behaviour_id: str, model: TimingModel, source: Source) -> int:
        """:meth:`add_behaviour` with a timing model's syncs and phases.

        Returns the index of the behaviour's first key; when its keys are
        new (the usual case) they are that index and the ones after it,
        in the model's order (``model.positions``).
        """
        return self._add(
            behaviour_id, model.syncs, model.phases, model.table, source, model.positions
        )

    def _add(
        self,
        behaviour_id: str,
        syncs: tuple[str, ...],
        phases: tuple[Phase, ...],
        table: Iterable[float],
        source: Source,
        positions: Mapping[str, int],
    ) -> int:
        chain = self._behaviours
        self._behaviours += 1
        first = self.size
        size = len(syncs)
        first_of = self._first
        if (
            behaviour_id not in first_of
            and behaviour_id not in self._named_ids
            and len(positions) == size  # no sync name repeats
        ):  # all new and distinct: consecutive indices
            last = self.size = first + size
            self._owner.extend([chain] * size)
            first_of[behaviour_id] = first
            self._positions[behaviour_id] = positions
            self._chains.append((behaviour_id, syncs, phases, source, first))
            self._starts.append(first)
            self._phase_a.extend(range(first, last - 1))
            self._phase_b.extend(range(first + 1, last))
        else:  # known keys keep their place
            earlier = first_of.pop(behaviour_id, None)
            if earlier is not None:  # the same id added before: its keys get entries
                for sync, position in self._positions.pop(behaviour_id).items():
                    self._named[(behaviour_id, sync)] = earlier + position
                self._named_ids.add(behaviour_id)
            indices = [self._index((behaviour_id, sync)) for sync in syncs]
            owner = self._owner
            for index in indices:
                if owner[index] >= 0 and owner[index] != chain:
                    self._links.append((owner[index], chain))
                owner[index] = chain
            self._chains.append((behaviour_id, syncs, phases, source, indices))
            self._starts.append(indices[0])
            self._phase_a.extend(indices[:-1])
            self._phase_b.extend(indices[1:])
            first = indices[0]
        self._phase_table.extend(table)
        return first

    def equal(self, a: Key, ka: float, b: Key, kb: float, source: Source) -> None:
        """``t_a + ka == t_b + kb``."""
        index_of = self.index_of
        index = index_of(a)
        self._tie_a.append(self._index(a) if index is None else index)
        index = index_of(b)
        self._tie_b.append(self._index(b) if index is None else index)
        self._tie_d.append(kb - ka)
        self._tie_given.append((a, ka, b, kb, source))

    def order(self, a: Key, ka: float, b: Key, kb: float, source: Source) -> None:
        """``t_a + ka <= t_b + kb``."""
        self._order_lower.append(self._index(a))
        self._order_upper.append(self._index(b))
        self._order_min.append(ka - kb)
        self._order_given.append((a, ka, b, kb, source))

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
    constraints cannot all hold. Tiny problems (up to :data:`TINY_KEYS`
    sync points) first try the pure-Python :func:`solve_tiny`; small ones
    (up to :data:`DENSE_KEYS`) take :func:`solve_dense`, the others
    :func:`solve_sparse`; all give the same times.
    """
    size = problem.size
    if size <= TINY_KEYS:
        times = _tiny_times(problem)
        if times is not None:
            return dict(zip(problem.keys, times, strict=True))
    if size <= DENSE_KEYS:
        return solve_dense(problem)
    return solve_sparse(problem)


def solve_times(problem: Problem) -> list[float]:
    """:func:`solve`'s times as a list in the order of ``problem.keys`` (no dict)."""
    size = problem.size
    if size <= TINY_KEYS:
        times = _tiny_times(problem)
        if times is not None:
            return times
    if size <= DENSE_KEYS:
        return _dense_times(problem)
    return _sparse_times(problem)


def _scipy() -> Any:
    """scipy, which only the sparse path needs: the ``schedule`` extra.

    Without it, blocks up to :data:`DENSE_KEYS` sync points are scheduled
    by the dense path (numpy only); a bigger one raises
    :class:`realizer.extras.MissingExtraError` naming the extra.
    """
    try:
        import scipy.linalg
        import scipy.sparse
        import scipy.sparse.csgraph
        import scipy.sparse.linalg
    except ModuleNotFoundError as error:
        raise missing_module(
            error,
            "schedule",
            f"scheduling a block of more than {DENSE_KEYS} sync points (the sparse solver)",
        ) from error
    return scipy


def warm_up() -> bool:
    """Import the sparse path's scipy now, if it is installed; False if it is not.

    A process that serves calls this at start: imported lazily, scipy would
    be imported by the first big block, on a planner thread, holding the
    interpreter lock for a few hundred milliseconds (seen: a 678 ms stall of
    a worker's frame clock), a frame gap for every viewer.
    """
    try:
        _scipy()
    except ImportError:
        return False
    return True


def solve_sparse(problem: Problem) -> dict[Key, float]:
    """:func:`solve` on sparse matrices, vectorised: the path for big blocks."""
    return dict(zip(problem.keys, _sparse_times(problem), strict=True))


def _sparse_times(problem: Problem) -> list[float]:
    """:func:`solve_sparse`'s times in key order."""
    scipy = _scipy()
    sp, csgraph = scipy.sparse, scipy.sparse.csgraph
    n_keys = problem.size
    # The problem's index lists become arrays in one call each.
    table = np.array(problem._phase_table, dtype=float).reshape(-1, 4)
    phase_a = np.array(problem._phase_a, dtype=np.int64)
    phase_b = np.array(problem._phase_b, dtype=np.int64)
    phase_w, phase_p, phase_min, phase_max = table[:, 0], table[:, 1], table[:, 2], table[:, 3]
    # A phase whose bounds meet is an equality; as two rows it would make
    # the active-set systems singular. t_a - t_b = d for every equality
    # (sync references, <synchronize>, fixed times, rigid phases).
    rigid = phase_max - phase_min <= TOLERANCE
    eq_a = np.concatenate([np.array(problem._tie_a, dtype=np.int64), phase_b[rigid]])
    eq_b = np.concatenate([np.array(problem._tie_b, dtype=np.int64), phase_a[rigid]])
    eq_d = np.concatenate([np.array(problem._tie_d, dtype=float), phase_min[rigid]])
    key_class, key_offset = _eliminate(n_keys, eq_a, eq_b, eq_d)
    if eq_a.size and np.abs(key_offset[eq_a] - key_offset[eq_b] - eq_d).max() > TOLERANCE:
        conflict = find_conflict(problem)
        raise Infeasible(conflict or frozenset(), "contradictory equalities")
    n_classes = int(key_class.max(initial=-1)) + 1
    block = 0  # BLOCK_START's index
    pinned_class = int(key_class[block])
    # The pinned class's value makes t_block = 0.
    pinned_value = -float(key_offset[block])

    # Cost components: classes linked by phases. Those without the pinned
    # class may shift freely and get the start-early pull.
    linked = sp.csr_matrix(
        (np.ones(phase_a.size), (key_class[phase_a], key_class[phase_b])),
        shape=(n_classes, n_classes),
    )
    _, comp = csgraph.connected_components(linked, directed=False)
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
    start_rows = np.array(problem._starts, dtype=np.int64)
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

    def exact() -> tuple[Any, np.ndarray]:
        """The objective without the pull: only the polish and the fallback need it."""
        if not n_pulled:
            return hessian, gradient  # the same terms
        return _quadratic(n, term_i[:n_phase], term_j[:n_phase], term_c[:n_phase], phase_w)

    # Inequalities as rows ``t_upper - t_lower >= minimum`` (key indices, -1: zero).
    stretchy = np.isfinite(phase_max) & (phase_max - phase_min > TOLERANCE)
    order_upper = np.array(problem._order_upper, dtype=np.int64)
    order_lower = np.array(problem._order_lower, dtype=np.int64)
    order_min = np.array(problem._order_min, dtype=float)
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
    ri, ci = as_var(upper)
    rj, cj = as_var(lower)
    b = minimum - ci + cj
    constant = ri == rj  # nothing variable: a plain check
    broken = np.flatnonzero(constant & (b > TOLERANCE))
    if broken.size:
        conflict = find_conflict(problem)
        raise Infeasible(
            conflict or frozenset({_row_source(problem, stretchy.tolist(), int(broken[0]))}),
            "a fixed time breaks a bound",
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
                exact(), matrix, ri, rj, b, solved[1], solved[0], pulled, var_comp, pinned_comp
            )
        else:
            # The fast method cycled or met a degenerate working set: the
            # primal active-set method from a feasible point always ends.
            start = _feasible_point(n, ri, rj, b)
            if start is None:
                conflict = find_conflict(problem)
                raise Infeasible(conflict or frozenset(), "the constraints cannot all hold")
            solved_x = _active_set(hessian, gradient, matrix, ri, rj, b, start, exact(), pulled,
                                   var_comp, pinned_comp)  # fmt: skip
            if solved_x is None:
                raise SchedulingError("the scheduler's active-set method did not converge")
            x = solved_x

    values = np.where(var_of_class >= 0, 0.0, pinned_value)
    values[free] = x
    times = values[key_class] + key_offset
    times_list: list[float] = times.tolist()
    return times_list


def _row_source(problem: Problem, stretchy: list[bool], row: int) -> Source:
    """The source of inequality row ``row`` of :func:`solve_sparse`'s list:
    orderings, phase minima, finite phase maxima, then t >= 0."""
    orderings = problem._order_given
    if row < len(orderings):
        return orderings[row][4]
    row -= len(orderings)
    phase_sources = [source for _, _, _, source in problem.phases]
    if row < len(phase_sources):
        return phase_sources[row]
    row -= len(phase_sources)
    maxima = [source for source, keep in zip(phase_sources, stretchy, strict=True) if keep]
    return maxima[row] if row < len(maxima) else BLOCK_SOURCE


# -- the dense path for small problems -------------------------------------------


def solve_dense(problem: Problem) -> dict[Key, float]:
    """:func:`solve` for small problems: the same method on dense matrices, numpy only.

    See :func:`_dense_times`.
    """
    return dict(zip(problem.keys, _dense_times(problem), strict=True))


def _dense_times(problem: Problem) -> list[float]:
    """:func:`solve_dense`'s times in key order.

    A block of a few behaviours is a few dozen sync points, for which the
    sparse path spends nearly all its time building scipy.sparse objects
    and array temporaries around a tiny system. Here the bookkeeping is
    plain Python over the problem's index lists, touching only what a tie
    touches: equality classes by a weighted union-find over the ties, cost
    components by a union-find over behaviours (a behaviour's phases hold
    its sync points together) and the ties between them. The arrays are
    then built in a fixed number of numpy calls (about thirty, whatever
    the size), the Hessian summed by ``bincount`` and the KKT systems
    solved by ``numpy.linalg.solve``; scipy is never imported. The method
    is the sparse path's step for step (the optimum without inequalities
    shifted to start at 0, the primal-dual active-set method, the polish,
    and should it cycle the primal active-set method from a feasible point
    found by Bellman-Ford), so results equal the sparse path's (tests
    compare them on random problems).
    """
    n_keys = problem.size
    phase_a, phase_b, flat = problem._phase_a, problem._phase_b, problem._phase_table
    table = np.array(flat, dtype=float).reshape(-1, 4)
    # Equality classes with offsets, t_key = t_root + offset[key]: the ties
    # t_a - t_b = d (sync references, fixed times, rigid phases).
    ties = list(zip(problem._tie_a, problem._tie_b, problem._tie_d, strict=True))
    rigid = table[:, 3] - table[:, 2] <= TOLERANCE
    if np.count_nonzero(rigid):
        for p in np.flatnonzero(rigid).tolist():
            ties.append((phase_b[p], phase_a[p], flat[4 * p + 2]))
    classes = _equality_classes(ties, n_keys)
    if classes is None:
        conflict = find_conflict(problem)
        raise Infeasible(conflict or frozenset(), "contradictory equalities")
    parent, offset = classes
    tied = {k for a, b, _ in ties for k in (a, b)}
    for k in tied:  # flatten: parent[k] is k's root, offset[k] relative to it
        _find(parent, offset, k)
    pinned = parent[0]  # the class of BLOCK_START, index 0
    pinned_value = -offset[0]
    # Variables: every class but the pinned one; t_key = x[var[key]] + const[key]
    # (var -1: the pinned class, const is then the time itself).
    roots = [k for k in range(n_keys) if parent[k] == k and k != pinned]
    n = len(roots)
    var_of_root = dict(zip(roots, range(n), strict=True))
    var_of_root[pinned] = -1
    var = [var_of_root[r] for r in parent]
    const = offset[:]
    # t >= 0 holds on a class when it holds on its earliest key.
    earliest: dict[int, int] = {}
    for k in tied | {pinned}:
        r = parent[k]
        if r == pinned:
            const[k] = offset[k] + pinned_value
            if const[k] < -TOLERANCE:
                conflict = find_conflict(problem)
                raise Infeasible(
                    conflict or frozenset({BLOCK_SOURCE}), "a fixed time breaks a bound"
                )
        elif offset[k] < offset[earliest.get(r, r)]:
            earliest[r] = k
    earliest_keys = [earliest.get(r, r) for r in roots]

    # Cost components: behaviours (each held together by its phases) and
    # keys of no behaviour, joined by the ties. Those without the block
    # start may shift freely: one start of each gets the start-early pull.
    owner, n_chains = problem._owner, problem._behaviours

    def node(k: int) -> int:
        return owner[k] if owner[k] >= 0 else n_chains + k

    group, pinned_comp, pulled = _cost_components(problem, ties, node, n_chains + n_keys, None)

    # Objective: sum w (x_i - x_j + c)^2 over phases (i: the later point),
    # as 1/2 x'Hx + g'x, plus the pull on the pulled starts.
    var_arr = np.array([*var, -1], dtype=np.int64)  # index n_keys: no key
    const_arr = np.array([*const, 0.0])
    pa = np.array(phase_a, dtype=np.int64)
    pb = np.array(phase_b, dtype=np.int64)
    term_i, term_j = var_arr[pb], var_arr[pa]
    term_c = const_arr[pb] - const_arr[pa] - table[:, 1]
    exact = _dense_quadratic(n, term_i, term_j, term_c, 2.0 * table[:, 0])
    hessian, gradient = exact
    pulled_vars = var_arr[pulled]
    if pulled:
        pull2 = 2.0 * PULL * (float(table[:, 0].mean()) if table.size else 1.0)
        hessian = hessian.copy()
        hessian[pulled_vars, pulled_vars] += pull2  # distinct: one per component
        gradient = gradient.copy()
        gradient[pulled_vars] += pull2 * const_arr[pulled]

    # Rows x_i - x_j >= b: orderings, phase minima, finite phase maxima, and
    # t >= 0 on the earliest key of every class.
    stretchy = np.isfinite(table[:, 3]) & (table[:, 3] - table[:, 2] > TOLERANCE)
    ek = np.array(earliest_keys, dtype=np.int64)
    upper = np.concatenate([np.array(problem._order_upper, dtype=np.int64), pb, pa[stretchy], ek])
    lower = np.concatenate(
        [
            np.array(problem._order_lower, dtype=np.int64),
            pa,
            pb[stretchy],
            np.full(ek.size, n_keys, dtype=np.int64),
        ]
    )
    minimum = np.concatenate(
        [np.array(problem._order_min, dtype=float), table[:, 2], -table[stretchy, 3],
         np.zeros(ek.size)]
    )  # fmt: skip
    row_i, row_j = var_arr[upper], var_arr[lower]
    b_rows = minimum - const_arr[upper] + const_arr[lower]
    constant = row_i == row_j  # nothing variable: a plain check
    if np.count_nonzero(constant):
        broken = np.flatnonzero(constant & (b_rows > TOLERANCE))
        if broken.size:
            conflict = find_conflict(problem)
            source = _row_source(problem, stretchy.tolist(), int(broken[0]))
            raise Infeasible(conflict or frozenset({source}), "a fixed time breaks a bound")
        keep = ~constant
        row_i, row_j, b_rows = row_i[keep], row_j[keep], b_rows[keep]

    x, _ = _row_kkt(hessian, gradient, row_i, row_j, [], b_rows)
    if x is None:
        raise SchedulingError("the scheduler's cost matrix is singular")
    comp_of_var = np.zeros(n, dtype=np.int64)
    if pulled:
        # Each free component moved so that its earliest point is at the block start.
        comp_of_var[:] = [_root(group, node(r)) for r in roots]
        comp_of_key = np.array([_root(group, node(k)) for k in range(n_keys)], dtype=np.int64)
        times = np.append(x, 0.0)[var_arr[:-1]] + const_arr[:-1]
        first = np.full(n_chains + n_keys, np.inf)
        np.minimum.at(first, comp_of_key, times)
        x = x - np.where(comp_of_var != pinned_comp, first[comp_of_var], 0.0)
    if b_rows.size and float(_slack(x, row_i, row_j, b_rows).min()) < -TOLERANCE:
        solved = _dense_active_set(hessian, gradient, row_i, row_j, b_rows, x)
        if solved is not None and not pulled:
            x = solved[0]  # nothing was pulled: already the exact optimum
        elif solved is not None:
            matrix = _incidence(row_i, row_j, n)
            x = _polish(
                exact, matrix, row_i, row_j, b_rows, solved[1], solved[0], pulled_vars,
                comp_of_var, pinned_comp, kkt=_dense_kkt,
            )  # fmt: skip
        else:
            # The fast method cycled or met a degenerate working set: the
            # primal active-set method from a feasible point always ends.
            matrix = _incidence(row_i, row_j, n)
            start = _feasible_point_dense(n, row_i, row_j, b_rows)
            if start is None:
                conflict = find_conflict(problem)
                raise Infeasible(conflict or frozenset(), "the constraints cannot all hold")
            solved_x = _active_set(hessian, gradient, matrix, row_i, row_j, b_rows, start,
                                   exact, pulled_vars, comp_of_var, pinned_comp,
                                   kkt=_dense_kkt)  # fmt: skip
            if solved_x is None:
                raise SchedulingError("the scheduler's active-set method did not converge")
            x = solved_x
    values = [*x.tolist(), 0.0]  # var -1: the pinned class, whose const is its time
    return [values[v] + c for v, c in zip(var, const, strict=True)]


def _slack(x: np.ndarray, ri: np.ndarray, rj: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x_i - x_j - b`` of every row (index -1: the zero appended to ``x``)."""
    extended = np.append(x, 0.0)
    slack: np.ndarray = extended[ri] - extended[rj] - b
    return slack


def _row_kkt(
    hessian: np.ndarray,
    gradient: np.ndarray,
    ri: np.ndarray,
    rj: np.ndarray,
    working: list[int],
    b: np.ndarray,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:func:`_dense_kkt` with the rows given by their indices (no m x n matrix)."""
    n = hessian.shape[0]
    k = len(working)
    if n == 0:
        return np.zeros(0), (np.zeros(k) if k else None)
    try:
        if not k:
            solution = np.linalg.solve(hessian, -gradient)
            return (solution, None) if np.isfinite(solution).all() else (None, None)
        kkt = np.zeros((n + k + 1, n + k + 1))  # index -1 (absent) lands in the last row and column
        kkt[:n, :n] = hessian
        lines = np.arange(n, n + k)
        wi, wj = ri[working], rj[working]
        kkt[lines, wi] = 1.0
        kkt[wi, lines] = -1.0
        kkt[lines, wj] = -1.0
        kkt[wj, lines] = 1.0
        rhs = np.concatenate([-gradient, b[working]])
        solution = np.linalg.solve(kkt[:-1, :-1], rhs)
    except np.linalg.LinAlgError:
        return None, None
    if not np.isfinite(solution).all():
        return None, None
    return solution[:n], solution[n:]


def _independent_rows(ri: list[int], rj: list[int], rows: list[int], n: int) -> list[int]:
    """:func:`_independent` on lists (index -1: the zero node)."""
    forest = _Forest(n + 1)
    union = forest.union
    return [row for row in rows if union(ri[row] % (n + 1), rj[row] % (n + 1))]


#: One step of the primal-dual active-set method: x, the working rows'
#: multipliers, the working rows, and every row's slack at x.
_PdasStep = tuple[np.ndarray, "np.ndarray | None", list[int], np.ndarray]


def _dense_active_set(
    hessian: np.ndarray,
    gradient: np.ndarray,
    ri: np.ndarray,
    rj: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
) -> tuple[np.ndarray, list[int]] | None:
    """:func:`_primal_dual_active_set` step for step, on rows given by their indices.

    The same predictions, tolerances and ways to give up, without an m x n
    matrix: slacks by indexing (:func:`_slack`), KKT systems from the
    working rows alone (:func:`_row_kkt`).
    """
    n = x.size
    ri_list, rj_list = ri.tolist(), rj.tolist()

    def step(active: np.ndarray) -> _PdasStep | None:
        working = _independent_rows(ri_list, rj_list, np.flatnonzero(active).tolist(), n)
        solution, lam = _row_kkt(hessian, gradient, ri, rj, working, b)
        if solution is None:
            return None
        return solution, lam, working, _slack(solution, ri, rj, b)

    return _pdas_steps(_slack(x, ri, rj, b) < -TOLERANCE, step)


def _dense_quadratic(
    n: int, i: np.ndarray, j: np.ndarray, c: np.ndarray, w2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Dense H and g of sum w2/2 (x_i - x_j + c)^2 as 1/2 x'Hx + g'x (index -1: absent).

    Summed by ``bincount`` (index -1 goes to a row and column n that is cut
    off), not as D'WD: a matrix product goes to the threaded BLAS, which on
    a busy machine costs a hundred times more.
    """
    size = n + 1
    i, j = i % size, j % size  # -1 -> n
    flat = np.concatenate([i * (size + 1), j * (size + 1), i * size + j, j * size + i])
    weights = np.concatenate([w2, w2, -w2, -w2])
    hessian = np.bincount(flat, weights, size * size).reshape(size, size)[:n, :n]
    wc = w2 * c
    gradient = (np.bincount(i, wc, size) - np.bincount(j, wc, size))[:n]
    return np.ascontiguousarray(hessian), gradient


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
    try:
        if not working:
            solution = np.linalg.solve(hessian, -gradient)
            return (solution, None) if np.isfinite(solution).all() else (None, None)
        active = matrix[working]
        k = len(working)
        kkt = np.zeros((n + k, n + k))
        kkt[:n, :n] = hessian
        kkt[:n, n:] = -active.T
        kkt[n:, :n] = active
        solution = np.linalg.solve(kkt, np.concatenate([-gradient, b[working]]))
    except np.linalg.LinAlgError:
        return None, None
    if not np.isfinite(solution).all():
        return None, None
    return solution[:n], solution[n : n + k]


def _feasible_point_dense(
    n: int, ri: np.ndarray, rj: np.ndarray, b: np.ndarray
) -> np.ndarray | None:
    """:func:`_feasible_point` without scipy: Bellman-Ford over arrays, for small problems.

    Row ``x_i - x_j >= b`` is the edge i -> j of weight -b (-1: the zero
    node n); every node starts at distance 0 (a virtual source joined to
    all), and a relaxation still possible after n + 1 rounds is a negative
    cycle.
    """
    u = np.where(ri >= 0, ri, n)
    v = np.where(rj >= 0, rj, n)
    weight = -b
    distance = np.zeros(n + 1)
    for _ in range(n + 2):
        candidate = distance[u] + weight
        if not (candidate < distance[v] - TOLERANCE).any():
            return np.asarray(distance[:n] - distance[n], dtype=float)
        np.minimum.at(distance, v, candidate)
    return None


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
    scipy = _scipy()
    sp, csgraph = scipy.sparse, scipy.sparse.csgraph
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
    _, labels = csgraph.connected_components(graph, directed=False)
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
    _, parent = csgraph.breadth_first_order(rooted, n_keys, directed=True, return_predecessors=True)
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
    solve = kkt or _kkt
    n = x.size

    def step(active: np.ndarray) -> _PdasStep | None:
        working = _independent(ri, rj, np.flatnonzero(active).tolist(), n)
        solution, lam = solve(hessian, gradient, matrix, working, b, quiet=True)
        if solution is None:
            return None
        return solution, lam, working, matrix @ solution - b

    return _pdas_steps((matrix @ x - b) < -TOLERANCE, step)


def _pdas_steps(
    active: np.ndarray, step: Callable[[np.ndarray], _PdasStep | None]
) -> tuple[np.ndarray, list[int]] | None:
    """The loop both :func:`_primal_dual_active_set` paths share.

    ``step`` solves the KKT system of the rows predicted ``active`` (None
    when it is singular); the loop predicts the next active rows, stops at
    the optimum, and gives up (None) on a repeated working set or after
    :data:`PDAS_STEPS` steps.
    """
    seen: set[bytes] = set()
    multipliers = np.zeros(active.size)
    for _ in range(PDAS_STEPS):
        result = step(active)
        if result is None:
            return None
        solution, lam, working, slack = result
        multipliers[:] = 0.0
        if working:
            assert lam is not None
            multipliers[working] = lam
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
    sp = _scipy().sparse
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
    sp = _scipy().sparse
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
    scipy = _scipy()
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
    graph = scipy.sparse.csr_matrix((weight, (u, v)), shape=(n + 2, n + 2))
    try:
        distance = scipy.sparse.csgraph.shortest_path(
            graph, method="BF", directed=True, indices=source
        )
    except scipy.sparse.csgraph.NegativeCycleError:
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
    kkt: Callable[..., tuple[np.ndarray | None, np.ndarray | None]] | None = None,
) -> np.ndarray | None:
    """Primal active-set method from the feasible point ``x`` (Nocedal & Wright 16.3).

    Minimises 1/2 x'Hx + g'x subject to ``matrix @ x >= b``. ``hessian`` and
    ``gradient`` include the start-early pull, which makes H definite; at the
    end the solution is polished with ``exact`` (no pull) on the final
    working set, whose bounds now pin every shift, so the result is the exact
    optimum of the phase costs.
    """
    solve_kkt = kkt or _kkt
    m = b.size
    working: list[int] = []
    in_working = np.zeros(m, dtype=bool)
    for _ in range(10 * m + 50):
        step, multipliers = solve_kkt(hessian, hessian @ x + gradient, matrix, working,
                                      np.zeros(m))  # fmt: skip
        if step is None:
            return None
        size = float(np.abs(step).max(initial=0.0))
        if size <= 1e-10 * (1 + np.abs(x).max(initial=0.0)):
            if not working or multipliers is None or multipliers.min() >= -1e-12:
                return _polish(exact, matrix, ri, rj, b, working, x, pulled, var_comp,
                               pinned_comp, kkt=kkt)  # fmt: skip
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
        sp = _scipy().sparse
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
    scipy = _scipy()
    sp, spla = scipy.sparse, scipy.sparse.linalg
    n = hessian.shape[0]
    if not working:
        if n == 0:
            return np.zeros(0), None
        banded = _band_solve(hessian, -gradient, definite=True)
        if banded is not None:
            return banded, None
        try:
            return spla.splu(hessian.tocsc()).solve(-gradient).reshape(n), None
        except RuntimeError:
            return None, None
    tied = _tied_kkt(hessian, gradient, matrix, working, b)
    if tied is not None:
        return tied
    # [[H, -A'], [A, 0]] assembled from coordinates in one constructor
    # (scipy's bmat makes the same matrix with a few times the overhead).
    active = matrix[working].tocoo()
    square = hessian.tocoo()
    k = len(working)
    kkt = sp.csc_matrix(
        (
            np.concatenate([square.data, -active.data, active.data]),
            (
                np.concatenate([square.row, active.col, active.row + n]),
                np.concatenate([square.col, active.row + n, active.col]),
            ),
        ),
        shape=(n + k, n + k),
    )
    rhs = np.concatenate([-gradient, b[working]])
    try:
        banded = _band_solve(kkt, rhs, definite=False)
        solution = banded if banded is not None else spla.splu(kkt).solve(rhs)
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


def _tied_kkt(
    hessian: sp.csc_matrix,
    gradient: np.ndarray,
    matrix: sp.csr_matrix,
    working: list[int],
    b: np.ndarray,
) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_kkt` with the working rows held as ties: one band Cholesky, no KKT LU.

    Every working row is ``x_i - x_j = b`` (one side may be the zero node);
    when they form a forest, each tree is one unknown (its root's; a tree
    holding the zero node is constant): ``x = Z y + c``. The reduced
    Hessian ``Z'HZ`` is the Hessian's entries relabelled by tree, definite
    where the KKT system is regular, and is solved as :func:`_kkt` solves
    the Hessian alone. The multipliers solve ``A'lam = Hx + g``, one row per
    tree edge, found by peeling each tree from its leaves. None (the caller
    solves the KKT system) when a row is not such a difference, the rows
    close a cycle, or the reduced system is singular.
    """
    scipy = _scipy()
    n = hessian.shape[0]
    k = len(working)
    active = matrix[working]
    counts = np.diff(active.indptr)
    data = active.data
    if counts.min() < 1 or counts.max() > 2 or not np.all(np.abs(data) == 1.0):
        return None
    row_of = np.repeat(np.arange(k), counts)
    plus = data > 0
    if np.bincount(row_of[plus], minlength=k).max(initial=0) > 1 or (
        np.bincount(row_of[~plus], minlength=k).max(initial=0) > 1
    ):
        return None
    zero = n
    upper = np.full(k, zero, dtype=np.int64)
    lower = np.full(k, zero, dtype=np.int64)
    upper[row_of[plus]] = active.indices[plus]
    lower[row_of[~plus]] = active.indices[~plus]
    ups: list[int] = upper.tolist()
    lows: list[int] = lower.tolist()
    bounds: list[float] = b[working].tolist()
    adjacent: dict[int, list[int]] = {}
    for t in range(k):
        adjacent.setdefault(ups[t], []).append(t)
        adjacent.setdefault(lows[t], []).append(t)
    # Breadth-first trees, the zero node's first: each node's root, its
    # offset to the root, and the edge to its parent.
    root: dict[int, int] = {}
    offset: dict[int, float] = {}
    visits: list[tuple[int, int, int]] = []  # (node, edge to the parent, parent)
    used = [False] * k
    starts = ([zero] if zero in adjacent else []) + list(adjacent)
    for start in starts:
        if start in root:
            continue
        root[start] = start
        offset[start] = 0.0
        queue = [start]
        for node in queue:
            for t in adjacent[node]:
                if used[t]:
                    continue
                used[t] = True
                other = lows[t] if ups[t] == node else ups[t]
                if other in root:
                    return None  # a cycle: dependent rows
                root[other] = start
                offset[other] = offset[node] + (bounds[t] if ups[t] == other else -bounds[t])
                visits.append((other, t, node))
                queue.append(other)
    # x = Z y + c: the representative of each variable (zero: constant).
    representative = np.arange(n + 1, dtype=np.int64)
    constant = np.zeros(n + 1)
    if visits:
        tied_nodes = np.fromiter(root.keys(), dtype=np.int64, count=len(root))
        representative[tied_nodes] = np.fromiter(root.values(), dtype=np.int64, count=len(root))
        constant[tied_nodes] = np.fromiter(offset.values(), dtype=float, count=len(offset))
    own = representative[:n] == np.arange(n)
    column = np.full(n + 1, -1, dtype=np.int64)
    column[np.flatnonzero(own)] = np.arange(int(own.sum()))
    z = column[representative[:n]]  # -1: in the zero node's tree
    c = constant[:n]
    size = int(own.sum())
    square = hessian.tocoo()
    zr, zc = z[square.row], z[square.col]
    keep = (zr >= 0) & (zc >= 0)
    reduced = scipy.sparse.csc_matrix((square.data[keep], (zr[keep], zc[keep])), shape=(size, size))
    shifted = hessian @ c + gradient
    free = z >= 0
    reduced_gradient = np.bincount(z[free], weights=shifted[free], minlength=size)
    if size:
        y = _band_solve(reduced, -reduced_gradient, definite=True)
        if y is None:
            try:
                y = scipy.sparse.linalg.splu(reduced).solve(-reduced_gradient).reshape(size)
            except RuntimeError:
                return None
    else:
        y = np.zeros(0)
    x = np.where(free, y[np.where(free, z, 0)] if size else 0.0, 0.0) + c
    if not np.all(np.isfinite(x)):
        return None
    # A'lam = Hx + g, peeled from the leaves: a node's edge to its parent
    # carries what its own residual and its children's edges leave.
    residual = hessian @ x + gradient
    rest = dict.fromkeys(root, 0.0)
    touched = np.fromiter((v for v in root if v != zero), dtype=np.int64)
    for v, r in zip(touched.tolist(), residual[touched].tolist(), strict=True):
        rest[v] = r
    multipliers = [0.0] * k
    for node, t, parent in reversed(visits):
        # the row's coefficient at node: +1 as its upper end, -1 as its lower
        value = rest[node] if ups[t] == node else -rest[node]
        multipliers[t] = value
        rest[parent] -= value if ups[t] == parent else -value
    return x, np.array(multipliers)


#: A system whose bandwidth after the reverse Cuthill-McKee ordering is at
#: most this is solved as a band matrix by LAPACK (cost ~ size x bandwidth^2)
#: rather than by SuperLU.
BAND_LIMIT = 16


def _band_solve(matrix: Any, rhs: np.ndarray, *, definite: bool) -> np.ndarray | None:
    """``matrix x = rhs`` as a band matrix after reverse Cuthill-McKee, or None.

    A block's Hessian is mostly chains of phases, its KKT systems add a
    row per held difference constraint: reordered, the bandwidth is
    small (9 for the benchmark's 1,000 behaviours, 4,330 unknowns), and a
    band factorisation (Cholesky for the definite Hessian, LU with partial
    pivoting for a KKT system) takes half of SuperLU's time there. None
    when the bandwidth exceeds :data:`BAND_LIMIT`, or LAPACK finds the
    system singular (not definite), or the answer does not solve it (a
    singular system passed on round-off): the caller takes SuperLU, which
    decides.
    """
    scipy = _scipy()
    size = matrix.shape[0]
    order = scipy.sparse.csgraph.reverse_cuthill_mckee(matrix.tocsr(), symmetric_mode=True)
    position = np.empty_like(order)
    position[order] = np.arange(order.size)
    entries = matrix.tocoo()
    entries.sum_duplicates()  # a no-op on the canonical matrices made here
    rows, cols = position[entries.row], position[entries.col]
    width = int(np.abs(rows - cols).max(initial=0))
    if width > BAND_LIMIT:
        return None
    try:
        if definite:  # lower form: band[i - j, j] = a[i, j]
            lower = rows >= cols
            band = np.zeros((width + 1, size))
            band[rows[lower] - cols[lower], cols[lower]] = entries.data[lower]
            solved = scipy.linalg.solveh_banded(band, rhs[order], lower=True,
                                                check_finite=False)  # fmt: skip
        else:  # band[width + i - j, j] = a[i, j]
            band = np.zeros((2 * width + 1, size))
            band[width + rows - cols, cols] = entries.data
            solved = scipy.linalg.solve_banded((width, width), band, rhs[order],
                                               check_finite=False)  # fmt: skip
    except (np.linalg.LinAlgError, ValueError):
        return None
    solution = np.empty(size)
    solution[order] = solved
    # A singular system can pass the factorisation on round-off (a tiny
    # positive pivot) and give nonsense: the residual tells.
    residual = matrix @ solution - rhs
    if not np.all(np.isfinite(residual)) or np.abs(residual).max(initial=0.0) > 1e-9 * (
        1.0 + float(np.abs(rhs).max(initial=0.0))
    ):
        return None
    return solution


# -- the pure-Python path for tiny problems (realizer.scheduler.tiny) ------------

#: Problems with at most this many sync points first try :func:`_tiny_times`.
TINY_KEYS = 120


def solve_tiny(problem: Problem) -> dict[Key, float] | None:
    """:func:`solve` by :func:`_tiny_times`, or None where it declines (see there)."""
    times = _tiny_times(problem)
    return None if times is None else dict(zip(problem.keys, times, strict=True))


def _tiny_times(problem: Problem) -> list[float] | None:
    """:func:`realizer.scheduler.tiny.tiny_times` with this module's :data:`PDAS_STEPS`."""
    return tiny_times(problem, PDAS_STEPS)
