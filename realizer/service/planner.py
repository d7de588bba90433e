"""Planner processes: parse and plan BML off the event loop's interpreter.

The clock never waits for a submitter (docs/service.md, "Guarantees under
hostile input"). Planner *threads* share the interpreter lock with the
event loop, so a heavy message still takes CPU time from the clock; a
:class:`PlannerPool` runs the two heavy steps of a submission in child
processes instead, so that a submitter's CPU is another process's:

* **parse** (:meth:`PlannerLease.parse`): the BML text is parsed (with the
  service's parse limits) and each behaviour's slow, clock-free work done
  (:meth:`realizer.engines.EngineRegistry.prepare`: a TTS synthesis);
  the parse result comes back to the service, which routes the block and
  admits it (:meth:`realizer.session.Session.admit_bml`, in order per
  character, on the service's side);
* **plan** (:meth:`PlannerLease.plan`): the admitted block is scheduled
  and realized (:meth:`realizer.session.Session.plan_bml`, a pure function
  of the block, its start, the sync times of the earlier blocks it names,
  the behaviours holding resource channels, the scene, and the engines);
  the plan, prediction, animations and audio come back, picklable, and the
  service's session commits them.

A lease holds one child for one submission (both steps, so the synthesis
of ``prepare`` is reused by ``plan``). Each child builds its engines once,
from a picklable :class:`PlanningRecipe`; children are forked from
multiprocessing's fork server, which has imported the planner's modules and
planned a warm-up block (``_planner_warm``), so a child starts in
milliseconds and plans its first block at full speed.

**A time budget per message.** The child time of one submission (its two
steps together) is bounded by ``ServiceLimits.planning_milliseconds``: a
message over it is refused (:class:`PlanningOverBudget`, a
``warningFeedback`` naming the limit), the child is killed and a fresh one
takes its place, so a pathological message costs one budget and never a
stuck planner. A child that dies (killed, out of memory) fails the
submission the same way (:class:`PlannerFailed`).

Between the processes go pickles; the parse result the child made is
referred to, not copied, in both directions (the block and its behaviours
are pickled as references to the copy each side holds), so a plan comes
back as a few hundred bytes per behaviour and its behaviours are the
service's own objects.
"""

from __future__ import annotations

import contextlib
import copy
import io
import logging
import multiprocessing
import os
import pickle
import queue
import signal
import threading
import time
import traceback
from collections.abc import Iterator
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from typing import Any

from realizer.bml_parser import BmlError, Limits, ParseResult, parse_bml
from realizer.service.errors import LimitExceeded, ServiceError

logger = logging.getLogger("realizer.service")

#: The module the fork server imports (and whose warm-up it runs) before it
#: forks any child.
PRELOAD = "realizer.service._planner_warm"

#: Seconds a child may take to start and say it is ready.
START_SECONDS = 30.0

#: Seconds a child is given to exit when the pool closes, before it is killed.
CLOSE_SECONDS = 1.0

#: Behaviour types whose planning reads the scene (realizer.session.SCENE_TYPES).
_SCENE_TYPES = frozenset({"gaze", "gazeShift", "pointing", "headDirectionShift"})


class PlanningOverBudget(LimitExceeded):
    """A message took its planner process longer than ``planning_milliseconds``."""


class PlannerFailed(ServiceError):
    """A planner process died or could not answer; the submission is refused."""

    warning_type = "CANNOT_CREATE_BEHAVIOR"


@dataclass(frozen=True, slots=True)
class PlanningRecipe:
    """How a planner process builds its engines (picklable): the speech
    options of :func:`realizer.service.assets.session_factory` (empty: the
    standard registry)."""

    speech: tuple[tuple[str, str], ...] = ()

    def registry(self) -> Any:
        """The engines, built as the service's sessions build theirs."""
        from realizer.engines import EngineRegistry

        if not self.speech:
            return EngineRegistry.standard()
        from realizer.engines.face import FaceEngine
        from realizer.engines.speech import SpeechEngine

        options = dict(self.speech)
        backend = options.pop("tts", "") or "espeak"
        options = {k: v for k, v in options.items() if v}
        return EngineRegistry([FaceEngine.default(), SpeechEngine.default(backend, **options)])


