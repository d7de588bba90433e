"""Scheduling a parsed block: from the BML tree to a :class:`TimedPlan`.

For one block this asks each behaviour's engine for its timing model, turns
every sync reference and ``<constraint>`` into equalities and orderings of
:mod:`realizer.scheduler.solver`, solves, and answers conflicts as the BML
1.0 standard asks:

* a reference to an unknown block, behaviour or sync point is skipped with a
  ``NO_SUCH_TARGET`` warning (the behaviour still runs, without that tie);
* when the constraints cannot all hold, the solver names the conflicting
  ones; a non-required part is dropped, one at a time, with a warning naming
  it (``IMPOSSIBLE_TO_SCHEDULE``), and the block is solved again. When a
  single behaviour's own timing is what cannot hold (the corpus's
  "behaviour should be removed"), that behaviour goes; otherwise the latest
  non-required ``<constraint>`` in the conflict goes, then the latest
  non-required behaviour. If only ``<required>`` parts conflict, the block
  fails with ``IMPOSSIBLE_TO_SCHEDULE``.

Cross-block references (``bml2:nod1:end``) resolve to the times of blocks
already planned, given by the caller as fixed global times.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from realizer.bml_parser import Behaviour, Block, BmlWarning, SyncRef, WarningType
from realizer.scheduler.solver import (
    BLOCK_SOURCE,
    BLOCK_START,
    Infeasible,
    Key,
    Problem,
    SchedulingError,
    Source,
    solve_times,
)
from realizer.scheduler.timing import TimingModel, TimingModelError


class Planner(Protocol):
    """Where the scheduler gets timing models (the engines' registry, above it).

    The scheduler imports no engine (docs/architecture.md): the caller hands
    it a planner, usually :class:`realizer.engines.EngineRegistry`.
    """

    def plan(self, behaviour: Behaviour) -> TimingModel:
        """The behaviour's model; may raise :class:`TimingModelError`."""
        ...

    def plan_plain(self, behaviour: Behaviour) -> TimingModel:
        """A plain model for a behaviour whose own engine cannot plan it."""
        ...

    def channels(self, behaviour: Behaviour) -> frozenset[str]:
        """The resource channels (body parts) the behaviour needs for itself."""
        ...


#: A sync point of any block: (block id, behaviour id, sync name).
GlobalKey = tuple[str, str, str]


class SchedulingFailed(SchedulingError):
    """The whole block cannot be scheduled (a required part is impossible)."""

    def __init__(self, block_id: str, message: str, warnings: tuple[BmlWarning, ...]) -> None:
        super().__init__(message)
        self.block_id = block_id
        self.message = message
        self.warnings = warnings
        self.warning_type = WarningType.IMPOSSIBLE_TO_SCHEDULE


@dataclass(frozen=True, slots=True)
class ScheduledBehaviour:
    """A behaviour with the global time (seconds) of each of its sync points."""

    behaviour: Behaviour
    times: dict[str, float]

    @property
    def id(self) -> str:
        return self.behaviour.id

    @property
    def start(self) -> float:
        return min(self.times.values())

    @property
    def end(self) -> float:
        return max(self.times.values())


@dataclass(frozen=True, slots=True)
class TimedPlan:
    """A solved block: global start and end, every behaviour's sync times."""

    block: Block
    start: float
    end: float
    behaviours: tuple[ScheduledBehaviour, ...]
    warnings: tuple[BmlWarning, ...] = ()
    dropped: frozenset[str] = frozenset()
    models: dict[str, TimingModel] = field(default_factory=dict, compare=False)
    #: behaviours scheduled for their feedback that no engine can animate
    unrealized: frozenset[str] = frozenset()

    @property
    def id(self) -> str:
        return self.block.id

    def time_of(self, behaviour_id: str, sync: str) -> float | None:
        for scheduled in self.behaviours:
            if scheduled.id == behaviour_id:
                return scheduled.times.get(sync)
        return None

    def global_keys(self) -> dict[GlobalKey, float]:
        return {
            (self.block.id, scheduled.id, sync): time
            for scheduled in self.behaviours
            for sync, time in scheduled.times.items()
        }


@dataclass(slots=True)
class _Builder:
    block: Block
    start: float
    models: dict[str, TimingModel]
    external: Mapping[GlobalKey, float]
    fixed: Mapping[Key, float]
    warnings: list[BmlWarning]
    order: dict[Source, int] = field(default_factory=dict)
    #: every constraint of the last recording build as a difference edge
    #: ``t_v - t_u <= w`` with what it comes from in the user's words, to
    #: explain a conflict
    edges: list[_Edge] = field(default_factory=list)
    #: behaviours that a required part refers to: removing one would drop a
    #: required reference, so a conflict that involves them fails the block
    pinned: set[str] = field(default_factory=set)
    #: whether :meth:`build` records :attr:`edges` and :attr:`pinned`: only
    #: a block in conflict needs them, so the first build of every block
    #: skips them (most blocks solve at once) and a conflict builds again
    record: bool = False

    def warn(self, kind: WarningType, message: str, target: str = "") -> None:
        self.warnings.append(
            BmlWarning(kind, message, id=f"{self.block.id}:{target}" if target else self.block.id)
        )

    def target(self, ref: SyncRef, holder: str) -> tuple[Key, float] | None:
        """The sync point a reference names (block-relative), or None with a warning."""
        behaviour = ref.behaviour
        if behaviour is None:  # a time
            return BLOCK_START, ref.offset
        assert ref.sync is not None
        if ref.block is not None and ref.block != self.block.id:
            key = (ref.block, behaviour, _sync_name(ref))
            if key not in self.external:
                self.warn(
                    WarningType.NO_SUCH_TARGET,
                    f"{holder}: {ref.raw.strip()!r} names no sync point of an earlier block",
                    holder,
                )
                return None
            # A fixed global time, expressed relative to this block's start.
            return BLOCK_START, self.external[key] - self.start + ref.offset
        if behaviour == "bml":
            if ref.sync != "start":
                self.warn(WarningType.NO_SUCH_TARGET, f"{holder}: bml has only a start", holder)
                return None
            return BLOCK_START, ref.offset
        model = self.models.get(behaviour)
        if model is None:
            self.warn(
                WarningType.NO_SUCH_TARGET,
                f"{holder}: behaviour {ref.behaviour!r} of {ref.raw.strip()!r} not found",
                holder,
            )
            return None
        name = ref.sync if ref.iteration is None else _sync_name(ref)
        if name not in model.positions:
            self.warn(
                WarningType.NO_SUCH_TARGET,
                f"{holder}: {behaviour!r} has no sync point {name!r}",
                holder,
            )
            return None
        return (behaviour, name), ref.offset

    def equal(
        self, problem: Problem, a: Key, ka: float, b: Key, kb: float, source: Source, label: str
    ) -> None:
        """``t_a + ka == t_b + kb``, remembered with its label."""
        problem.equal(a, ka, b, kb, source)
        if not self.record:
            return
        self.edges.append(_Edge(b, a, kb - ka, source, label))
        self.edges.append(_Edge(a, b, ka - kb, source, label))
        if source.required:
            self.pinned.update(key[0] for key in (a, b) if key != BLOCK_START)

    def order_(
        self, problem: Problem, a: Key, ka: float, b: Key, kb: float, source: Source, label: str
    ) -> None:
        """``t_a + ka <= t_b + kb``, remembered with its label."""
        problem.order(a, ka, b, kb, source)
        if not self.record:
            return
        self.edges.append(_Edge(b, a, kb - ka, source, label))
        if source.required:
            self.pinned.update(key[0] for key in (a, b) if key != BLOCK_START)

    def build(self, skip: set[str], dropped_constraints: set[Source]) -> Problem:
        problem = Problem()
        block = self.block
        record = self.record
        self.edges = []
        self.pinned = set()
        models, target, equal = self.models, self.target, problem.equal
        for behaviour in block.behaviours:
            behaviour_id = behaviour.id
            model = models.get(behaviour_id)
            if model is None or behaviour_id in skip:
                continue
            source = (
                self._source("behaviour", behaviour_id, behaviour.required)
                if record
                else Source("behaviour", behaviour_id, behaviour.required)
            )
            problem.add_model(behaviour_id, model, source)
            if record:
                self._phase_edges(behaviour_id, model, source)
            refs: Sequence[tuple[str, SyncRef]] = behaviour.sync_refs
            if behaviour.speech is not None:
                refs = [*refs, *((r.id, r.ref) for r in behaviour.speech.runs
                                 if not isinstance(r, str) and r.ref is not None)]  # fmt: skip
            for sync, ref in refs:
                # The usual reference, a sync point of a behaviour of this
                # block (or a time), is resolved here; target() does the rest
                # and warns.
                name = ref.behaviour
                found: tuple[Key, float] | None
                if name is None:
                    found = BLOCK_START, ref.offset
                elif (
                    ref.block is None
                    and ref.iteration is None
                    and name != "bml"
                    and (other := models.get(name)) is not None
                    and ref.sync in other.positions
                ):
                    found = (name, ref.sync), ref.offset
                else:
                    found = target(ref, behaviour_id)
                    if found is None:
                        continue
                key, offset = found
                if skip and key[0] in skip:
                    continue
                # t_sync = t_target + offset
                if record:
                    self.equal(problem, (behaviour_id, sync), 0.0, key, offset, source,
                               f'{behaviour_id} {sync}="{ref.raw.strip()}"')  # fmt: skip
                else:
                    equal((behaviour_id, sync), 0.0, key, offset, source)
        for index, constraint in enumerate(block.constraints):
            source = self._source("constraint", constraint.id or f"#{index + 1}",
                                  constraint.required)  # fmt: skip
            if source in dropped_constraints:
                continue
            holder = constraint.id or f"constraint #{index + 1}"
            for relation in constraint.relations:
                members = [self.target(ref, holder) for ref in relation.syncs]
                anchor = self.target(relation.ref, holder) if relation.ref is not None else None
                live = [m for m in members if m is not None and m[0][0] not in skip]
                if anchor is not None and anchor[0][0] in skip:
                    anchor = None
                label = f"<{relation.kind}> of constraint {holder!r}" + (
                    f' (ref="{relation.ref.raw.strip()}")' if relation.ref is not None else ""
                )
                if relation.kind == "synchronize":
                    chain = ([anchor] if anchor is not None else []) + live
                    for (a, ka), (b, kb) in itertools.pairwise(chain):
                        self.equal(problem, a, ka, b, kb, source, label)
                elif anchor is not None:
                    for key, offset in live:
                        if relation.kind == "before":  # the syncs lie before ref
                            self.order_(problem, key, offset, anchor[0], anchor[1], source, label)
                        else:
                            self.order_(problem, anchor[0], anchor[1], key, offset, source, label)
        for key, time in self.fixed.items():
            if key[0] not in skip and problem.index_of(key) is not None:
                fixed = Source("fixed", f"{key[0]}:{key[1]}", True)
                self.equal(problem, key, 0.0, BLOCK_START, time - self.start, fixed,
                           f"{key[0]}:{key[1]} already passed at {time:g} s")  # fmt: skip
        return problem

    def _phase_edges(self, behaviour_id: str, model: TimingModel, source: Source) -> None:
        """The phase bounds of one behaviour as labelled edges."""
        for (first, second), phase in zip(
            itertools.pairwise(model.syncs), model.phases, strict=True
        ):
            a, b = (behaviour_id, first), (behaviour_id, second)
            self.edges.append(_Edge(b, a, -phase.minimum, source, _phase_label(
                behaviour_id, first, second, phase.minimum, "at least")))  # fmt: skip
            if math.isfinite(phase.maximum):
                self.edges.append(_Edge(a, b, phase.maximum, source, _phase_label(
                    behaviour_id, first, second, phase.maximum, "at most")))  # fmt: skip

    def explain(self, conflict: frozenset[Source]) -> list[str]:
        """The constraints that conflict, in the user's words, in cycle order."""
        edges = [e for e in self.edges if e.source in conflict]
        keys = {k for e in edges for k in (e.u, e.v)} | {BLOCK_START}
        edges += [_Edge(k, BLOCK_START, 0.0, BLOCK_SOURCE, "nothing happens before the block "
                        "starts") for k in keys if k != BLOCK_START]  # fmt: skip
        return _negative_cycle(keys, edges)

    def _source(self, kind: str, ident: str, required: bool) -> Source:
        source = Source(kind, ident, required)
        if self.record:  # the document order of sources, for choosing what to drop
            self.order.setdefault(source, len(self.order))
        return source


@dataclass(frozen=True, slots=True)
class _Edge:
    """``t_v - t_u <= w``, from ``source``, described by ``label``."""

    u: Key
    v: Key
    w: float
    source: Source
    label: str


def _phase_label(behaviour: str, first: str, second: str, seconds: float, bound: str) -> str:
    if bound == "at least" and seconds <= 0.0:
        return f"{behaviour}: {second} cannot come before {first}"
    return f"{behaviour} needs {bound} {seconds:.3g} s from {first} to {second}"


def _negative_cycle(keys: set[Key], edges: list[_Edge]) -> list[str]:
    """Labels along one negative cycle of ``edges`` (Bellman-Ford), or [].

    Only run on a failure, over the edges of the conflicting sources.
    """
    distance = dict.fromkeys(keys, 0.0)
    parent: dict[Key, _Edge] = {}
    last: Key | None = None
    for _ in range(len(keys) + 1):
        last = None
        for edge in edges:
            if distance[edge.u] + edge.w < distance[edge.v] - 1e-9:
                distance[edge.v] = distance[edge.u] + edge.w
                parent[edge.v] = edge
                last = edge.v
        if last is None:
            return []
    assert last is not None
    node: Key = last
    for _ in range(len(keys)):
        node = parent[node].u
    labels: list[str] = []
    start = node
    while True:
        edge = parent[node]
        if edge.label not in labels:
            labels.append(edge.label)
        node = edge.u
        if node == start:
            break
    labels.reverse()
    return labels


def _sync_name(ref: SyncRef) -> str:
    # stroke:1 is the first stroke, which behaviours list as "stroke".
    return "stroke" if ref.sync == "stroke" and ref.iteration == 1 else ref.sync_name


def schedule_block(
    block: Block,
    *,
    registry: Planner,
    start: float = 0.0,
    dropped: frozenset[str] = frozenset(),
    external: Mapping[GlobalKey, float] | None = None,
    fixed: Mapping[Key, float] | None = None,
    warnings: tuple[BmlWarning, ...] = (),
    occupied: Sequence[tuple[str, ScheduledBehaviour]] = (),
) -> TimedPlan:
    """Solve one block whose start is ``start`` (global seconds).

    ``registry`` gives each behaviour's timing model (see :class:`Planner`);
    ``dropped`` are behaviours the parser already ruled out; ``external``
    gives global times of sync points of other blocks for cross-block
    references; ``fixed`` pins sync points of this block already consumed
    by time (global seconds); ``occupied`` are (block id, behaviour) of the
    character's other blocks still to run, whose resource channels this
    block's behaviours must not take (docs/scheduler.md, "Resource
    conflicts"). Raises :class:`SchedulingFailed` when a required part
    cannot be met.
    """
    notes: list[BmlWarning] = list(warnings)
    models: dict[str, TimingModel] = {}
    unrealized: set[str] = set()
    for behaviour in block.behaviours:
        if behaviour.id in dropped:
            continue
        try:
            models[behaviour.id] = registry.plan(behaviour)
        except TimingModelError as exc:
            # Nothing is lost: the behaviour keeps its place in the schedule
            # and its feedback (the corpus's testhead_selftimed.xml times a
            # head with lexeme "Y"), but no engine animates it.
            models[behaviour.id] = registry.plan_plain(behaviour)
            unrealized.add(behaviour.id)
            notes.append(
                BmlWarning(
                    WarningType.CANNOT_CREATE_BEHAVIOR,
                    f"{behaviour.id}: {exc}; it is scheduled and reported but not shown",
                    id=f"{block.id}:{behaviour.id}",
                )
            )
    builder = _Builder(block, start, models, external or {}, fixed or {}, notes)
    skip: set[str] = set()
    dropped_constraints: set[Source] = set()
    while True:
        mark = len(notes)
        problem = builder.build(skip, dropped_constraints)
        try:
            values = solve_times(problem)
            break
        except Infeasible as exc:
            # The edges and pins that explain a conflict, from the same build
            # again; its reference warnings are given again on the next build.
            del notes[mark:]
            builder.record = True
            builder.build(skip, dropped_constraints)
            builder.record = False
            del notes[mark:]
            victim = _choose_victim(exc.conflict, builder.order, builder.pinned)
            why = "; ".join(builder.explain(exc.conflict)) or exc.detail
            if victim is None:
                names = ", ".join(sorted(str(s) for s in exc.conflict if s.kind != "block"))
                pinned = sorted(
                    s.id for s in exc.conflict
                    if s.kind == "behaviour" and not s.required and s.id in builder.pinned
                )  # fmt: skip
                because = (
                    f"; {', '.join(map(repr, pinned))} cannot be removed because a required "
                    "part refers to it"
                    if pinned
                    else ""
                )
                notes.append(
                    BmlWarning(
                        WarningType.IMPOSSIBLE_TO_SCHEDULE,
                        f"required parts cannot all be met ({names}): these cannot hold "
                        f"together: {why}{because}; the block fails",
                        id=block.id,
                    )
                )
                raise SchedulingFailed(
                    block.id, f"block {block.id!r} cannot be scheduled: {names}", tuple(notes)
                ) from None
            if victim.kind == "behaviour":
                skip.add(victim.id)
                notes.append(
                    BmlWarning(
                        WarningType.IMPOSSIBLE_TO_SCHEDULE,
                        f"the timing of {victim.id!r} cannot be met ({why}); "
                        "the behaviour is removed",
                        id=f"{block.id}:{victim.id}",
                    )
                )
            else:
                dropped_constraints.add(victim)
                notes.append(
                    BmlWarning(
                        WarningType.IMPOSSIBLE_TO_SCHEDULE,
                        f"constraint {victim.id!r} cannot be met together with the others "
                        f"({why}); it is dropped",
                        id=f"{block.id}:{victim.id}",
                    )
                )
    # max(0, t): the solver's round-off may leave -1e-18 at the block start
    values = [start + t if t > 0.0 else start for t in values]
    behaviours = []
    #: each behaviour's (start, end), made once (the channel sweep and the
    #: plan's end read them)
    spans: dict[str, tuple[float, float]] = {}
    firsts = problem._first
    for behaviour in block.behaviours:
        behaviour_id = behaviour.id
        model = models.get(behaviour_id)
        if model is None or behaviour_id in skip:
            continue
        syncs = model.syncs
        first = firsts.get(behaviour_id)
        if first is not None:  # its keys are consecutive
            own = values[first : first + len(syncs)]
        else:
            own = [values[problem._index((behaviour_id, sync))] for sync in syncs]  # all known
        spans[behaviour_id] = (min(own), max(own))
        # the lengths agree (one time per sync point): no strict check
        behaviours.append(ScheduledBehaviour(behaviour, dict(zip(syncs, own, strict=False))))
    busy = _resolve_channels(block.id, behaviours, registry, notes, occupied, spans)
    if busy:
        skip |= busy
        behaviours = [b for b in behaviours if b.behaviour.id not in busy]
        for behaviour_id in busy:
            del spans[behaviour_id]
    end = max([span[1] for span in spans.values()], default=start)
    gone = dropped | skip
    if len(models) < len(block.behaviours):  # behaviours planned by no engine
        gone = gone | (set(b.id for b in block.behaviours) - set(models))
    return TimedPlan(
        block=block,
        start=start,
        end=end,
        behaviours=tuple(behaviours),
        warnings=tuple(notes),
        dropped=frozenset(gone),
        models=models,
        unrealized=frozenset(unrealized),
    )


#: Two behaviours overlap on a channel when they share more than this (seconds).
CHANNEL_TOLERANCE = 1e-6


def _resolve_channels(
    block_id: str,
    behaviours: list[ScheduledBehaviour],
    registry: Planner,
    notes: list[BmlWarning],
    occupied: Sequence[tuple[str, ScheduledBehaviour]] = (),
    spans: Mapping[str, tuple[float, float]] | None = None,
) -> set[str]:
    """Resource conflicts, by the policy of docs/scheduler.md.

    Two behaviours that need one channel (``registry.channels``) at once:
    when one's time span contains the other's (identical timing included),
    the later in document order is removed with a warning (a required one is
    kept and the other removed; two required ones both stay, with a
    warning); when they only partly overlap, both run and a warning names
    the overlap. The behaviours of other blocks (``occupied``, named
    ``block:behaviour``) come before this block's: they are already
    promised, so a behaviour of this block inside or around one of them is
    the later and goes (a required one stays, with a warning). Returns the
    ids removed. The overlapping pairs are found by a sweep over start
    times (:func:`_overlapping`), so the cost grows with the behaviours and
    the pairs that do overlap, not with every pair that shares a channel (a
    block of 10,000 behaviours has thousands of nods).
    """
    by_channel: dict[str, list[tuple[str, ScheduledBehaviour, tuple[float, float]]]] = {}
    channels_of = registry.channels
    for other_block, scheduled in occupied:
        bounds = (scheduled.start, scheduled.end)
        for channel in sorted(channels_of(scheduled.behaviour)):
            by_channel.setdefault(channel, []).append((f"{other_block}:", scheduled, bounds))
    for scheduled in behaviours:
        names = channels_of(scheduled.behaviour)
        if not names:
            continue
        bounds = (
            spans[scheduled.behaviour.id] if spans is not None else (scheduled.start, scheduled.end)
        )
        entry = ("", scheduled, bounds)
        for channel in sorted(names) if len(names) > 1 else names:
            listed = by_channel.get(channel)
            if listed is None:
                by_channel[channel] = [entry]
            else:
                listed.append(entry)
    removed: set[str] = set()
    for channel, found in by_channel.items():
        if len(found) < 2:
            continue
        users = [(block, scheduled) for block, scheduled, _ in found]
        spans_of = [bounds for *_, bounds in found]
        for later_index, earlier_index in _overlapping(spans_of):
            later_block, later = users[later_index]
            earlier_block, earlier = users[earlier_index]
            if later_block:
                continue  # another block's: not this block's to remove
            if (not earlier_block and earlier.id in removed) or later.id in removed:
                continue
            (earlier_start, earlier_end), (later_start, later_end) = (
                spans_of[earlier_index],
                spans_of[later_index],
            )
            lo, hi = max(earlier_start, later_start), min(earlier_end, later_end)
            span = f"{lo:.3f} to {hi:.3f} s"
            contains = (
                earlier_start <= later_start + CHANNEL_TOLERANCE
                and later_end <= earlier_end + CHANNEL_TOLERANCE
            ) or (
                later_start <= earlier_start + CHANNEL_TOLERANCE
                and earlier_end <= later_end + CHANNEL_TOLERANCE
            )
            earlier_name = f"{earlier_block}{earlier.id}"
            both = f"{earlier_name!r} and {later.id!r} both need the {channel} channel"
            if earlier_block and later.behaviour.required and contains:
                notes.append(BmlWarning(WarningType.IMPOSSIBLE_TO_SCHEDULE,
                    f"{both} from {span}; {later.id!r} is required and {earlier_name!r} "
                    "belongs to a block already planned, so both run",
                    id=f"{block_id}:{later.id}"))  # fmt: skip
                continue
            if not contains:
                notes.append(BmlWarning(WarningType.IMPOSSIBLE_TO_SCHEDULE,
                    f"{both} from {span} (a partial overlap); both run and their "
                    "motions are mixed there", id=f"{block_id}:{later.id}"))  # fmt: skip
                continue
            victim, kept = later, earlier
            if earlier_block:
                removed.add(later.id)
                notes.append(BmlWarning(WarningType.IMPOSSIBLE_TO_SCHEDULE,
                    f"{both} from {span}; {later.id!r} is removed and {earlier_name!r} "
                    "(a block already planned) keeps it",
                    id=f"{block_id}:{later.id}"))  # fmt: skip
                continue
            if later.behaviour.required and not earlier.behaviour.required:
                victim, kept = earlier, later
            elif later.behaviour.required:
                notes.append(BmlWarning(WarningType.IMPOSSIBLE_TO_SCHEDULE,
                    f"{both} from {span}; both are required, so both run",
                    id=f"{block_id}:{later.id}"))  # fmt: skip
                continue
            removed.add(victim.id)
            notes.append(BmlWarning(WarningType.IMPOSSIBLE_TO_SCHEDULE,
                f"{both} from {span}; {victim.id!r} is removed and {kept.id!r} keeps it",
                id=f"{block_id}:{victim.id}"))  # fmt: skip
    return removed


def _overlapping(spans: list[tuple[float, float]]) -> list[tuple[int, int]]:
    """Pairs ``(later, earlier)`` of indices (earlier < later) whose spans overlap.

    Overlap as :func:`_resolve_channels` means it: the shared part is longer
    than :data:`CHANNEL_TOLERANCE`. Sorted by ``later``, then ``earlier``
    (document order), which is the order the policy takes them in. A sweep
    by start time: a span that ends before the current start can overlap
    neither it nor any span starting later, and leaves the open set.
    """
    pairs: list[tuple[int, int]] = []
    open_ends: list[tuple[float, int]] = []  # a heap of (end, index)
    open_set: set[int] = set()
    for index in sorted(range(len(spans)), key=lambda i: spans[i][0]):
        start, end = spans[index]
        while open_ends and open_ends[0][0] < start:
            open_set.discard(heapq.heappop(open_ends)[1])
        for other in open_set:
            other_start, other_end = spans[other]
            if min(end, other_end) - max(start, other_start) > CHANNEL_TOLERANCE:
                pairs.append((index, other) if other < index else (other, index))
        open_set.add(index)
        heapq.heappush(open_ends, (end, index))
    pairs.sort()
    return pairs


def _choose_victim(
    conflict: frozenset[Source], order: Mapping[Source, int], pinned: set[str]
) -> Source | None:
    droppable = [
        s
        for s in conflict
        if not s.required
        and s.kind in ("behaviour", "constraint")
        and not (s.kind == "behaviour" and s.id in pinned)
    ]
    if not droppable:
        return None
    behaviours = {s.id for s in conflict if s.kind == "behaviour"}
    own = [s for s in droppable if s.kind == "behaviour"]
    if len(behaviours) == 1 and own:
        return own[0]
    latest = sorted(droppable, key=lambda s: (s.kind == "constraint", order.get(s, -1)))
    return latest[-1]
