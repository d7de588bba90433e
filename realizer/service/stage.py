"""The service's sans-I/O core: characters, their sessions, routing, frames.

Like the protocol core of websockets, a :class:`Stage` never touches a
socket and never reads a clock (the sans-I/O core of docs/architecture.md): the asyncio
layer (:mod:`realizer.service.server`) passes ``now`` in seconds and sends
what the stage returns. Tests drive a stage at any speed, with no network.

A stage keeps one :class:`realizer.session.Session` per character id,
created on first use, and answers

* :meth:`Stage.submit_bml`: route a BML document to its character (the
  request's ``character``, else the block's ``characterId``, else the
  connection's default), check the named limits, hand it to the session and
  return the feedback it made at once (the prediction, or a warning);
* :meth:`Stage.interrupt`: interrupt a block by id;
* :meth:`Stage.tick`: advance every session once to ``now`` (one clock
  tick), returning each character's progress feedback and FAP frame.

**Every accepted block ends** (the stage's guarantee, tested with
hypothesis in ``tests/service/test_stage_properties.py``): for every
``accepted`` :class:`BlockEvent` the stage returns, exactly one of
``done``, ``interrupted`` or ``failed`` follows. Acceptance is the outcome
of this very call (the session returned a plan), never read from feedback
that may belong to an older block of the same id; a block is opened at its
prediction, so a block whose end falls in the same call (an empty one) is
``done`` in the same answer; a session that raises while planning gets the
block refused (its prediction dropped); a session that fails while ticking
has its open blocks failed and is replaced by a fresh one; and a block
still open :data:`END_GRACE_SECONDS` after its predicted end (or after an
interrupt) is failed. Warnings about one block in one answer are bounded
(``ServiceLimits.warnings_per_block``).

Where a block is parsed and planned: with a ``planner``
(:class:`BlockPlanner`, realizer.service.planner's pool of planner
processes) the stage leases one for each submission, which parses the text
and, once the session has admitted the block (on the caller's side, the
character's lock held), plans it (:meth:`realizer.session.Session.plan_bml`);
the session then commits the plan. Without one, the calling thread does
both. The stage itself starts no process and reads no clock.

Time given to sessions never goes backwards: a BML document that arrives
between the due time of a frame and the moment the clock computes it is
received at its arrival time, and that frame is then computed at the same
time, not before (the frame's ``t`` says which).

:class:`FrameEncoder` turns a character's FAP frame into the msgpack bytes
each kind of viewer wants, deforming the face at most once per tick and not
at all when the FAPs did not change.
"""

from __future__ import annotations

import logging
import math
import re
import threading
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from realizer.bml_parser import BmlError, Limits, ParseResult, parse_bml
from realizer.errors import RealizerError
from realizer.face.fapcoding import DEFAULT_FAP_QUANT, FapStreamEncoder, is_intra
from realizer.face.frame import FapFrame
from realizer.face.model import Face
from realizer.feedback import Feedback
from realizer.scene import Scene, SceneError
from realizer.service import codec
from realizer.service.errors import LimitExceeded, PeerError
from realizer.service.limits import DEFAULT_LIMITS, ServiceLimits, valid_character_id
from realizer.service.messages import BlockState, DeltaPayload, ViewOptions, warning_feedback_xml
from realizer.session import AdmittedBlock, PlannedBlock, Session

logger = logging.getLogger("realizer.service")

#: Seconds between intra frames of the coded FAP stream: a viewer that
#: joins decodes from the next one, at most this long after it joined.
CODED_INTRA_SECONDS = 1.0

# -- the session and the face, as the stage uses them (docs/interfaces.md) ----

#: Makes the session of a character id (realizer.service.assets.session_factory).
SessionFactory = Callable[[str], Session]


class PlanLease(Protocol):
    """One planner (a process) for one submission: it parses the text, then
    plans the block it parsed once the session has admitted it
    (realizer.service.planner.PlannerLease). Its errors are
    :class:`realizer.errors.RealizerError` with a ``warning_type``."""

    def parse(self, text: str, limits: Limits, *, prepare: bool) -> ParseResult: ...

    def plan(self, admitted: AdmittedBlock, character_id: str, scene: Any) -> PlannedBlock: ...


class BlockPlanner(Protocol):
    """Where a stage parses and plans blocks (realizer.service.planner.PlannerPool)."""

    def lease(self) -> AbstractContextManager[PlanLease]: ...


Deformer = Callable[[Any, npt.NDArray[np.float64]], npt.NDArray[Any]]


# -- what the stage returns ----------------------------------------------------


@dataclass(frozen=True, slots=True)
class WireFeedback:
    """One feedback element for the submitters of ``character``."""

    character: str
    kind: str
    block_id: str
    time: float
    xml: str