# -- pickles that refer to the parse result both sides hold ----------------------------


def _shared(parsed: ParseResult | None) -> list[Any]:
    """The objects both sides hold, in the same order: the parse result, its
    block and the block's behaviours."""
    if parsed is None:
        return []
    return [parsed, parsed.block, *parsed.block.behaviours]


def _dumps(value: Any, shared: list[Any]) -> bytes:
    index = {id(obj): n for n, obj in enumerate(shared)}
    buffer = io.BytesIO()
    pickler = pickle.Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL)
    if index:
        pickler.persistent_id = lambda obj: index.get(id(obj))  # type: ignore[method-assign]
    pickler.dump(value)
    return buffer.getvalue()


def _loads(data: bytes, shared: list[Any]) -> Any:
    unpickler = pickle.Unpickler(io.BytesIO(data))
    unpickler.persistent_load = shared.__getitem__  # type: ignore[method-assign]
    return unpickler.load()


# -- the child ----------------------------------------------------------------------


class _ChildPlanner:
    """A child's state: its engines (one planning session) and the parse
    result of the submission it serves."""

    def __init__(self, recipe: PlanningRecipe) -> None:
        from realizer.session import Session

        self.session = Session("", None, registry=recipe.registry())
        self.parsed: ParseResult | None = None

    def handle(self, request: tuple[Any, ...]) -> tuple[str, Any]:
        op = request[0]
        if op == "parse":
            _, text, limits, prepare = request
            self.parsed = None
            try:
                parsed = parse_bml(text, limits=limits)
            except BmlError as exc:
                return "bml-error", exc
            if prepare:
                for behaviour in parsed.block.behaviours:
                    self.session.registry.prepare(behaviour)
            self.parsed = parsed
            return "parsed", parsed
        if op == "plan":
            _, admitted, character_id, scene = request
            session = self.session
            session.character_id = character_id
            session.scene = scene
            planned = session.plan_bml(admitted)
            return "planned", (
                planned.notes,
                planned.plan,
                planned.predicted,
                planned.events,
                planned.animations,
                planned.audio,
                planned.owned,
                planned.engine_notes,
            )
        raise ValueError(f"unknown planner request {op!r}")


def _child_main(conn: Connection, recipe: PlanningRecipe, nice: int = 0) -> None:
    """A planner process: answer requests until the pipe closes."""
    # The service's SIGINT and SIGTERM are the service's to handle: a child
    # ends when its pipe closes (or is killed), never halfway on a signal.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if nice:
        with contextlib.suppress(OSError):
            os.nice(nice)
    try:
        planner = _ChildPlanner(recipe)
    except Exception:
        conn.send_bytes(pickle.dumps(("error", traceback.format_exc())))
        return
    conn.send_bytes(pickle.dumps(("ready", os.getpid())))
    while True:
        try:
            data = conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            request = _loads(data, _shared(planner.parsed))
            kind, value = planner.handle(request)
            # a parse result goes back whole (the service has none yet)
            reply = _dumps((kind, value), [] if kind == "parsed" else _shared(planner.parsed))
        except Exception:
            reply = pickle.dumps(("error", traceback.format_exc()))
        try:
            conn.send_bytes(reply)
        except (EOFError, OSError):
            return


#: How much lower than the service a planner process runs (os.nice): when
#: both compete for a core, the frame clock's process wins it.
NICE = 5


# -- the service's side -------------------------------------------------------------


