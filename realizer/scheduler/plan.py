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

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from realizer.bml_parser import Behaviour, Block, BmlWarning, SyncRef, WarningType
from realizer.scheduler.solver import (
    BLOCK_START,
    Infeasible,
    Key,
    Problem,
    SchedulingError,
    Source,
    solve,
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

    def warn(self, kind: WarningType, message: str, target: str = "") -> None:
        self.warnings.append(
            BmlWarning(kind, message, id=f"{self.block.id}:{target}" if target else self.block.id)
        )

    def target(self, ref: SyncRef, holder: str) -> tuple[Key, float] | None:
        """The sync point a reference names (block-relative), or None with a warning."""
        if ref.is_time:
            return BLOCK_START, ref.offset
        assert ref.behaviour is not None and ref.sync is not None
        if ref.block is not None and ref.block != self.block.id:
            key = (ref.block, ref.behaviour, _sync_name(ref))
            if key not in self.external:
                self.warn(
                    WarningType.NO_SUCH_TARGET,
                    f"{holder}: {ref.raw.strip()!r} names no sync point of an earlier block",
                    holder,
                )
                return None
            # A fixed global time, expressed relative to this block's start.
            return BLOCK_START, self.external[key] - self.start + ref.offset
        if ref.behaviour == "bml":
            if ref.sync != "start":
                self.warn(WarningType.NO_SUCH_TARGET, f"{holder}: bml has only a start", holder)
                return None
            return BLOCK_START, ref.offset
        model = self.models.get(ref.behaviour)
        if model is None:
            self.warn(
                WarningType.NO_SUCH_TARGET,
                f"{holder}: behaviour {ref.behaviour!r} of {ref.raw.strip()!r} not found",
                holder,
            )
            return None
        name = _sync_name(ref)
        if name not in model.syncs:
            self.warn(
                WarningType.NO_SUCH_TARGET,
                f"{holder}: {ref.behaviour!r} has no sync point {name!r}",
                holder,
            )
            return None
        return (ref.behaviour, name), ref.offset

    def build(self, skip: set[str], dropped_constraints: set[Source]) -> Problem:
        problem = Problem()
        block = self.block
        for behaviour in block.behaviours:
            model = self.models.get(behaviour.id)
            if model is None or behaviour.id in skip:
                continue
            source = self._source("behaviour", behaviour.id, behaviour.required)
            problem.add_behaviour(behaviour.id, model.syncs, model.phases, source)
            refs = list(behaviour.sync_refs)
            if behaviour.speech is not None:
                refs += [(r.id, r.ref) for r in behaviour.speech.runs
                         if not isinstance(r, str) and r.ref is not None]  # fmt: skip
            for sync, ref in refs:
                target = self.target(ref, behaviour.id)
                if target is None or (target[0][0] in skip):
                    continue
                key, offset = target
                # t_sync = t_target + offset
                problem.equal((behaviour.id, sync), 0.0, key, offset, source)
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
                if relation.kind == "synchronize":
                    chain = ([anchor] if anchor is not None else []) + live
                    for (a, ka), (b, kb) in itertools.pairwise(chain):
                        problem.equal(a, ka, b, kb, source)
                elif anchor is not None:
                    for key, offset in live:
                        if relation.kind == "before":  # the syncs lie before ref
                            problem.order(key, offset, anchor[0], anchor[1], source)
                        else:
                            problem.order(anchor[0], anchor[1], key, offset, source)
        for key, time in self.fixed.items():
            if key[0] not in skip and key in problem.keys:
                problem.fix(key, time - self.start, Source("fixed", f"{key[0]}:{key[1]}", True))
        return problem

    def _source(self, kind: str, ident: str, required: bool) -> Source:
        source = Source(kind, ident, required)
        self.order.setdefault(source, len(self.order))
        return source


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
) -> TimedPlan:
    """Solve one block whose start is ``start`` (global seconds).

    ``registry`` gives each behaviour's timing model (see :class:`Planner`);
    ``dropped`` are behaviours the parser already ruled out; ``external``
    gives global times of sync points of other blocks for cross-block
    references; ``fixed`` pins sync points of this block already consumed
    by time (global seconds). Raises :class:`SchedulingFailed` when a
    required part cannot be met.
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
            times = solve(problem)
            break
        except Infeasible as exc:
            del notes[mark:]  # the reference warnings are given again on the next build
            victim = _choose_victim(exc.conflict, builder.order)
            if victim is None:
                names = ", ".join(sorted(str(s) for s in exc.conflict if s.kind != "block"))
                notes.append(
                    BmlWarning(
                        WarningType.IMPOSSIBLE_TO_SCHEDULE,
                        f"required parts cannot all be met ({names}); the block fails",
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
                        f"the timing of {victim.id!r} cannot be met; the behaviour is removed",
                        id=f"{block.id}:{victim.id}",
                    )
                )
            else:
                dropped_constraints.add(victim)
                notes.append(
                    BmlWarning(
                        WarningType.IMPOSSIBLE_TO_SCHEDULE,
                        f"constraint {victim.id!r} cannot be met together with the others; "
                        "it is dropped",
                        id=f"{block.id}:{victim.id}",
                    )
                )
    behaviours = []
    for behaviour in block.behaviours:
        if behaviour.id in skip or behaviour.id not in models:
            continue
        model = models[behaviour.id]
        behaviours.append(
            ScheduledBehaviour(
                # max(0, t): the solver's round-off may leave -1e-18 at the block start
                behaviour,
                {sync: start + max(0.0, times[(behaviour.id, sync)]) for sync in model.syncs},
            )
        )
    end = max((b.end for b in behaviours), default=start)
    return TimedPlan(
        block=block,
        start=start,
        end=end,
        behaviours=tuple(behaviours),
        warnings=tuple(notes),
        dropped=frozenset(dropped | skip | (set(b.id for b in block.behaviours) - set(models))),
        models=models,
        unrealized=frozenset(unrealized),
    )


def _choose_victim(conflict: frozenset[Source], order: Mapping[Source, int]) -> Source | None:
    droppable = [s for s in conflict if not s.required and s.kind in ("behaviour", "constraint")]
    if not droppable:
        return None
    behaviours = {s.id for s in conflict if s.kind == "behaviour"}
    own = [s for s in droppable if s.kind == "behaviour"]
    if len(behaviours) == 1 and own:
        return own[0]
    latest = sorted(droppable, key=lambda s: (s.kind == "constraint", order.get(s, -1)))
    return latest[-1]