@dataclass(frozen=True, slots=True)
class BlockEvent:
    """A block of ``character`` changed state (see protocols/submitter.md)."""

    character: str
    block_id: str
    state: BlockState
    time: float


Outgoing = WireFeedback | BlockEvent


@dataclass(frozen=True, slots=True)
class SubmitResult:
    """What a submission did: the character it went to (``""`` when it never
    reached one), the block's id, and the messages to send, in order."""

    character: str
    block_id: str
    accepted: bool
    messages: tuple[Outgoing, ...]


@dataclass(frozen=True, slots=True)
class CharacterTick:
    """One character after one tick: its frame at ``time`` and its feedback."""

    character: str
    time: float
    frame: Any  # FapFrame
    messages: tuple[Outgoing, ...]


@dataclass(slots=True)
class Character:
    """A character's session and the blocks the stage counts against limits.

    ``open_blocks``: id -> session time it was accepted, until its end;
    ``deadlines``: id -> session time by which an open block must have
    ended (its predicted end and :data:`END_GRACE_SECONDS`), after which the
    stage fails it; ``interrupting``: ids of open blocks asked to stop;
    ``idle_since``: session time since which the character has had no open
    block (None while it has one).
    """

    id: str
    session: Session
    open_blocks: dict[str, float] = field(default_factory=dict)
    deadlines: dict[str, float] = field(default_factory=dict)
    interrupting: set[str] = field(default_factory=set)
    idle_since: float | None = None
    #: held while the session is used (a tick; a block admitted or
    #: committed; an interrupt), each time briefly: never while a block is
    #: planned. The clock skips, for one tick, a character whose lock is
    #: held instead of waiting for it.
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    #: held by a planner thread for the whole of one submission or
    #: interrupt of this character (so they keep their order, and a block
    #: is planned against the session it is committed to); never by the clock
    submitting: threading.Lock = field(default_factory=threading.Lock, repr=False)
    #: made for a viewer and never given a block: counted against
    #: ``limits.viewer_characters``
    viewer_made: bool = False


#: Seconds after its predicted end by which an accepted block must have
#: ended; a block still open then is failed by the stage (its session lost
#: it: a bug), so that every accepted block ends.
END_GRACE_SECONDS = 1.0


# Linear: a whitespace character, the literal "id", then runs that border
# characters they cannot match.
_ID_ATTRIBUTE = re.compile(r"\sid\s*=\s*[\"']([^\"'<>]{0,200})[\"']")
_FEEDBACK_ID = re.compile(r"\sid\s*=\s*[\"']([^\"']*)[\"']")
# BMLA's block status (realizer.feedback): INTERRUPTED while running, REVOKED before
_PENDING = re.compile(r"[\s:]status\s*=\s*[\"']PENDING[\"']")
_GLOBAL_END = re.compile(r"\sglobalEnd\s*=\s*[\"']([0-9.eE+-]{1,40})[\"']")
_INTERRUPTED = re.compile(r"[\s:]status\s*=\s*[\"'](?:INTERRUPTED|REVOKED)[\"']")


def _guess_block_id(text: str) -> str:
    """The root's ``id`` of a document the parser refused, for the warning.

    Looks at the first 4,096 characters, each once: the text between one
    ``<`` and the next is a tag candidate; the first named ``bml`` (with any
    prefix) that has an ``id`` gives it.
    """
    for piece in text[:4096].split("<")[1:]:
        tag = piece.partition(">")[0]
        name = tag.split(None, 1)[0] if tag[:1].strip() else ""
        if name.rpartition(":")[2] == "bml":
            match = _ID_ATTRIBUTE.search(tag)
            if match:
                return match.group(1)
    return ""


def _is_block_end(feedback: Feedback) -> bool:
    """True for the ``blockProgress`` that says a block ended (id ``b:end``)."""
    if feedback.kind != "blockProgress":
        return False
    match = _FEEDBACK_ID.search(feedback.xml)
    return match is not None and match.group(1).endswith(":end")