class _Child:
    """One planner process and the service's end of its pipe."""

    def __init__(self, context: Any, recipe: PlanningRecipe, nice: int = NICE) -> None:
        ours, theirs = context.Pipe(duplex=True)
        self.process = context.Process(
            target=_child_main,
            args=(theirs, recipe, nice),
            name="realizer-planner",
            daemon=True,
        )
        self.process.start()
        theirs.close()
        self.conn: Connection = ours
        self.broken = False
        self.pid: int = self.process.pid or 0

    def wait_ready(self) -> _Child:
        """Wait until the child has built its engines (children start in parallel)."""
        try:
            started = self.conn.poll(START_SECONDS)
            kind, value = pickle.loads(self.conn.recv_bytes()) if started else ("late", "")
        except (OSError, EOFError) as exc:
            self.kill()
            raise PlannerFailed("a planner process died while starting") from exc
        if kind != "ready":
            self.kill()
            raise PlannerFailed(f"a planner process could not start ({kind}):\n{value}")
        return self

    def call(self, request: tuple[Any, ...], shared: list[Any], timeout: float) -> Any:
        """Send ``request``, wait at most ``timeout`` seconds for the answer.

        Raises :class:`PlanningOverBudget` (the child is killed) or
        :class:`PlannerFailed`.
        """
        try:
            self.conn.send_bytes(_dumps(request, shared))
            answered = self.conn.poll(max(0.0, timeout))
        except (OSError, EOFError) as exc:
            self.kill()
            raise PlannerFailed("the planner process is gone") from exc
        if not answered:
            self.kill()
            raise PlanningOverBudget("over the planning budget")
        try:
            data = self.conn.recv_bytes()
        except (OSError, EOFError) as exc:
            self.kill()
            raise PlannerFailed("the planner process died while planning") from exc
        kind, value = _loads(data, shared)
        if kind == "error":
            logger.error("planner process %d failed:\n%s", self.pid, value)
            raise PlannerFailed("internal error in the planner process")
        return kind, value

    def alive(self) -> bool:
        return not self.broken and bool(self.process.is_alive())

    def kill(self) -> None:
        self.broken = True
        with contextlib.suppress(Exception):
            self.process.kill()
        with contextlib.suppress(Exception):
            self.conn.close()
        with contextlib.suppress(Exception):
            self.process.join(CLOSE_SECONDS)

    def close(self) -> None:
        """Ask the child to exit (its pipe closes), then make sure it did."""
        self.broken = True
        with contextlib.suppress(Exception):
            self.conn.close()
        with contextlib.suppress(Exception):
            self.process.join(CLOSE_SECONDS)
        if self.process.is_alive():
            self.kill()


class PlannerLease:
    """One child, held for one submission (see the module docstring).

    ``budget`` seconds of child time for the whole submission; each call
    gets what is left of it.
    """

    def __init__(self, child: _Child, budget: float, budget_ms: int) -> None:
        self.child = child
        self.left = budget
        self.budget_ms = budget_ms
        self.parsed: ParseResult | None = None
        self.calls = 0

    def _call(self, request: tuple[Any, ...], what: str) -> tuple[str, Any]:
        began = time.monotonic()
        try:
            return self.child.call(request, _shared(self.parsed), self.left)  # type: ignore[no-any-return]
        except PlanningOverBudget:
            raise PlanningOverBudget(
                f"{what} took more than the limit of {self.budget_ms} ms of planning "
                "per message (planning_milliseconds); it is refused"
            ) from None
        finally:
            self.calls += 1
            self.left -= time.monotonic() - began

    def parse(self, text: str, limits: Limits, *, prepare: bool) -> ParseResult:
        """The parse result of ``text`` (raises :class:`BmlError` as
        :func:`realizer.bml_parser.parse_bml` does); ``prepare``: also do the
        engines' clock-free work for each behaviour (a TTS synthesis)."""
        self.parsed = None
        kind, value = self._call(("parse", text, limits, prepare), "parsing the message")
        if kind == "bml-error":
            raise value
        self.parsed = value
        return value  # type: ignore[no-any-return]

    def plan(self, admitted: Any, character_id: str, scene: Any) -> Any:
        """:meth:`realizer.session.Session.plan_bml` of ``admitted`` (whose
        parse result this lease's :meth:`parse` made) in the child, as a
        :class:`realizer.session.PlannedBlock` of the service's objects."""
        from realizer.session import PlannedBlock

        if self.parsed is None or admitted.result is not self.parsed:
            raise PlannerFailed("a block is planned by the lease that parsed it")
        block = admitted.result.block
        needs_scene = scene is not None and any(b.type in _SCENE_TYPES for b in block.behaviours)
        sent = replace(admitted, earlier=(), external=admitted.external_times())
        _, value = self._call(
            ("plan", sent, character_id, _snapshot(scene) if needs_scene else None),
            f"planning block {block.id!r}",
        )
        notes, plan, predicted, events, animations, audio, owned, engine_notes = value
        return PlannedBlock(
            admitted, notes, plan, predicted, events, animations, audio, owned, engine_notes
        )


