"""The realizer session: one character's blocks, from BML text to feedback and frames.

Sans-I/O (see docs/architecture.md): a session never reads a clock and
never touches a socket. The caller passes the current time ``now`` (seconds,
any monotonic clock) to every call and takes what is due::

    session = Session("Alice")
    session.receive_bml(text, now=0.0)     # parse, plan, solve: prediction
    session.tick(0.5)                      # progress feedback up to 0.5 s
    for feedback in session.take_feedback():
        send(feedback.xml)
    frame = session.frame(0.5)             # the FAP vector at 0.5 s

Tests drive a session at any speed. The block lifecycle is one transition
table, :data:`TRANSITIONS` (like h11's ``_state.py``); an illegal transition
raises :class:`LifecycleError` naming the block, event and state.

Composition (BML 1.0): MERGE starts a block now beside running ones, APPEND
after every earlier block of the character has ended, REPLACE interrupts
every running and pending block first. A block may refer to sync points of
blocks already planned (``bml1:nod1:end``); they are fixed times for it.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from realizer.bml_parser import BmlError, Limits, ParseResult, WarningType, parse_bml
from realizer.engines import EngineRegistry
from realizer.errors import RealizerError
from realizer.feedback import (
    Feedback,
    block_progress,
    prediction,
    sync_point_progress,
    warning,
)
from realizer.scheduler.plan import ScheduledBehaviour, SchedulingFailed, TimedPlan, schedule_block

if TYPE_CHECKING:  # the types only; the modules load when a face or speech is used
    from realizer.engines.speech.engine import AudioClip
    from realizer.face.animation import Animation
    from realizer.face.idle import IdleMotion
    from realizer.face.model import Face
    from realizer.scene import Scene

_UNSET: Any = object()
_MIXER: tuple[Any, Any] | None = None


def _face_mixer() -> tuple[Any, Any]:
    """``(FapFrame, mix)``, imported on the first frame (a session without a
    face never loads the face package) and kept for every later one."""
    global _MIXER
    if _MIXER is None:
        from realizer.face.frame import FapFrame
        from realizer.face.tracks import mix

        _MIXER = (FapFrame, mix)
    return _MIXER


class BlockState(enum.Enum):
    PENDING = "pending"  # planned, start not yet reached
    IN_EXECUTION = "in execution"
    DONE = "done"
    INTERRUPTED = "interrupted"
    FAILED = "failed"


class BlockEvent(enum.Enum):
    START = "start"  # time passed the block's start
    FINISH = "finish"  # time passed the block's end
    INTERRUPT = "interrupt"  # interrupted by id, or by a REPLACE block
    FAIL = "fail"  # the block could not be scheduled


#: Every legal transition of a block's lifecycle; nothing else may happen.
TRANSITIONS: dict[tuple[BlockState, BlockEvent], BlockState] = {
    (BlockState.PENDING, BlockEvent.START): BlockState.IN_EXECUTION,
    (BlockState.PENDING, BlockEvent.INTERRUPT): BlockState.INTERRUPTED,
    (BlockState.PENDING, BlockEvent.FAIL): BlockState.FAILED,
    (BlockState.IN_EXECUTION, BlockEvent.FINISH): BlockState.DONE,
    (BlockState.IN_EXECUTION, BlockEvent.INTERRUPT): BlockState.INTERRUPTED,
}

ACTIVE = frozenset({BlockState.PENDING, BlockState.IN_EXECUTION})


class LifecycleError(RealizerError):
    """An event that the lifecycle table does not allow in the block's state."""


@dataclass(slots=True)
class BlockLifecycle:
    block_id: str
    state: BlockState = BlockState.PENDING

    def handle(self, event: BlockEvent) -> BlockState:
        try:
            self.state = TRANSITIONS[(self.state, event)]
        except KeyError:
            raise LifecycleError(
                f"block {self.block_id!r}: event {event.value!r} is not allowed "
                f"in state {self.state.value!r}"
            ) from None
        return self.state


#: A feedback event still to report: (global time rounded to the microsecond,
#: block sequence number, kind rank (0 start, 1 sync, 2 end), behaviour
#: index in the block, sync index in the behaviour's canonical order, kind,
#: behaviour id, sync name, exact global time).
#: Sorting by the tuple gives the documented same-instant order: time, then
#: the order blocks arrived in (so a block's end comes before the start of
#: the block appended after it), then block start, sync points (behaviours
#: in document order, each in its canonical order), block end.
_Event = tuple[float, int, int, int, int, str, str, str, float]