class Stage:
    """Characters and their sessions; see the module docstring.

    ``make_session(character_id)`` builds a session (the real one is
    ``Session(character_id, face)``); ``default_character`` receives BML that
    names no character.
    """

    def __init__(
        self,
        make_session: SessionFactory,
        limits: ServiceLimits = DEFAULT_LIMITS,
        default_character: str = "default",
        *,
        planner: BlockPlanner | None = None,
    ) -> None:
        if not valid_character_id(default_character):
            raise ValueError(f"invalid default character id {default_character!r}")
        self.make_session = make_session
        #: where blocks are parsed and planned: planner processes
        #: (realizer.service.planner.PlannerPool), or None: the calling thread
        self.planner = planner
        self.limits = limits
        self.default_character = default_character
        self.characters: dict[str, Character] = {}
        # The targets every character's gaze can name (realizer.scene).
        self.scene = Scene()
        self.now = 0.0  # the latest time given to any session, seconds
        # guards the character table and ``now`` (planner threads and the clock)
        self._table = threading.Lock()
        #: character ticks that found the character's lock held (a block
        #: being admitted or committed, an interrupt)
        self.skipped_ticks = 0
        #: the characters the last :meth:`tick` left out, their lock held
        self.busy: list[str] = []
        self._parse_limits = Limits(
            max_bytes=limits.message_bytes, max_behaviours=limits.behaviours_per_block
        )

    # -- time -------------------------------------------------------------------

    def _advance(self, now: float) -> float:
        with self._table:
            self.now = max(self.now, now)
            return self.now

    # -- characters -------------------------------------------------------------

    def character(self, character_id: str, *, for_viewer: bool = False) -> Character:
        """The character named ``character_id``, made on first use.

        Raises :class:`LimitExceeded` when ``limits.characters`` exist
        already, or, ``for_viewer``, when viewers alone have made
        ``limits.viewer_characters``; :class:`PeerError` for an id that
        cannot name one.
        """
        with self._table:
            return self._character(character_id, for_viewer)

    def _character(self, character_id: str, for_viewer: bool) -> Character:
        found = self.characters.get(character_id)
        if found is not None:
            if not for_viewer:
                found.viewer_made = False
            return found
        if not valid_character_id(character_id):
            raise PeerError(f"invalid character id {character_id[:80]!r}")
        if len(self.characters) >= self.limits.characters:
            raise LimitExceeded(
                f"limit of {self.limits.characters} characters reached; "
                f"character {character_id!r} not created"
            )
        if for_viewer:
            made_for_viewers = sum(1 for c in self.characters.values() if c.viewer_made)
            if made_for_viewers >= self.limits.viewer_characters:
                raise LimitExceeded(
                    f"limit of {self.limits.viewer_characters} characters made for viewers "
                    f"reached; character {character_id!r} not created"
                )
        made = Character(
            character_id,
            self.make_session(character_id),
            idle_since=self.now,
            viewer_made=for_viewer,
        )
        self._join_scene(made)
        self.characters[character_id] = made
        return made

    def _join_scene(self, found: Character) -> None:
        """The character's eyes become a scene target; its session sees the scene."""
        self.scene.add_character(found.id)
        if hasattr(found.session, "scene"):
            found.session.scene = self.scene

    # -- submitting -------------------------------------------------------------

    def submit_bml(
        self,
        text: str,
        now: float,
        *,
        character: str | None = None,
        fallback: str | None = None,
        strict: bool = False,
        clock: Callable[[], float] | None = None,
    ) -> SubmitResult:
        """Hand a BML document to its character's session at ``now`` seconds.

        ``clock``: a live clock (the server's). Then the engines first do the
        slow, clock-free part of planning (a TTS synthesis,
        :meth:`realizer.engines.EngineRegistry.prepare`) and the block is timed
        from the clock's reading after that, not from ``now``: a speech that
        takes seconds to synthesise starts when its audio is ready instead of
        in the past. Offline runs (``realizer render``) pass no clock.

        ``strict``: every warning refuses the block (the connection's
        ``/bml?strict=true``; :meth:`realizer.session.Session.receive_bml`).
        Never raises for bad input: refusals come back as a ``warningFeedback``
        and a ``rejected`` :class:`BlockEvent`.
        """
        now = self._advance(now)
        planner = self.planner
        if planner is None:
            return self._submit_bml(text, now, None, character, fallback, strict, clock)
        try:
            with planner.lease() as lease:
                return self._submit_bml(text, now, lease, character, fallback, strict, clock)
        except RealizerError as exc:  # no planner process (the service is stopping)
            target = character or fallback or self.default_character
            warning_type = str(getattr(exc, "warning_type", "CANNOT_CREATE_BEHAVIOR"))
            return self._refuse(target, _guess_block_id(text), now, warning_type, str(exc))

    def _submit_bml(
        self,
        text: str,
        now: float,
        lease: PlanLease | None,
        character: str | None,
        fallback: str | None,
        strict: bool,
        clock: Callable[[], float] | None,
    ) -> SubmitResult:
        """:meth:`submit_bml`, parsing and planning with ``lease`` (a planner
        process) or, None, in this thread."""
        default = fallback or self.default_character
        try:
            if lease is not None:
                parsed = lease.parse(text, self._parse_limits, prepare=clock is not None)
            else:
                parsed = parse_bml(text, limits=self._parse_limits)
        except BmlError as exc:
            block_id = _guess_block_id(text)
            target = character or default
            return self._refuse(target, block_id, now, exc.warning_type, self._describe(exc))
        except RealizerError as exc:  # the planner process: over its budget, or gone
            target = character or default
            warning_type = str(getattr(exc, "warning_type", "CANNOT_CREATE_BEHAVIOR"))
            return self._refuse(target, _guess_block_id(text), now, warning_type, str(exc))
        block = parsed.block
        target = character or block.character_id or default
        try:
            found = self.character(target)
        except PeerError as exc:
            return self._refuse(target, block.id, now, exc.warning_type, exc.message)
        if clock is not None:
            registry = getattr(found.session, "registry", None)
            if registry is not None and lease is None:  # a lease prepared in its parse
                for behaviour in block.behaviours:
                    registry.prepare(behaviour)
            now = self._advance(max(now, clock()))
        with found.submitting:
            with found.lock:
                if self.characters.get(target) is not found:  # freed meanwhile: once more
                    return self._submit_bml(text, now, lease, character, fallback, strict, None)
                now = self._advance(now)
                if not hasattr(found.session, "plan_bml"):  # a stand-in: all at once
                    return self._submit(found, parsed, now, strict)
                refused = self._queue_full(found, parsed.block.id, now)
                if refused is not None:
                    return refused
                try:
                    admitted = found.session.admit_bml(parsed, now, strict=strict)
                except Exception as exc:
                    return self._planning_failed(found, parsed.block.id, now, exc)
                if admitted is None:
                    return self._submitted(found, parsed.block.id, now, None)
            # Planned with the session free: its clock ticks meanwhile.
            try:
                if lease is not None:
                    scene = getattr(found.session, "scene", None)
                    planned = lease.plan(admitted, found.id, scene)
                else:
                    planned = found.session.plan_bml(admitted)
            except Exception as exc:
                with found.lock:
                    return self._planning_failed(found, parsed.block.id, self._advance(now), exc)
            with found.lock:
                now = self._advance(now)
                try:
                    plan = found.session.commit_bml(planned, now)
                except Exception as exc:
                    return self._planning_failed(found, parsed.block.id, now, exc)
                return self._submitted(found, parsed.block.id, now, plan)

    def _queue_full(self, found: Character, block_id: str, now: float) -> SubmitResult | None:
        if len(found.open_blocks) < self.limits.queued_blocks:
            return None
        return self._refuse(
            found.id,
            block_id,
            now,
            LimitExceeded.warning_type,
            f"limit of {self.limits.queued_blocks} queued blocks reached for "
            f"character {found.id!r}; block {block_id!r} refused",
        )

    def _submit(self, found: Character, parsed: Any, now: float, strict: bool) -> SubmitResult:
        """:meth:`submit_bml` with a session that plans in one call
        (``found.lock`` held)."""
        block = parsed.block
        refused = self._queue_full(found, block.id, now)
        if refused is not None:
            return refused
        try:
            plan = found.session.receive_bml(parsed, now, strict=strict)  # parsed once, here
        except Exception as exc:
            return self._planning_failed(found, block.id, now, exc)
        return self._submitted(found, block.id, now, plan)

    def _planning_failed(
        self, found: Character, block_id: str, now: float, exc: Exception
    ) -> SubmitResult:
        """The block is refused: its session raised while planning it
        (``found.lock`` held)."""
        target = found.id
        messages: list[Outgoing] = []
        # The contract says sessions queue warnings and return None; a
        # session that raises is answered the same way, and the block is
        # refused (whatever feedback it made for it is dropped, so no
        # prediction of a block that will not run reaches the client).
        text = (
            str(exc)
            if isinstance(exc, RealizerError)
            else f"internal error while planning block {block_id!r}; the block is refused"
        )
        if not isinstance(exc, RealizerError):
            logger.exception("session of character %r failed on block %r", target, block_id)
        kind = str(getattr(exc, "warning_type", "CANNOT_CREATE_BEHAVIOR"))
        produced = [
            fb for fb in self._take(found) if fb.block_id != block_id or fb.kind == "warning"
        ]
        messages.extend(self._route(found, self._bounded(found.id, block_id, now, produced)))
        messages.extend(self._end_lost_block(found, block_id, now))
        messages.extend(self._warning(target, block_id, now, kind, text))
        messages.append(BlockEvent(target, block_id, "rejected", now))
        return SubmitResult(target, block_id, False, tuple(messages))

    def _submitted(self, found: Character, block_id: str, now: float, plan: Any) -> SubmitResult:
        """What the session said about a block it planned (``plan``) or
        refused (None), as messages (``found.lock`` held)."""
        target = found.id
        # Acceptance is this call's own outcome: a plan came back. Feedback
        # of an older block with the same id (its start or end in this very
        # call) says nothing about the new one.
        accepted = plan is not None
        produced = self._take(found)
        messages = self._route(
            found,
            self._bounded(found.id, block_id, now, produced),
            admit=block_id if accepted else None,
            now=now,
            plan_end=getattr(plan, "end", None),
        )
        if not accepted:
            messages.append(BlockEvent(target, block_id, "rejected", now))
        return SubmitResult(target, block_id, accepted, tuple(messages))

    def place_target(
        self, name: str, position: tuple[float, float, float], now: float
    ) -> tuple[Outgoing, ...]:
        """Add or move a scene target at ``now``; behaviours aimed at it follow.

        A bad name or position is answered with a ``warningFeedback``.
        """
        now = self._advance(now)
        try:
            self.scene.place(name, position)
        except SceneError as exc:
            return tuple(self._warning(self.default_character, "", now, exc.warning_type,
                                       str(exc.args[0])))  # fmt: skip
        messages: list[Outgoing] = []
        for found in self.characters.values():
            moved = getattr(found.session, "target_moved", None)
            if moved is not None:
                moved(name, now)
                messages.extend(self._route(found, self._take(found)))
        return tuple(messages)

    def interrupt(self, character_id: str, block_id: str, now: float) -> tuple[Outgoing, ...]:
        """Interrupt ``block_id`` of ``character_id`` at ``now`` seconds."""
        now = self._advance(now)
        found = self.characters.get(character_id)
        if found is None:
            return tuple(
                self._warning(
                    character_id, block_id, now, "NO_SUCH_TARGET", f"no character {character_id!r}"
                )
            )
        with found.submitting, found.lock:
            return self._interrupt(found, block_id, self._advance(now))

    def _interrupt(self, found: Character, block_id: str, now: float) -> tuple[Outgoing, ...]:
        character_id = found.id
        if block_id in found.open_blocks:
            found.interrupting.add(block_id)
        messages: list[Outgoing] = []
        try:
            found.session.interrupt(block_id, now)
        except RealizerError as exc:
            messages.extend(self._warning(character_id, block_id, now, "NO_SUCH_TARGET", str(exc)))
        except Exception:
            logger.exception("session of character %r failed interrupting %r", found.id, block_id)
        messages.extend(self._route(found, self._take(found)))
        if block_id in found.open_blocks:
            # an interrupted block ends now or soon; if its session never
            # ends it, the stage fails it at this deadline
            found.deadlines[block_id] = min(
                found.deadlines.get(block_id, float("inf")), now + END_GRACE_SECONDS
            )
        return tuple(messages)

    def interrupt_all(self, now: float) -> tuple[Outgoing, ...]:
        """Interrupt every open block of every character (at shutdown)."""
        messages: list[Outgoing] = []
        for found in list(self.characters.values()):
            for block_id in list(found.open_blocks):
                messages.extend(self.interrupt(found.id, block_id, now))
        return tuple(messages)

    # -- the clock --------------------------------------------------------------

    def tick(self, now: float, only: Iterable[str] | None = None) -> list[CharacterTick]:
        """Advance every session (``only``: those of these character ids) to
        ``now`` seconds; one entry per character ticked.

        A character whose lock a submission holds at that moment is not
        waited for: it is left out, and :attr:`busy` names it afterwards (the
        characters the last call left out), so the caller may try it again
        a little later in the same frame (the server's clock does).
        """
        now = self._advance(now)
        ticks: list[CharacterTick] = []
        busy: list[str] = []
        if only is None:
            chosen = list(self.characters.values())
        else:
            chosen = [c for c in map(self.characters.get, only) if c is not None]
        for found in chosen:
            # The clock never waits for a submitter: a block is planned with
            # its character's lock free (Session.plan_bml), so the lock is
            # held only briefly (a block admitted or committed, an
            # interrupt); a character caught in that moment is left out of
            # this call.
            if not found.lock.acquire(blocking=False):
                self.skipped_ticks += 1
                busy.append(found.id)
                continue
            try:
                tick = self._tick_character(found, now)
            finally:
                found.lock.release()
            if tick is not None:
                ticks.append(tick)
        self.busy = busy
        return ticks

    def _tick_character(self, found: Character, now: float) -> CharacterTick | None:
        """One character's tick (``found.lock`` held)."""
        try:
            found.session.tick(now)
            messages = self._route(found, found.session.take_feedback())
            frame = found.session.frame(now)
        except Exception:
            # A failing session must not take every other character down
            # with it: skip its frame this tick, say so in the log, fail
            # its open blocks (each accepted block ends) and give the
            # character a fresh session, so it accepts blocks again.
            logger.exception("session of character %r failed at %.3f s", found.id, now)
            lost = [
                *self._route(found, self._take(found)),
                *self._fail_all(found, now, "the character's session failed"),
            ]
            found.session = self.make_session(found.id)
            self._join_scene(found)
            try:
                fresh = found.session.frame(now)
            except Exception:
                return None
            return CharacterTick(found.id, now, fresh, tuple(lost))
        overdue = [b for b, deadline in found.deadlines.items() if deadline < now]
        for block_id in overdue:
            messages.extend(self._fail(found, block_id, now, "the block did not end in time"))
        return CharacterTick(found.id, now, frame, tuple(messages))

    def forget_idle(self, now: float, idle_seconds: float, keep: Iterable[str] = ()) -> list[str]:
        """Free characters that have had no open block for ``idle_seconds``.

        ``keep`` names characters something still uses (a viewer, a
        submitter that named it); returns the ids freed. The default
        character is never freed.
        """
        kept = set(keep)
        kept.add(self.default_character)
        freed: list[str] = []
        with self._table:
            for found in list(self.characters.values()):
                if (
                    found.id in kept
                    or found.open_blocks
                    or found.idle_since is None
                    or now - found.idle_since < idle_seconds
                    or not found.submitting.acquire(blocking=False)  # being planned
                ):
                    continue
                try:
                    del self.characters[found.id]
                    freed.append(found.id)
                finally:
                    found.submitting.release()
        return freed

    # -- helpers ----------------------------------------------------------------

    @staticmethod
    def _take(found: Character) -> list[Feedback]:
        try:
            return list(found.session.take_feedback())
        except Exception:
            logger.exception("session of character %r failed giving feedback", found.id)
            return []

    def _route(
        self,
        found: Character,
        produced: Iterable[Feedback],
        *,
        admit: str | None = None,
        now: float = 0.0,
        plan_end: float | None = None,
    ) -> list[Outgoing]:
        """Feedback as wire messages, with the block events it implies.

        ``admit``: the id of a block this call accepted. It is opened at its
        prediction (so an end later in the same call, a zero-length block,
        is its ``done``, and an end of an older block of that id before it
        is not), and ``accepted`` follows the prediction.
        """
        messages: list[Outgoing] = []
        for fb in produced:
            messages.append(WireFeedback(found.id, fb.kind, fb.block_id, fb.time, fb.xml))
            if admit is not None and fb.block_id == admit and fb.kind == "prediction":
                self._open(found, admit, now, plan_end)
                messages.append(BlockEvent(found.id, admit, "accepted", now))
                admit = None
                self._predicted(found, fb, now)
                continue
            if fb.kind == "prediction" and fb.block_id in found.open_blocks:
                self._predicted(found, fb, now)  # planned again (a BMLA activation)
            if _is_block_end(fb) and fb.block_id in found.open_blocks:
                del found.open_blocks[fb.block_id]
                found.deadlines.pop(fb.block_id, None)
                if not found.open_blocks:
                    found.idle_since = fb.time
                # interrupted by us, or by the session (a REPLACE block)
                interrupted = fb.block_id in found.interrupting or _INTERRUPTED.search(fb.xml)
                state: BlockState = "interrupted" if interrupted else "done"
                found.interrupting.discard(fb.block_id)
                messages.append(BlockEvent(found.id, fb.block_id, state, fb.time))
        if admit is not None:  # accepted with no prediction (a session that makes none)
            self._open(found, admit, now, plan_end)
            messages.append(BlockEvent(found.id, admit, "accepted", now))
        return messages

    def _predicted(self, found: Character, fb: Feedback, now: float) -> None:
        """A block's deadline follows its latest prediction; a BMLA preplanned
        block (``bmla:status="PENDING"``) waits for its activation, without one."""
        if _PENDING.search(fb.xml):
            found.deadlines.pop(fb.block_id, None)
            return
        match = _GLOBAL_END.search(fb.xml)
        try:
            end = float(match.group(1)) if match is not None else math.nan
        except ValueError:
            end = math.nan
        if end == end:
            found.deadlines[fb.block_id] = max(now, end) + END_GRACE_SECONDS

    def _open(self, found: Character, block_id: str, now: float, plan_end: float | None) -> None:
        found.open_blocks[block_id] = now
        found.idle_since = None
        if plan_end is not None and plan_end == plan_end:  # not nan
            found.deadlines[block_id] = max(now, float(plan_end)) + END_GRACE_SECONDS

    def _fail(self, found: Character, block_id: str, now: float, why: str) -> list[Outgoing]:
        """End an open block as ``failed``, with a warning, and stop what it animates."""
        if block_id not in found.open_blocks:
            return []
        del found.open_blocks[block_id]
        found.deadlines.pop(block_id, None)
        found.interrupting.discard(block_id)
        if not found.open_blocks:
            found.idle_since = now
        messages: list[Outgoing] = [
            *self._warning(
                found.id, block_id, now, "CANNOT_CREATE_BEHAVIOR", f"block {block_id!r}: {why}"
            ),
            BlockEvent(found.id, block_id, "failed", now),
        ]
        messages.extend(self._end_lost_block(found, block_id, now))
        return messages

    def _fail_all(self, found: Character, now: float, why: str) -> list[Outgoing]:
        messages: list[Outgoing] = []
        for block_id in list(found.open_blocks):
            if block_id in found.open_blocks:
                messages.extend(self._fail(found, block_id, now, why))
        return messages

    def _end_lost_block(self, found: Character, block_id: str, now: float) -> list[Outgoing]:
        """Ask the session to stop a block the stage no longer counts (best
        effort); the session's feedback about that block is dropped (the
        client was told it failed or was rejected), the rest is routed."""
        try:
            found.session.interrupt(block_id, now)
        except Exception:
            logger.debug("could not interrupt lost block %r of %r", block_id, found.id)
        return self._route(found, [fb for fb in self._take(found) if fb.block_id != block_id])

    def _bounded(
        self, character: str, block_id: str, now: float, produced: list[Feedback]
    ) -> list[Feedback]:
        """At most ``limits.warnings_per_block`` warnings about ``block_id``;
        the rest are counted in one last warning."""
        limit = self.limits.warnings_per_block
        count = sum(1 for fb in produced if fb.kind == "warning" and fb.block_id == block_id)
        if count <= limit:
            return produced
        kept: list[Feedback] = []
        seen = 0
        for fb in produced:
            if fb.kind == "warning" and fb.block_id == block_id:
                seen += 1
                if seen >= limit:
                    continue
            kept.append(fb)
        more = count - limit + 1
        xml = warning_feedback_xml(
            block_id,
            character,
            "PARSING_FAILURE",
            f"{more} more warnings about block {block_id!r} are not listed "
            f"(limit of {limit} warnings per block)",
        )
        summary = Feedback("warning", block_id, now, xml)
        last_warning = max(
            i for i, fb in enumerate(kept) if fb.kind == "warning" and fb.block_id == block_id
        )
        kept.insert(last_warning + 1, summary)
        return kept

    def _warning(
        self, character: str, block_id: str, now: float, warning_type: str, text: str
    ) -> list[Outgoing]:
        xml = warning_feedback_xml(block_id, character, warning_type, text)
        return [WireFeedback(character, "warning", block_id, now, xml)]

    def _refuse(
        self, character: str, block_id: str, now: float, warning_type: str, text: str
    ) -> SubmitResult:
        messages = [
            *self._warning(character, block_id, now, warning_type, text),
            BlockEvent(character, block_id, "rejected", now),
        ]
        return SubmitResult(character, block_id, False, tuple(messages))

    @staticmethod
    def _describe(exc: BmlError) -> str:
        where = f"line {exc.line}, column {exc.column}: " if exc.line else ""
        return f"{where}{exc.message}"