def _snapshot(scene: Any) -> Any:
    """A copy of the scene to send: another thread may place a target while
    it is copied (a dict changing size), so the copy is tried again."""
    for _ in range(4):
        try:
            return copy.deepcopy(scene)
        except RuntimeError:
            continue
    return copy.deepcopy(scene)


class PlannerPool:
    """``processes`` planner processes (see the module docstring).

    :meth:`lease` waits for a free child; :meth:`close` ends them all. Thread
    safe: the service's planner threads lease children concurrently.
    """

    def __init__(
        self,
        processes: int,
        recipe: PlanningRecipe,
        budget_ms: int,
        *,
        start_method: str = "forkserver",
        nice: int = NICE,
    ) -> None:
        if processes < 1:
            raise ValueError(f"a planner pool needs at least one process, not {processes}")
        self.recipe = recipe
        self.nice = nice  # added to the children's niceness (os.nice)
        self.budget_ms = budget_ms
        self.processes = processes
        self._context = multiprocessing.get_context(start_method)
        if start_method == "forkserver":
            # "__main__": a program run as a script is imported once, by the
            # fork server, instead of again by every child (as multiprocessing
            # does; a program run with -m is not imported again at all).
            self._context.set_forkserver_preload(["__main__", PRELOAD])
        self._idle: queue.SimpleQueue[_Child | None] = queue.SimpleQueue()
        self._children: set[_Child] = set()
        self._lock = threading.Lock()
        self._closed = False
        self.replaced = 0  # children killed over their budget or found dead
        began = time.perf_counter()
        children = [self._start() for _ in range(processes)]
        try:
            for child in children:
                self._idle.put(child.wait_ready())
        except PlannerFailed:
            self.close()
            raise
        #: seconds the pool took to start its children (the fork server too,
        #: the first time in a process)
        self.start_seconds = time.perf_counter() - began

    def _start(self) -> _Child:
        child = _Child(self._context, self.recipe, self.nice)
        with self._lock:
            self._children.add(child)
        return child

    def pids(self) -> list[int]:
        """The process ids of the live children (for tests and /health)."""
        with self._lock:
            return sorted(c.pid for c in self._children if c.alive())

    @contextlib.contextmanager
    def lease(self) -> Iterator[PlannerLease]:
        """A child for one submission; a child broken meanwhile is replaced."""
        child = self._idle.get()
        if child is None or self._closed:
            self._idle.put(None)  # wake the next waiter too
            raise PlannerFailed("the planner is shut down")
        try:
            if not child.alive():
                child = self._replace(child)
            yield PlannerLease(child, self.budget_ms / 1000.0, self.budget_ms)
        finally:
            if child.broken and not self._closed:
                try:
                    child = self._replace(child)
                except PlannerFailed:
                    logger.exception("could not start a planner process")
                    self._idle.put(child)  # broken: the next lease tries again
                else:
                    self._idle.put(child)
            elif self._closed:
                child.close()
            else:
                self._idle.put(child)

    def _replace(self, child: _Child) -> _Child:
        child.kill()
        with self._lock:
            self._children.discard(child)
            self.replaced += 1
        return self._start().wait_ready()

    def close(self) -> None:
        """End every child (those in a lease end when it is over): their
        pipes close, so they exit; any still there after
        :data:`CLOSE_SECONDS` is killed."""
        self._closed = True
        with self._lock:
            children = list(self._children)
        for child in children:
            child.broken = True
            with contextlib.suppress(Exception):
                child.conn.close()
        for child in children:
            child.close()
        self._idle.put(None)