@dataclass(slots=True)
class _Record:
    plan: TimedPlan
    lifecycle: BlockLifecycle
    # still to report, in the order of :data:`_Event`'s rank
    events: deque[_Event]
    animations: list[Animation] = field(default_factory=list)
    #: speech audio on the session clock
    audio: list[AudioClip] = field(default_factory=list)
    #: the parsed block, to plan it again (a preplanned block when activated)
    result: ParseResult | None = None
    #: behaviour id -> its animations (for BMLA interrupts and value changes)
    owned: dict[str, list[Animation]] = field(default_factory=dict)
    #: BMLA control behaviours of the block (activate, interrupt,
    #: parameterValueChange): behaviour id -> behaviour, acted on at its start
    controls: dict[str, Any] = field(default_factory=dict)
    #: BMLA: planned, waiting for an activation (bmla:preplan)
    preplanned: bool = False
    #: BMLA: do not start before this global time (a prependBefore block's end)
    not_before: float = -math.inf


@dataclass(frozen=True, slots=True)
class AdmittedBlock:
    """A block :meth:`Session.admit_bml` let in, with what planning needs:
    the time it arrived, its start (after the blocks it is appended to) and
    the plans of the session's earlier blocks (for references to their sync
    points)."""

    result: ParseResult
    now: float
    strict: bool
    start: float
    earlier: tuple[TimedPlan, ...]
    #: behaviours of other active blocks whose resource channels are taken
    occupied: list[tuple[str, ScheduledBehaviour]] = field(default_factory=list)
    #: the sync times of ``earlier``, (block, behaviour, sync) -> global
    #: seconds, when already collected (a planner process is sent these, not
    #: the plans): None, collect them from ``earlier``
    external: dict[tuple[str, str, str], float] | None = None

    def external_times(self) -> dict[tuple[str, str, str], float]:
        """The fixed times the block refers to: the sync points of the earlier
        blocks it names (``bml1:nod1:end``), (block, behaviour, sync) -> seconds.

        Linear in the block's references and the named blocks' sync points."""
        if self.external is not None:
            return self.external
        block = self.result.block
        named = {
            ref.block
            for _, ref in block.all_sync_refs()
            if ref.block is not None and ref.block != block.id
        }
        external: dict[tuple[str, str, str], float] = {}
        for earlier in self.earlier:
            if earlier.id in named:
                external.update(earlier.global_keys())
        return external


@dataclass(slots=True)
class PlannedBlock:
    """What :meth:`Session.plan_bml` made of an admitted block: its warnings
    (queued by :meth:`Session.commit_bml`), and, unless planning failed
    (``plan`` None), the plan, its prediction, events and animations."""

    admitted: AdmittedBlock
    notes: list[Feedback]
    plan: TimedPlan | None = None
    predicted: Feedback | None = None
    events: list[_Event] = field(default_factory=list)
    animations: list[Animation] = field(default_factory=list)
    audio: list[AudioClip] = field(default_factory=list)
    owned: dict[str, list[Animation]] = field(default_factory=dict)
    engine_notes: int = 0  # warnings of the engines (refuse the block in strict mode)


@dataclass(frozen=True, slots=True)
class SessionLimits:
    """Named limits of one session."""

    parse: Limits = field(default_factory=Limits)
    #: interrupted animations ease out over this many seconds
    release: float = 0.2
    #: finished (done, interrupted, failed) blocks remembered for state
    #: queries and cross-block references; older ones are forgotten so that
    #: a long-running session stays as fast as a new one
    finished_kept: int = 64