def _NO_ARKIT(vector: npt.NDArray[np.float64]) -> bytes:
    """The ARKit encoder of a face the targets do not fit (never called)."""
    raise AssertionError("no ARKit stream for this face")


class FrameEncoder:
    """msgpack bytes of one character's frames, per kind of viewer.

    ARKit viewers get no frame until their face's ARKit fit is set up, off
    the clock (:meth:`_arkit_ready`): the result of :meth:`encode` then has
    no entry for their options.

    ``face`` gives the neutral pose and triangles; ``deform(face, vector)``
    the (n, 3) vertices for a (68,) FAP vector. The face is deformed only
    when some viewer wants vertices and the FAPs changed since the last
    deformation.
    """

    def __init__(
        self,
        character_id: str,
        face: Face,
        deform: Deformer,
        fps: float,
        colours: npt.NDArray[np.uint8] | None = None,
    ) -> None:
        self.character_id = character_id
        self.face = face
        self.deform = deform
        self.neutral = np.asarray(face.vertices, dtype=np.float64)
        self.mesh_bytes = codec.pack(
            codec.mesh_message(character_id, self.neutral, face.faces, colours, fps)
        )
        self._vector: npt.NDArray[np.float64] | None = None
        self._vertices32: bytes | None = None
        self._delta: DeltaPayload | None = None
        self._model_bytes: bytes | None = None
        self.fps = fps
        self.fap_quant = DEFAULT_FAP_QUANT
        self._coder: FapStreamEncoder | None = None
        self._coded_number: int | None = None  # the frame the coder last coded
        self._arkit: Callable[[npt.NDArray[np.float64]], bytes] | None = None
        self.deformations = 0  # how many times the face was deformed (for tests)
        # The content of the last frame observed and its version, which
        # changes whenever the content does (see observe).
        self._shown: tuple[npt.NDArray[np.bool_], npt.NDArray[np.float64]] | None = None
        self.version = 0

    @property
    def model_bytes(self) -> bytes:
        """The ``model`` message (protocols/viewer.md): the face's deformation
        model as data, for viewers that deform the face themselves. Built on
        first use (a few hundred kB for the default face), then cached."""
        if self._model_bytes is None:
            from realizer.face.gpu_model import gpu_model_for, model_message_fields

            fields = model_message_fields(gpu_model_for(self.face))
            self._model_bytes = codec.pack(codec.model_message(self.character_id, fields))
        return self._model_bytes

    def observe(self, frame: FapFrame) -> int:
        """The version of ``frame``'s content: the previous frame's when it shows
        exactly the same FAPs (set and values), else a new one. A viewer that
        already has this version is sent a ``same`` message instead."""
        mask = np.asarray(frame.mask, dtype=bool)
        values = np.where(mask, np.asarray(frame.values, dtype=np.float64), 0.0)
        shown = self._shown
        if shown is None or not (
            np.array_equal(mask, shown[0]) and np.array_equal(values, shown[1])
        ):
            self._shown = (mask, values)
            self.version += 1
        return self.version

    def encode(
        self, number: int, time: float, frame: FapFrame, wanted: Iterable[ViewOptions]
    ) -> dict[ViewOptions, bytes]:
        """One frame's bytes for each distinct :class:`ViewOptions` wanted."""
        wanted = set(wanted)
        if not wanted:
            return {}
        mask = np.asarray(frame.mask, dtype=bool)
        values = np.asarray(frame.values, dtype=np.float64)
        fap = codec.fap_payload(values, mask)
        if any(options.vertices != "none" for options in wanted):
            self._update_vertices(np.where(mask, values, 0.0))
        coded = self._code(number, values, mask) if any(o.coded for o in wanted) else None
        arkit = None
        if any(o.arkit for o in wanted):
            encode_arkit = self._arkit_ready()
            if encode_arkit is None:  # the fit is being set up: those viewers wait
                wanted = {o for o in wanted if not o.arkit}
            elif encode_arkit is not _NO_ARKIT:
                arkit = encode_arkit(np.where(mask, values, 0.0))
        return {
            options: codec.pack(
                codec.frame_message(
                    self.character_id,
                    number,
                    time,
                    options,
                    fap=fap,
                    vertices=self._vertices32,
                    delta=self._delta,
                    coded=coded,
                    arkit=arkit,
                )
            )
            for options in wanted
        }

    def _arkit_ready(self) -> Callable[[npt.NDArray[np.float64]], bytes] | None:
        """This face's ARKit encoder, or None while its fit is set up in a
        background thread (realizer.face.arkit.prepare_arkit; tens of ms the
        clock must not wait for); :data:`_NO_ARKIT` for a face the ARKit
        targets do not fit (its frames then carry no ``arkit`` field)."""
        if self._arkit is None:
            from realizer.face.arkit import arkit_encoder, prepare_arkit

            basis = prepare_arkit(self.face)
            if not basis.done():
                return None
            if basis.exception() is not None:
                logger.warning("no ARKit stream for this face: %s", basis.exception())
                self._arkit = _NO_ARKIT
            else:
                self._arkit = arkit_encoder(self.face, basis.result())
        return self._arkit

    def want_intra(self) -> None:
        """Make the next coded frame an intra frame (a coded viewer joined)."""
        self._coded_number = None

    def _code(
        self, number: int, values: npt.NDArray[np.float64], mask: npt.NDArray[np.bool_]
    ) -> tuple[bytes, int | None]:
        """This tick's coded FAP frame and the frame it predicts from (None:
        intra). A coder that did not code the previous tick (no coded viewer
        then, or nothing was sent) starts again with an intra frame, and so
        does one asked to by :meth:`want_intra`."""
        if self._coder is None or self._coded_number is None or number != self._coded_number + 1:
            interval = max(1, round(self.fps * CODED_INTRA_SECONDS))
            self._coder = FapStreamEncoder(self.fap_quant, interval)
            self._coded_number = None
        frame = self._coder.encode(values, mask)
        ref = None if is_intra(frame) else self._coded_number
        self._coded_number = number
        return frame, ref

    def _update_vertices(self, vector: npt.NDArray[np.float64]) -> None:
        if self._vector is not None and np.array_equal(vector, self._vector):
            return
        vertices = np.asarray(self.deform(self.face, vector), dtype=np.float64)
        self.deformations += 1
        self._vector = vector
        self._vertices32 = np.ascontiguousarray(vertices, dtype="<f4").tobytes()
        self._delta = codec.delta_payload(vertices, self.neutral)