class Session:
    """One character: its blocks, their lifecycles, feedback and face frames."""

    def __init__(
        self,
        character_id: str = "",
        face: Face | None = None,
        *,
        registry: EngineRegistry | None = None,
        limits: SessionLimits | None = None,
        idle: IdleMotion | None = None,
        scene: Scene | None = None,
    ) -> None:
        self.character_id = character_id
        #: the character's face (None: the default face)
        self.face: Face | None = face
        # Idle motion (realizer.face.idle.IdleMotion, or None: off): fills the
        # FAPs no animation sets, so explicit behaviours win per FAP.
        self.idle = idle
        # The targets gaze, gazeShift, pointing and headDirectionShift look at
        # (realizer.scene.Scene, shared by a server's characters), or None.
        self.scene = scene
        self.registry = registry or EngineRegistry.standard()
        self.limits = limits or SessionLimits()
        self.now = float("-inf")
        self._blocks: dict[str, _Record] = {}
        # What a tick looks at: records with events to report or animations
        # to show (pending, running, or finished and still fading). Finished
        # blocks kept only for queries are not here, so a tick costs the
        # same however many of them are kept.
        self._live: list[_Record] = []
        # Finished records, oldest first, for forgetting beyond the limit.
        self._finished: deque[_Record] = deque()
        self._feedback: list[Feedback] = []
        self._order = 0
        self._audio_cut: float | None = None  # earliest audio cut not yet taken
        self._fap_limits: Any = _UNSET  # the registry's, looked up on the first frame

    # -- queries -----------------------------------------------------------

    def state(self, block_id: str) -> BlockState | None:
        record = self._blocks.get(block_id)
        return record.lifecycle.state if record else None

    def plan(self, block_id: str) -> TimedPlan | None:
        record = self._blocks.get(block_id)
        return record.plan if record else None

    @property
    def active_blocks(self) -> list[str]:
        return [bid for bid, r in self._blocks.items() if r.lifecycle.state in ACTIVE]

    # -- input -------------------------------------------------------------

    def receive_bml(
        self, text: str | bytes | ParseResult, now: float, *, strict: bool = False
    ) -> TimedPlan | None:
        """Parse, plan and schedule a block arriving at ``now``.

        ``text`` may also be a :class:`ParseResult` the caller already has
        (the service parses once to route a block to its character).

        ``strict`` (planners' CI): every warning of the parser or the
        scheduler, an unknown reference included, is an error: the warnings
        are reported, then one more saying the block is refused in strict
        mode, and nothing of it runs (a REPLACE block interrupts nothing).

        Feedback (warnings, then the prediction) is queued; returns the plan,
        or None when the block was refused (a warningFeedback says why).

        The same as :meth:`admit_bml`, :meth:`plan_bml` and
        :meth:`commit_bml` in a row; the service calls them apart, so that
        the session is only held (from its clock) while admitting and
        committing, not while the block is planned.
        """
        admitted = self.admit_bml(text, now, strict=strict)
        if admitted is None:
            return None
        return self.commit_bml(self.plan_bml(admitted), now)

    def admit_bml(
        self, text: str | bytes | ParseResult, now: float, *, strict: bool = False
    ) -> AdmittedBlock | None:
        """The first step of :meth:`receive_bml`: parse (unless parsed), refuse
        a duplicate, act on the composition (REPLACE and BMLA interrupts), and
        take what planning needs from the session (the start, the sync times of
        earlier blocks). None: refused (a warning is queued)."""
        self._advance(now)
        # What time has passed since the last tick is reported first, so
        # that the feedback queue stays in time order (and a block that
        # ended meanwhile is done before a REPLACE or APPEND looks at it).
        self._progress(now)
        try:
            result = (
                text
                if isinstance(text, ParseResult)
                else parse_bml(text, source=f"bml@{now:.3f}", limits=self.limits.parse)
            )
        except BmlError as exc:
            self._emit(warning("", "", str(exc.warning_type),
                               f"{exc.line}:{exc.column}: {exc.message}", now,
                               self.character_id))  # fmt: skip
            return None
        block = result.block
        if self._refuse_duplicate(block.id, now):
            return None
        control = block.control
        if block.composition == "REPLACE" and not strict:
            for block_id in self.active_blocks:
                self.interrupt(block_id, now)
        for block_id in control.interrupt if not strict else ():
            self.interrupt(block_id, now)  # BMLA: bmla:interrupt="b1,b2"
        start = now
        if block.composition == "APPEND":
            ends = [r.plan.end for r in self._blocks.values() if r.lifecycle.state in ACTIVE]
            start = max([now, *ends])
        for block_id in control.after:  # BMLA: appendAfter, chunkAfter
            earlier = self._blocks.get(block_id)
            if earlier is None:
                self._emit(warning(block.id, block.id, str(WarningType.NO_SUCH_TARGET),
                                   f"block {block.id!r} is to follow {block_id!r}, which is not "
                                   "known; it starts without waiting for it", now,
                                   self.character_id))  # fmt: skip
            elif earlier.lifecycle.state in ACTIVE:
                start = max(start, earlier.plan.end)
        # the plans (immutable) only: their sync times are collected off the lock
        plans = tuple(record.plan for record in self._blocks.values())
        # strict mode judges the block as it would run: what its REPLACE
        # or bmla:interrupt would stop takes no channel from it
        occupied = self._occupied(
            start,
            stops=set(control.interrupt)
            | (set(self.active_blocks) if block.composition == "REPLACE" else set()),
        )
        return AdmittedBlock(result, now, strict, start, plans, occupied)

    def _refuse_duplicate(self, block_id: str, now: float) -> bool:
        """True (and a warning) when a block of this id is pending or running."""
        found = self._blocks.get(block_id)
        if found is None or found.lifecycle.state not in ACTIVE:
            return False
        self._emit(
            warning(
                block_id,
                block_id,
                str(WarningType.PARSING_FAILURE),
                f"block {block_id!r} is already running; the new one is refused",
                now,
                self.character_id,
            )
        )
        return True

    def plan_bml(self, admitted: AdmittedBlock) -> PlannedBlock:
        """The second step of :meth:`receive_bml`: schedule the block and
        realize its behaviours (solver, face and speech engines).

        Reads nothing of the session that a tick changes (what it needs was
        taken by :meth:`admit_bml`) and changes nothing: its warnings are kept
        in the result for :meth:`commit_bml`. So it may run on another thread
        while the session ticks; only one block of a session at a time.
        """
        block = admitted.result.block
        now = admitted.now
        notes: list[Feedback] = []
        external = admitted.external_times()
        try:
            plan = schedule_block(
                block,
                start=admitted.start,
                registry=self.registry,
                dropped=admitted.result.dropped,
                external=external,
                warnings=admitted.result.warnings,
                occupied=admitted.occupied,
            )
        except SchedulingFailed as exc:
            for note in exc.warnings:
                notes.append(warning(block.id, note.id, str(note.type), note.message, now,
                                     self.character_id))  # fmt: skip
            return PlannedBlock(admitted, notes)
        try:
            # Everything that can still go wrong with this block happens
            # before its prediction is sent: a prediction is a promise that
            # the block runs and ends.
            predicted = prediction(
                block.id,
                plan.start,
                plan.end,
                [(s.behaviour, s.times) for s in plan.behaviours],
                now,
                self.character_id,
            )
            if block.control.preplan:
                events: list[_Event] = []
                animations: list[Animation] = []
                audio: list[AudioClip] = []
                owned: dict[str, list[Animation]] = {}
            else:
                events = _events(plan, 0)
                animations, audio, owned = self._realize(plan, notes, now)
        except Exception as exc:  # a bug or an unforeseen value: the block fails, cleanly
            notes.append(
                warning(
                    block.id,
                    block.id,
                    str(WarningType.CANNOT_CREATE_BEHAVIOR),
                    f"block {block.id!r} could not be realized ({type(exc).__name__}); "
                    "it is refused",
                    now,
                    self.character_id,
                )
            )
            return PlannedBlock(admitted, notes)
        for note in plan.warnings:
            notes.append(warning(block.id, note.id, str(note.type), note.message, now,
                                 self.character_id))  # fmt: skip
        engine_notes = 0
        for scheduled in plan.behaviours:
            for text in self.registry.notes(scheduled.behaviour):
                engine_notes += 1
                notes.append(warning(block.id, f"{block.id}:{scheduled.id}",
                                     str(WarningType.CANNOT_CREATE_BEHAVIOR),
                                     f"{scheduled.id}: {text}", now,
                                     self.character_id))  # fmt: skip
        return PlannedBlock(admitted, notes, plan, predicted, events, animations, audio, owned,
                            engine_notes)  # fmt: skip

    def commit_bml(self, planned: PlannedBlock, now: float) -> TimedPlan | None:
        """The last step of :meth:`receive_bml`: queue the planning's warnings
        and the prediction, record the block and report what is already due.

        ``now``: the session time of the commit (the arrival time or later:
        the session may have ticked while the block was planned; the block
        keeps the start it was planned for, and what of it is already past is
        reported now). Returns the plan, or None when the block was refused.
        """
        self._advance(now)
        now = self.now
        admitted = planned.admitted
        block = admitted.result.block
        strict = admitted.strict
        lifecycle = BlockLifecycle(block.id)
        for note in planned.notes:
            self._emit(note)
        if self._refuse_duplicate(block.id, now):  # one came meanwhile (another caller)
            return None
        plan = planned.plan
        if plan is None or planned.predicted is None:
            self._failed(block, admitted.start, lifecycle)
            return None
        if strict and (plan.warnings or planned.engine_notes):
            kind = plan.warnings[0].type if plan.warnings else WarningType.CANNOT_CREATE_BEHAVIOR
            self._emit(warning(block.id, block.id, str(kind),
                               f"strict mode: {len(plan.warnings) + planned.engine_notes} "
                               f"warning(s) above are errors; block {block.id!r} is refused",
                               admitted.now, self.character_id))  # fmt: skip
            self._failed(block, admitted.start, lifecycle)
            return None
        control = block.control
        if block.composition == "REPLACE" and strict:
            for block_id in self.active_blocks:
                self.interrupt(block_id, now)
        predicted = planned.predicted
        if control.preplan:  # BMLA: the prediction says it waits to be activated
            predicted = prediction(block.id, plan.start, plan.end,
                                   [(s.behaviour, s.times) for s in plan.behaviours],
                                   admitted.now, self.character_id,
                                   status="PENDING")  # fmt: skip
        self._emit(predicted)
        self._order += 1
        events = [(e[0], self._order, *e[2:]) for e in planned.events]
        record = _Record(plan, lifecycle, deque(events), planned.animations, planned.audio,
                         admitted.result, planned.owned)  # fmt: skip
        record.controls = _controls(plan)
        record.preplanned = control.preplan
        self._blocks[block.id] = record
        if not control.preplan:
            self._live.append(record)
        for block_id in control.prepend_before:  # BMLA: the targets wait for this one
            self._prepend(record, block_id, now)
        self._progress(now)
        return plan

    def activate(self, block_id: str, now: float) -> bool:
        """Start a preplanned block (BMLA) at ``now``; False (and a warning) if there is none.

        It is planned again from ``now`` (or from the end of a block that
        was prepended before it, if later), with a new prediction.
        """
        self._advance(now)
        record = self._blocks.get(block_id)
        if record is None or not record.preplanned or record.result is None:
            self._emit(warning(block_id, block_id, str(WarningType.NO_SUCH_TARGET),
                               f"no preplanned block {block_id!r} to activate", now,
                               self.character_id))  # fmt: skip
            return False
        record.preplanned = False
        self._start_at(record, max(now, record.not_before), now)
        return True

    def _start_at(self, record: _Record, start: float, now: float) -> None:
        """Plan ``record``'s block again to start at ``start`` (global seconds)."""
        assert record.result is not None
        block = record.result.block
        external: dict[tuple[str, str, str], float] = {}
        for other in self._blocks.values():
            if other is not record:
                external.update(other.plan.global_keys())
        try:
            plan = schedule_block(block, start=start, registry=self.registry,
                                  dropped=record.result.dropped, external=external,
                                  occupied=self._occupied(start, record))  # fmt: skip
        except SchedulingFailed as exc:
            for note in exc.warnings:
                self._emit(warning(block.id, note.id, str(note.type), note.message, now,
                                   self.character_id))  # fmt: skip
            record.lifecycle.handle(BlockEvent.INTERRUPT)
            self._emit(block_progress(block.id, "end", now, self.character_id, "FAILED"))
            self._finished.append(record)
            return
        record.plan = plan
        record.events = deque(self._events(plan))
        record.animations, record.audio, record.owned = self._realize(plan)
        record.controls = _controls(plan)
        self._emit(prediction(block.id, plan.start, plan.end,
                              [(s.behaviour, s.times) for s in plan.behaviours], now,
                              self.character_id))  # fmt: skip
        if record not in self._live:
            self._live.append(record)

    def _occupied(
        self, start: float, planning: _Record | None = None, stops: set[str] | None = None
    ) -> list[tuple[str, ScheduledBehaviour]]:
        """Behaviours of the other pending and running blocks (but ``stops``)
        that end after ``start``: their resource channels are taken
        (docs/scheduler.md, "Resource conflicts")."""
        return [
            (record.plan.id, scheduled)
            for record in self._blocks.values()
            if record is not planning
            and record.plan.id not in (stops or ())
            and record.lifecycle.state in ACTIVE
            and not record.preplanned  # may never run (BMLA preplan, not activated)
            for scheduled in record.plan.behaviours
            if scheduled.end > start
        ]

    def _prepend(self, record: _Record, block_id: str, now: float) -> None:
        """BMLA prependBefore: ``block_id`` does not start before ``record`` ends."""
        later = self._blocks.get(block_id)
        if later is None or later.lifecycle.state is not BlockState.PENDING:
            self._emit(warning(record.plan.id, record.plan.id, str(WarningType.NO_SUCH_TARGET),
                               f"no block {block_id!r} waiting to start, to prepend "
                               f"{record.plan.id!r} before", now, self.character_id))  # fmt: skip
            return
        later.not_before = max(later.not_before, record.plan.end)
        if not later.preplanned and later.plan.start < record.plan.end:
            self._start_at(later, record.plan.end, now)

    def _realize(
        self, plan: TimedPlan, notes: list[Feedback] | None = None, now: float | None = None
    ) -> tuple[list[Animation], list[AudioClip], dict[str, list[Animation]]]:
        """The animations, audio clips and animations by behaviour of a solved
        plan; warnings go to ``notes`` (at ``now``) when given, else are queued."""
        animations: list[Animation] = []
        audio: list[AudioClip] = []
        owned: dict[str, list[Animation]] = {}
        for scheduled in plan.behaviours:
            if scheduled.id in plan.unrealized:
                continue
            aimed = self._aimed(plan.id, scheduled.behaviour, warn=True, notes=notes, now=now)
            realized = self.registry.realize(aimed, scheduled.times)
            if realized is None:
                continue
            # A speech realizes as several animations (lip sync) and audio.
            parts = getattr(realized, "parts", None)
            mine = list(parts if parts is not None else (realized,))
            animations.extend(mine)
            owned[scheduled.id] = mine
            clip = getattr(realized, "audio", None)
            if clip is not None:
                audio.append(clip)
        return animations, audio, owned

    def _aimed(
        self,
        block_id: str,
        behaviour: Any,
        warn: bool = False,
        notes: list[Feedback] | None = None,
        now: float | None = None,
    ) -> Any:
        """The behaviour with its scene target's direction (``sceneYaw``,
        ``scenePitch``: degrees, yaw to the left, pitch down) for the engine;
        a target neither the scene nor the direction words know: a warning."""
        if behaviour.type not in SCENE_TYPES:
            return behaviour
        target = (behaviour.param("target") or "").strip()
        if target.upper().replace("_", "") in DIRECTION_WORDS:
            return behaviour
        found = self.scene.direction(self.character_id, target) if self.scene else None
        if found is None:
            if warn:
                known = ", ".join(sorted(self.scene.targets)) if self.scene else "none"
                note = warning(block_id, f"{block_id}:{behaviour.id}",
                               str(WarningType.NO_SUCH_TARGET),
                               f"{behaviour.id}: target {target!r} is not in the scene "
                               f"(targets: {known}; or a direction word); it looks straight "
                               "ahead", self.now if now is None else now,
                               self.character_id)  # fmt: skip
                if notes is None:
                    self._emit(note)
                else:
                    notes.append(note)
            return behaviour
        yaw, pitch = found
        params = (*behaviour.params, ("sceneYaw", f"{yaw:.6f}"), ("scenePitch", f"{-pitch:.6f}"))
        return dataclasses.replace(behaviour, params=params)

    def target_moved(self, name: str, now: float) -> None:
        """A scene target moved (or appeared) at ``now``: behaviours aimed at
        it look at its new place from now on (the eyes jump, as in a saccade)."""
        from realizer.control import Window
        from realizer.face.tracks import InterruptedAnimation

        self._advance(now)
        for record in self._live:
            if record.lifecycle.state not in ACTIVE:
                continue
            for scheduled in record.plan.behaviours:
                behaviour = scheduled.behaviour
                if (
                    behaviour.type not in SCENE_TYPES
                    or (behaviour.param("target") or "").strip() != name
                    or scheduled.end <= now
                    or scheduled.id in record.plan.unrealized
                ):
                    continue
                realized = self.registry.realize(self._aimed(record.plan.id, behaviour),
                                                 scheduled.times)  # fmt: skip
                if realized is None:
                    continue
                old = {id(a) for a in record.owned.get(scheduled.id, ())}
                new: list[Animation] = [
                    Window(a, now) for a in getattr(realized, "parts", None) or (realized,)
                ]
                record.animations = [
                    InterruptedAnimation(a, at=now, release=0.0) if id(a) in old else a
                    for a in record.animations
                ] + new  # fmt: skip
                record.owned[scheduled.id] = new

    def _control(self, record: _Record, behaviour: Any, now: float) -> None:
        """Act on a BMLA control behaviour whose start passed at ``now``."""
        target = behaviour.param("target") or ""
        if behaviour.type == "activate":
            self.activate(target, now)
        elif behaviour.type == "interrupt":
            include = _ids(behaviour.param("include"))
            exclude = _ids(behaviour.param("exclude"))
            if not include and not exclude:
                self.interrupt(target, now)
            else:
                self._interrupt_behaviours(target, include, exclude, now)
        elif behaviour.type == "parameterValueChange":
            self._change_parameter(record, behaviour, now)

    def _interrupt_behaviours(
        self, block_id: str, include: tuple[str, ...], exclude: tuple[str, ...], now: float
    ) -> None:
        """BMLA ``<bmla:interrupt include|exclude>``: stop some behaviours of a block."""
        record = self._blocks.get(block_id)
        if record is None or record.lifecycle.state not in ACTIVE:
            self._emit(warning(block_id, block_id, str(WarningType.NO_SUCH_TARGET),
                               f"no pending or running block {block_id!r} to interrupt "
                               "behaviours of", now, self.character_id))  # fmt: skip
            return
        ids = [s.id for s in record.plan.behaviours]
        chosen = {i for i in ids if (i in include if include else i not in exclude)}
        for missing in sorted(set(include) - set(ids)):
            self._emit(warning(block_id, f"{block_id}:{missing}", str(WarningType.NO_SUCH_TARGET),
                               f"block {block_id!r} has no behaviour {missing!r} to interrupt",
                               now, self.character_id))  # fmt: skip
        from realizer.face.tracks import InterruptedAnimation

        for behaviour_id in sorted(chosen, key=ids.index):
            pending = [e for e in record.events if e[6] == behaviour_id]
            if not pending:
                continue  # already over
            record.events = deque(e for e in record.events if e[6] != behaviour_id)
            stopped = {id(a) for a in record.owned.get(behaviour_id, ())}
            record.animations = [
                InterruptedAnimation(a, at=now, release=self.limits.release)
                if id(a) in stopped else a
                for a in record.animations
            ]  # fmt: skip
            record.audio = [
                c.cut(now) if getattr(c, "behaviour_id", "") == behaviour_id else c
                for c in record.audio
            ]
            # The behaviour's end is reported at the moment it stopped.
            self._emit(sync_point_progress(block_id, behaviour_id, "end", now - record.plan.start,
                                           now, self.character_id))  # fmt: skip

    def _change_parameter(self, record: _Record, behaviour: Any, now: float) -> None:
        """BMLA parametervaluechange: move a parameter of a behaviour along a ramp."""
        from realizer.control import CHANGEABLE, Ramp, ScaledAnimation, scaled_clip

        target = behaviour.param("target") or ""
        block_id, _, behaviour_id = target.rpartition(":")
        block_id = block_id or record.plan.id
        param = behaviour.param("paramId") or ""
        owner = self._blocks.get(block_id)
        scheduled = next(
            (s for s in owner.plan.behaviours if s.id == behaviour_id), None
        ) if owner is not None else None  # fmt: skip
        times = next(s.times for s in record.plan.behaviours if s.id == behaviour.id)
        if owner is None or scheduled is None or param not in CHANGEABLE:
            why = (
                f"{param!r} is not a parameter that can change (only {', '.join(CHANGEABLE)})"
                if param not in CHANGEABLE
                else f"{target!r} names no behaviour"
            )
            self._emit(warning(record.plan.id, f"{record.plan.id}:{behaviour.id}",
                               str(WarningType.NO_SUCH_TARGET), f"{behaviour.id}: {why}", now,
                               self.character_id))  # fmt: skip
            return
        own = scheduled.behaviour.number("amount", 1.0) if param == "amount" else 1.0
        initial = behaviour.number("initialValue", own)
        goal = behaviour.number("targetValue", own)
        scale = 1.0 / own if own else 1.0
        ramp = Ramp(times["start"], times["end"], initial * scale, goal * scale)
        if param == "volume":
            owner.audio = [
                scaled_clip(c, ramp) if getattr(c, "behaviour_id", "") == behaviour_id else c
                for c in owner.audio
            ]
            return
        changed = {id(a) for a in owner.owned.get(behaviour_id, ())}
        replaced: list[Animation] = []
        for animation in owner.animations:
            replaced.append(
                ScaledAnimation(animation, ramp) if id(animation) in changed else animation
            )
        owner.animations = replaced
        owner.owned[behaviour_id] = [a for a in replaced if isinstance(a, ScaledAnimation)
                                     and id(a.base) in changed]  # fmt: skip

    def _failed(self, block: Any, start: float, lifecycle: BlockLifecycle) -> None:
        lifecycle.handle(BlockEvent.FAIL)
        failed = _Record(TimedPlan(block, start, start, ()), lifecycle, deque())
        self._blocks[block.id] = failed
        self._finished.append(failed)

    def _events(self, plan: TimedPlan) -> list[_Event]:
        """The block's feedback events, in the order of :data:`_Event`."""
        self._order += 1
        return _events(plan, self._order)

    def interrupt(self, block_id: str, now: float) -> bool:
        """Interrupt a pending or running block; False (and a warning) if there is none."""
        self._advance(now)
        self._progress(now)
        record = self._blocks.get(block_id)
        if record is None or record.lifecycle.state not in ACTIVE:
            self._emit(
                warning(
                    block_id,
                    block_id,
                    str(WarningType.NO_SUCH_TARGET),
                    f"no pending or running block {block_id!r} to interrupt",
                    now,
                    self.character_id,
                )
            )
            return False
        was_running = record.lifecycle.state is BlockState.IN_EXECUTION
        record.lifecycle.handle(BlockEvent.INTERRUPT)
        self._finished.append(record)
        record.events.clear()
        if was_running:
            from realizer.face.tracks import InterruptedAnimation

            record.animations = [
                InterruptedAnimation(a, at=now, release=self.limits.release)
                for a in record.animations
            ]
        else:
            record.animations = []
        # The audio stops now: what a viewer has not been sent is never sent,
        # and what was sent ahead is cut (take_audio_cut).
        if record.audio:
            self._audio_cut = now if self._audio_cut is None else min(self._audio_cut, now)
        record.audio = [clip.cut(now) for clip in record.audio] if was_running else []
        status = "INTERRUPTED" if was_running else "REVOKED"
        self._emit(block_progress(block_id, "end", now, self.character_id, status))
        return True

    def tick(self, now: float) -> None:
        """Advance to ``now``: progress feedback for every sync point passed."""
        self._advance(now)
        self._progress(now)
        self._forget(now)

    # -- output ------------------------------------------------------------

    def take_feedback(self) -> list[Feedback]:
        """The queued feedback, oldest first; the queue is emptied."""
        out, self._feedback = self._feedback, []
        return out

    def frame(self, now: float) -> Any:
        """The face's FAP frame at ``now``: the mix of every animation active then."""
        frame_type, mix = _face_mixer()
        animations = [a for r in self._live for a in r.animations]
        if not animations:
            if self.idle is not None:
                values, mask = self.idle.frame(now)
                return frame_type(values, mask, time=now)
            return frame_type.neutral(time=now)
        if self._fap_limits is _UNSET:
            self._fap_limits = self.registry.fap_limits
        values, mask = mix(animations, now, self._fap_limits)
        if self.idle is not None:
            idle_values, idle_mask = self.idle.frame(now)
            free = idle_mask & ~mask
            values = values.copy()
            values[free] = idle_values[free]
            mask = mask | idle_mask
        return frame_type(values, mask, time=now)

    def audio(self, start: float, end: float, sample_rate: int = 22050) -> Any:
        """The character's speech audio over ``[start, end)`` seconds, or None if silent there.

        Returns an :class:`~realizer.engines.speech.AudioClip` of mono PCM16
        at ``sample_rate``: every speech clip sounding then, mixed (and
        clipped to 16 bits). Sample ``i`` of the whole clock is at
        ``i / sample_rate`` seconds, so consecutive calls whose ``start`` is
        the previous ``end`` join without a gap or an overlap.
        """
        clips = [c for r in self._live for c in r.audio if c.end > start and c.start < end]
        if not clips:
            return None
        from realizer.engines.speech.mixing import mix_audio

        return mix_audio(clips, start, end, sample_rate)

    def take_audio_cut(self) -> float | None:
        """The earliest instant (seconds) at which an interruption cut speech audio
        since the last call, or None: audio sent ahead of it must not play."""
        cut, self._audio_cut = self._audio_cut, None
        return cut

    # -- internals ---------------------------------------------------------

    def _advance(self, now: float) -> None:
        if now > self.now:
            self.now = now

    def _emit(self, feedback: Feedback) -> None:
        self._feedback.append(feedback)

    def _forget(self, now: float) -> None:
        """Drop animations that have ended and the oldest finished blocks.

        Costs what the live blocks cost: finished blocks kept for queries are
        only touched when one is forgotten.
        """
        dropped = False
        for record in self._live:
            if record.lifecycle.state in ACTIVE:
                continue
            if record.animations:
                record.animations = [a for a in record.animations if a.end >= now]
            if record.audio:
                record.audio = [clip for clip in record.audio if clip.end >= now]
            if not record.animations and not record.events and not record.audio:
                dropped = True
        if dropped:
            self._live = [
                r
                for r in self._live
                if r.lifecycle.state in ACTIVE or r.animations or r.events or r.audio
            ]
        finished = self._finished
        while len(finished) > self.limits.finished_kept:
            oldest = finished[0]
            if oldest.animations:
                break  # still fading out; forgotten on a later tick
            finished.popleft()
            block_id = oldest.lifecycle.block_id
            if self._blocks.get(block_id) is oldest:  # not a newer block of that id
                del self._blocks[block_id]

    def _progress(self, now: float) -> None:
        due: list[tuple[_Event, _Record]] = []
        for record in self._live:
            events = record.events
            while events and events[0][-1] <= now + 1e-12:
                due.append((events.popleft(), record))
        if not due:
            return
        due.sort(key=lambda item: item[0])
        previous = -math.inf
        again = False  # a control started a block whose first events are due now
        for (*_, kind, behaviour_id, sync, exact), record in due:
            # Events of one microsecond keep the documented order; their exact
            # times, a round-off apart, are made non-decreasing with it.
            time = previous = max(exact, previous)
            block_id = record.lifecycle.block_id
            if record.lifecycle.state not in ACTIVE:
                continue  # stopped by a control acted on earlier in this batch
            if kind == "start":
                record.lifecycle.handle(BlockEvent.START)
                self._emit(block_progress(block_id, "start", time, self.character_id, "IN_EXEC"))
                if record.result is not None:
                    for later in record.result.block.control.on_start:  # BMLA onStart
                        self.activate(later, time)
                        again = True
            elif kind == "sync":
                self._emit(
                    sync_point_progress(
                        block_id,
                        behaviour_id,
                        sync,
                        time - record.plan.start,
                        time,
                        self.character_id,
                    )
                )
                if sync == "start" and behaviour_id in record.controls:
                    self._control(record, record.controls[behaviour_id], time)
                    again = True
            else:
                record.lifecycle.handle(BlockEvent.FINISH)
                self._finished.append(record)
                self._emit(block_progress(block_id, "end", time, self.character_id, "DONE"))
        if again:
            self._progress(now)


#: Behaviour types whose ``target`` names a place in the scene.
SCENE_TYPES = frozenset({"gaze", "gazeShift", "pointing", "headDirectionShift"})
#: BML 1.0 direction words a gaze may name instead of a target (upper case, no "_").
DIRECTION_WORDS = frozenset(
    {"LEFT", "RIGHT", "UP", "DOWN", "UPLEFT", "UPRIGHT", "DOWNLEFT", "DOWNRIGHT"}
)

#: Behaviour types of AsapRealizer's BMLA that control the realizer.
CONTROL_TYPES = frozenset({"activate", "interrupt", "parameterValueChange"})


def _events(plan: TimedPlan, seq: int) -> list[_Event]:
    """A block's feedback events, in the order of :data:`_Event` (``seq``: the
    block's sequence number in the session)."""
    # Equal instants are equal as the feedback writes them (microseconds),
    # not as the solver's floating point happens to leave them.
    events: list[_Event] = [(round(plan.start, 6), seq, 0, 0, 0, "start", "", "", plan.start)]
    for index, scheduled in enumerate(plan.behaviours):
        canonical = scheduled.behaviour.syncs
        for sync, time in scheduled.times.items():
            rank = canonical.index(sync) if sync in canonical else len(canonical)
            events.append((round(time, 6), seq, 1, index, rank, "sync", scheduled.id, sync, time))
    events.append((round(plan.end, 6), seq, 2, 0, 0, "end", "", "", plan.end))
    events.sort()
    return events


def _controls(plan: TimedPlan) -> dict[str, Any]:
    return {s.id: s.behaviour for s in plan.behaviours if s.behaviour.type in CONTROL_TYPES}


def _ids(raw: str | None) -> tuple[str, ...]:
    return tuple(part.strip() for part in (raw or "").split(",") if part.strip())
