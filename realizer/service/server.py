"""The asyncio layer: WebSocket endpoints, plain HTTP, the frame clock.

A thin shell around :class:`realizer.service.stage.Stage` (the sans-I/O
core), in the manner of websockets' ``asyncio`` sub-package: it reads
messages, passes them with the time of arrival to the stage, and sends what
the stage returns. One port serves

* ``/bml``   submitters: BML in, BML feedback out (protocols/submitter.md);
* ``/view``  viewers: mesh, then msgpack frames (protocols/viewer.md);
* ``/``      the browser viewer; ``/health`` and ``/version`` as JSON.

Why a remotely controllable face with its own clock (Paul 2010, section 4.2):
the thesis drove Xface over TCP and lost frames sent quickly one after the
other, so its frames went out once per 250 ms. Here the server owns the
clock: frame n is computed at ``start + n / fps`` (never by adding periods,
so it cannot drift), every session advances once per tick, and each viewer
has a mailbox of one frame that a newer frame replaces. A viewer that reads
slowly gets fewer, complete frames; it never delays the clock or any other
viewer, and what the server holds for it stays bounded.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import hmac
import http
import ipaddress
import json
import logging
import selectors
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from importlib import resources
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, cast
from urllib.parse import parse_qs, urlsplit

import numpy as np
import numpy.typing as npt
from websockets.asyncio.server import Server, ServerConnection
from websockets.asyncio.server import serve as websocket_serve
from websockets.datastructures import Headers, MultipleValuesError
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.protocol import State

from realizer import __version__
from realizer.face.model import Face
from realizer.scheduler import solver
from realizer.service import codec
from realizer.service.audio import AUDIO_VALUES, AudioStream, backlog_limit
from realizer.service.errors import BadMessage, CloseCode, ConfigError, PeerError
from realizer.service.limits import DEFAULT_LIMITS, ServiceLimits, valid_character_id
from realizer.service.logs import log_block
from realizer.service.messages import (
    PROTOCOL_VERSION,
    BlockMessage,
    FeedbackFormat,
    FeedbackMessage,
    ViewOptions,
    WelcomeMessage,
    read_submitter_message,
    read_subscribe_message,
    warning_feedback_xml,
)
from realizer.service.stage import (
    CODED_INTRA_SECONDS,
    BlockEvent,
    CharacterTick,
    Deformer,
    FrameEncoder,
    Outgoing,
    Stage,
    WireFeedback,
)

if TYPE_CHECKING:
    from realizer.service.planner import PlannerPool

logger = logging.getLogger("realizer.service")

#: Bytes a connection's socket buffer may hold before sending waits (and a
#: viewer's frames go to its one-frame mailbox instead): about a dozen
#: vertex frames of the default face.
WRITE_LIMIT = 256 * 1024

#: Seconds a thread waiting for the GIL waits at most while the service runs.
SWITCH_INTERVAL = 0.001

SUBMIT_PATH = "/bml"
VIEW_PATH = "/view"


@dataclass(frozen=True, slots=True)
class ServiceConfig:
    """How to run the service. ``port`` 0 picks a free port; ``fps`` is the
    clock's rate in frames per second; ``shutdown_timeout`` bounds, in
    seconds, each waiting step of the shutdown sequence."""

    host: str = "127.0.0.1"
    port: int = 8765
    fps: float = 60.0
    submit_token: str | None = None
    view_token: str | None = None
    limits: ServiceLimits = DEFAULT_LIMITS
    shutdown_timeout: float = 2.0
    #: threads that handle submitted messages off the event loop (each waits
    #: for a planner process, or, with none, parses and plans itself)
    planner_threads: int = 4
    #: processes that parse and plan submitted blocks (realizer.service.planner),
    #: so a submitter's CPU is never the clock's; 0 (the default: measured
    #: better on 2 cores, docs/service.md): the planner threads parse and
    #: plan in the service's own process (sharing its interpreter lock)
    planner_processes: int = 0

    def __post_init__(self) -> None:
        if not 1 <= self.planner_threads <= 64:
            raise ConfigError(f"planner_threads must be 1 to 64, not {self.planner_threads}")
        if not 0 <= self.planner_processes <= 64:
            raise ConfigError(f"planner_processes must be 0 to 64, not {self.planner_processes}")
        if not 1.0 <= self.fps <= 1000.0:
            raise ConfigError(f"fps must be between 1 and 1000, not {self.fps}")
        if self.submit_token is None and self.view_token is None and not is_loopback(self.host):
            raise ConfigError(
                f"refusing to serve on {self.host!r} without tokens: set a submit token "
                "and/or a view token, or bind to a loopback address such as 127.0.0.1"
            )


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback addresses (127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True, slots=True)
class FaceAssets:
    """The face every character shows: the model, its deformer and colours."""

    face: Face
    deform: Deformer
    colours: npt.NDArray[np.uint8] | None = None
    avatar: bytes | None = None  # a glTF binary the browser viewer drives (--avatar)
    avatar_missing: tuple[str, ...] = ()  # ARKit targets the avatar lacks


@dataclass(slots=True)
class ClockStats:
    """What the frame clock did; read by /health and the benchmark.

    ``started``: the clock's frame 0, in seconds of the host's monotonic
    clock (``time.monotonic()``, shared by processes on one host), so a
    local client can tell when frame n was due. Lateness is how long after
    its due time a tick began; the recent values (last minute at 60 fps)
    give the percentiles.
    """

    started: float = 0.0
    ticks: int = 0
    skipped: int = 0  # frames not computed because the clock was behind
    last_tick_seconds: float = 0.0  # work of the last tick
    max_tick_seconds: float = 0.0
    max_lateness_seconds: float = 0.0
    recent_lateness: deque[float] = field(default_factory=lambda: deque(maxlen=3600))
    #: the longest time between the starts of two consecutive ticks (so
    #: between two frames sent), seconds: a stall shows here in full, where
    #: lateness only sees how late the frame the clock skipped to began
    max_frame_gap_seconds: float = 0.0
    recent_frame_gaps: deque[float] = field(default_factory=lambda: deque(maxlen=3600))
    last_tick_began: float | None = None
    #: frame due -> its fan-out done (every viewer's frame written to its
    #: socket, or put in its mailbox when the socket is full), seconds: the
    #: service's own part of a frame's delay
    recent_written: deque[float] = field(default_factory=lambda: deque(maxlen=3600))
    #: times the clock gave the event loop back in the middle of a fan-out
    given_back: int = 0
    #: character frames sent after a second try in the same tick (a
    #: submission held the character's lock at the first), and those not
    #: sent at all (the lock still held at :data:`GIVE_BACK_SHARE` of a period)
    busy_retried: int = 0
    busy_missed: int = 0

    def tick_began(self, at: float) -> None:
        """Record that a tick began at ``at`` (loop seconds)."""
        if self.last_tick_began is not None:
            gap = at - self.last_tick_began
            self.max_frame_gap_seconds = max(self.max_frame_gap_seconds, gap)
            self.recent_frame_gaps.append(gap)
        self.last_tick_began = at

    def summary(self) -> dict[str, float | int]:
        recent = sorted(self.recent_lateness)
        written = sorted(self.recent_written)

        def share(q: float, values: list[float] = recent) -> float:
            return values[min(len(values) - 1, int(q * len(values)))] if values else 0.0

        return {
            "started": self.started,
            "ticks": self.ticks,
            "skipped": self.skipped,
            "last_tick_seconds": self.last_tick_seconds,
            "max_tick_seconds": self.max_tick_seconds,
            "max_lateness_seconds": self.max_lateness_seconds,
            "lateness_p50_seconds": share(0.5),
            "lateness_p99_seconds": share(0.99),
            "written_p50_seconds": share(0.5, written),
            "written_p99_seconds": share(0.99, written),
            "max_frame_gap_seconds": self.max_frame_gap_seconds,
            "recent_max_frame_gap_seconds": max(self.recent_frame_gaps, default=0.0),
            "given_back": self.given_back,
            "busy_retried": self.busy_retried,
            "busy_missed": self.busy_missed,
        }


@dataclass(eq=False, slots=True)
class Submitter:
    """One submitter connection: its outgoing text messages, in order."""

    connection: ServerConnection
    format: FeedbackFormat
    default_character: str
    characters: set[str] = field(default_factory=set)
    #: ``/bml?strict=true``: every warning refuses the block
    strict: bool = False
    #: (loop time it was queued, text) of each message not yet sent
    outbox: deque[tuple[float, str]] = field(default_factory=deque)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    closing: bool = False


@dataclass(eq=False, slots=True)
class Viewer:
    """One viewer connection: control messages (never dropped) and a
    mailbox holding only the newest frame."""

    connection: ServerConnection
    character: str
    options: ViewOptions
    control: deque[bytes] = field(default_factory=deque)
    latest: bytes | None = None
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    offered: int = 0
    replaced: int = 0  # frames replaced before they were sent
    direct: int = 0  # frames written at once, without the pump
    idle: bool = False  # the pump waits for something to send
    closing: bool = False
    wants_model: bool = False  # send the deformation model after each mesh
    audio: bool = True  # send the character's speech audio (audio=none opts out)
    #: audio messages not yet sent, oldest first (bounded: the oldest go first)
    audio_queue: deque[bytes] = field(default_factory=deque)
    audio_dropped: int = 0
    #: ``scene=true``: send the scene (its targets and the characters' eyes)
    #: after each mesh and whenever it changes
    scene: bool = False
    #: the scene message queued and not yet sent (a newer one replaces it)
    scene_queued: bytes | None = None
    #: ``same=true``: a tick that shows what the last frame showed may be
    #: sent as a ``same`` message (protocols/viewer.md)
    same: bool = False
    #: the content version (FrameEncoder.observe) of the last frame offered;
    #: -1: none yet for this subscription
    version: int = -1
    latest_same: bool = False  # the mailbox holds a `same`, not a frame
    #: counts the subscribe messages applied: an offer the clock queued for
    #: an earlier subscription is dropped (its frame must not follow the new mesh)
    subscription: int = 0

    def offer_audio(self, message: bytes, backlog: int) -> None:
        """Queue an audio chunk (never replaced like frames: audio must be whole);
        beyond ``backlog`` queued chunks the oldest is dropped."""
        if len(self.audio_queue) >= backlog:
            self.audio_queue.popleft()
            self.audio_dropped += 1
        self.audio_queue.append(message)
        self.wake.set()

    def writes_at_once(self, write_limit: int) -> bool:
        """Whether a frame offered now may go straight to the socket: the
        pump is idle with nothing waiting (mailbox, control, audio), the
        connection is open and its buffer holds under ``write_limit`` bytes."""
        connection = self.connection
        return (
            self.idle
            and self.latest is None
            and not self.control
            and not self.audio_queue
            and connection.protocol.state is State.OPEN
            and connection.transport.get_write_buffer_size() < write_limit
        )

    def offer(self, frame: bytes, write_limit: int = 0, wire: bytes | None = None) -> None:
        """Send the newest frame, or put it in the mailbox (replacing an
        unsent one) when the viewer's socket buffer holds ``write_limit``
        bytes or more. ``wire``: ``binary_frame(frame)``, if the caller has it.

        The fast path writes at once, as websockets' ``broadcast`` does, but
        only while the pump is idle and the socket's buffer is under the
        limit, so order and the memory bound are kept: a viewer that does not
        read fills its buffer once, then only its mailbox is replaced.
        """
        self.offered += 1
        connection = self.connection
        if self.writes_at_once(write_limit):
            try:
                # The WebSocket frame's bytes straight to the socket: what
                # websockets' send_binary would write for this server-side,
                # unmasked, uncompressed connection, whose writes are all
                # flushed at once (nothing of it is pending here: the pump is
                # idle), so order is kept; ``wire`` is built once per tick.
                connection.transport.write(wire if wire is not None else binary_frame(frame))
            except Exception:  # the connection broke: its pump will see it close
                return
            self.direct += 1
            return
        if self.latest is not None:
            self.replaced += 1
        self.latest = frame
        self.latest_same = False
        self.wake.set()

    def offer_same(self, same: bytes, write_limit: int = 0, wire: bytes | None = None) -> None:
        """Offer a ``same`` message, unless a frame still waits in the mailbox
        (that frame is newer content than what the viewer has: it must not be
        replaced, and it says more than ``same``)."""
        if self.latest is not None and not self.latest_same:
            return
        self.offer(same, write_limit, wire)
        self.latest_same = self.latest is not None


#: Seconds before a tick's due time the clock's event-loop wait ends: the
#: loop's wait (epoll) counts whole milliseconds and rounds up, so a wait
#: for the due time itself ends up to 1 ms after it (0.7 ms at the median,
#: measured here); the rest of the wait is a sleep of the thread.
EPOLL_GRANULARITY = 0.001


#: Seconds of writing frames to viewers after which the clock gives the
#: event loop back (:meth:`RealizerService._write_offers`): a submission that
#: arrives while a tick fans out 1,000 frames (several milliseconds) is read,
#: handed to a planner thread and answered between two slices instead of
#: after the whole fan-out.
FAN_OUT_SLICE = 0.0005

#: Share of a frame period, from the frame's due time, in which the clock
#: gives the loop back between slices and tries again a character whose lock
#: a submission held; past it, what is left of the tick is written at once,
#: so whatever else the loop has to do never costs a frame.
GIVE_BACK_SHARE = 0.5

#: Seconds between two tries of a character whose lock a submission holds
#: (admitting or committing a block, a few milliseconds at most).
BUSY_RETRY_SECONDS = 0.0005


#: One offer the clock queued: the viewer, its subscription then
#: (:attr:`Viewer.subscription`), the payload, its WebSocket bytes and the
#: content version (-1: a ``same`` message).
_Offer = tuple["Viewer", int, bytes, bytes, int]


def _make_offer(offer: _Offer) -> None:
    """Offer a queued frame or ``same`` to its viewer, unless the viewer has
    subscribed again since (that frame must not follow the new mesh)."""
    viewer, subscription, data, wire, version = offer
    if viewer.subscription != subscription:
        return
    if version < 0:
        viewer.offer_same(data, WRITE_LIMIT, wire)
    else:
        viewer.offer(data, WRITE_LIMIT, wire)


def _ready_callbacks(loop: asyncio.AbstractEventLoop) -> int | None:
    """How many callbacks wait on ``loop``'s ready queue (CPython's
    ``BaseEventLoop._ready``), or None for a loop that has none to read."""
    ready = getattr(loop, "_ready", None)
    return len(ready) if ready is not None else None


#: Seconds the thread sleeps at a time in the last millisecond before a
#: tick, with a round of the event loop between two sleeps: the loop is never
#: held longer than this (and a sleep's slack) waiting for a tick.
LAST_SLEEP = 0.00025


async def _wait_until(loop: asyncio.AbstractEventLoop, due: float) -> None:
    """Return at the loop time ``due`` (never before it), within tens of
    microseconds when the machine is not busy.

    The event loop waits until ``due - EPOLL_GRANULARITY`` (so callbacks,
    reads and other tasks run while it waits), then the thread sleeps what
    is left, under a millisecond, with the GIL released (``time.sleep``:
    ``clock_nanosleep``, microsecond resolution), so planner threads go on
    meanwhile. A wait that the loop's rounding would have made end up to
    1 ms late now ends on time. That last millisecond is slept in pieces of
    :data:`LAST_SLEEP` with a round of the loop between them, so a
    submission that arrives then is read and handed to a planner thread
    before the tick, not after it.
    """
    early = due - EPOLL_GRANULARITY - loop.time()
    if early > 0:
        await asyncio.sleep(early)
    while (rest := due - loop.time()) > LAST_SLEEP:
        time.sleep(LAST_SLEEP)
        await asyncio.sleep(0)
    if rest > 0:
        time.sleep(rest)


def binary_frame(payload: bytes) -> bytes:
    """A final, unmasked WebSocket binary frame (RFC 6455 section 5.2) of
    ``payload``: what a server without extensions sends for it."""
    size = len(payload)
    if size < 126:
        head = bytes((0x82, size))
    elif size < 65536:
        head = b"\x82\x7e" + size.to_bytes(2, "big")
    else:
        head = b"\x82\x7f" + size.to_bytes(8, "big")
    return head + payload


class RealizerService:
    """The server. ``await start()``, then ``await shutdown()``; see
    :func:`run_service` for the process around it.

    The cluster's worker and gateway (:mod:`realizer.service.cluster`)
    subclass it and override the hooks marked "hook" below: where a
    request goes (:meth:`_on_submit`), where a character is made
    (:meth:`_admit_viewer`), where a frame goes (:meth:`_deliver_frame`).
    """

    #: Whether this process computes frames (a cluster gateway does not).
    runs_clock: ClassVar[bool] = True

    def __init__(self, config: ServiceConfig, stage: Stage, assets: FaceAssets) -> None:
        self.config = config
        self.stage = stage
        self.assets = assets
        self.limits: ServiceLimits = config.limits
        self.stats = ClockStats()
        self.submitters: set[Submitter] = set()
        self.viewers: dict[str, set[Viewer]] = {}
        self.encoders: dict[str, FrameEncoder] = {}
        self.audio_streams: dict[str, AudioStream] = {}
        self._server: Server | None = None
        self._clock: asyncio.Task[None] | None = None
        self._tasks: set[asyncio.Task[Any]] = set()
        self._start = 0.0  # loop time of frame 0
        self._frame = 0  # number of the next frame
        self._scene_version = -1  # the scene version the viewers were last sent
        # This tick's offers (_deliver_frame queues them, _write_offers makes
        # them in slices): each character's frames once it is ticked, every
        # `same` message after all the frames.
        self._frame_offers: list[_Offer] = []
        self._same_offers: list[_Offer] = []
        self._given_back_seconds = 0.0  # in the current tick
        self._slice_end = 0.0  # perf_counter time the clock's current slice ends
        # The submitters' sockets, polled (never read) between two slices of
        # a fan-out: a message waiting there is a reason to give the loop back.
        self._submitter_sockets = selectors.DefaultSelector()
        self._stopping = False
        self._static = _StaticFiles()
        # The clock never waits for a submitter: each message is handled on
        # one of these threads, one message per connection at a time (in
        # order), which parse and plan themselves or, with
        # config.planner_processes, in planner processes; the stage's lock
        # per character keeps each session single-threaded and lets the
        # clock skip, not wait for, a character being admitted or committed.
        self._planner = ThreadPoolExecutor(
            max_workers=config.planner_threads, thread_name_prefix="realizer-planner"
        )
        # ... or in planner processes (config.planner_processes; start()).
        self._planner_pool: PlannerPool | None = None
        # The sparse solver's scipy is imported lazily; import it here, before
        # any frame, so a first big block does not import it on a planner
        # thread while the clock runs (the light install has no scipy: fine).
        solver.warm_up()

    # -- life cycle ---------------------------------------------------------------

    @property
    def port(self) -> int:
        """The port actually bound (useful with ``port=0``)."""
        assert self._server is not None, "start() first"
        return int(self._server.sockets[0].getsockname()[1])

    def now(self) -> float:
        """Service time in seconds since the clock started."""
        return asyncio.get_running_loop().time() - self._start

    def _now_any_thread(self) -> float:
        """:meth:`now` from a planner thread (the loop's clock is time.monotonic())."""
        return time.monotonic() - self._start

    async def start(self) -> None:
        """Bind the port and start the clock."""
        loop = asyncio.get_running_loop()
        # The first session pays for loading the engines (a few hundred ms);
        # pay it here, before the clock runs, not on the loop when a viewer
        # of a new character connects. (A cluster gateway has no sessions.)
        if self.runs_clock:
            self.stage.make_session(self.stage.default_character)
            await self._start_planner()
        self._server = await websocket_serve(
            self._handle,
            self.config.host,
            self.config.port,
            process_request=self._process_request,
            max_size=self.limits.message_bytes,
            # Frames are msgpack of float32/int16 data and small; deflate
            # would cost CPU per viewer for little gain.
            compression=None,
            close_timeout=self.config.shutdown_timeout,
            # Per-connection buffer before send() waits: a viewer that stops
            # reading holds at most this much plus two frames (one written
            # past the limit, one in its mailbox).
            write_limit=WRITE_LIMIT,
            create_connection=_OneRequestConnection,
        )
        # Planner threads compete with the loop for the GIL; a thread that
        # wants it waits at most the switch interval (5 ms by default). A
        # shorter one lets the clock's tick take the GIL back sooner while a
        # block is planned (a process-wide setting: the service owns it).
        sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL))
        self._start = loop.time()
        # asyncio's loop clock is time.monotonic(); record frame 0 on it.
        self.stats.started = self._start
        if self.runs_clock:
            self._clock = loop.create_task(self._run_clock(), name="realizer-clock")

    async def _start_planner(self) -> None:
        """Start the planner processes (``config.planner_processes``) and give
        them to the stage, when its sessions say how to build their engines
        in another process (realizer.service.assets.Sessions); otherwise the
        planner threads plan in this process."""
        recipe = getattr(self.stage.make_session, "planning", None)
        processes = self.config.planner_processes
        if processes == 0 or recipe is None or self.stage.planner is not None:
            return
        from realizer.service.planner import PlannerPool

        # Starting the children (and, the first time, the fork server that
        # imports and warms up the planner) takes a while: off the loop.
        self._planner_pool = await asyncio.to_thread(
            PlannerPool, processes, recipe, self.limits.planning_milliseconds
        )
        self.stage.planner = self._planner_pool
        logger.debug(
            "%d planner processes started in %.3f s",
            processes,
            self._planner_pool.start_seconds,
        )

    async def shutdown(self, reason: str = "server shutting down") -> None:
        """The shutdown sequence, each waiting step bounded by the timeout."""
        if self._stopping:
            return
        self._stopping = True
        timeout = self.config.shutdown_timeout
        assert self._server is not None
        # 1. Stop accepting: close the listening socket; handshakes still in
        #    progress are answered 503 by websockets.
        self._server.server.close()
        # 2. Stop the clock, then interrupt every pending and running block,
        #    so submitters get the feedback of their blocks' end, and tick
        #    once more to flush what the interruption produced.
        if self._clock is not None:
            self._clock.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._clock
        now = self.now()
        self._dispatch(self.stage.interrupt_all(now))
        for character_tick in self.stage.tick(now):
            self._dispatch(character_tick.messages)
        # 3. Let the submitters' outboxes drain (bounded).
        deadline = asyncio.get_running_loop().time() + timeout
        while any(s.outbox for s in self.submitters if not s.closing):
            if asyncio.get_running_loop().time() > deadline:
                break
            await asyncio.sleep(0.01)
        # 4. Close every connection with 1001 (going away) and wait for the
        #    handlers, bounded; 5. abort what is left.
        self._server.close(close_connections=True, code=CloseCode.GOING_AWAY, reason=reason)
        try:
            await asyncio.wait_for(self._server.wait_closed(), timeout * 2)
        except TimeoutError:
            for connection in list(self._server.connections):
                connection.transport.abort()
        for task in list(self._tasks):
            task.cancel()
        self._planner.shutdown(wait=False, cancel_futures=True)
        self._submitter_sockets.close()
        if self._planner_pool is not None:
            self.stage.planner = None
            self._planner_pool.close()
            self._planner_pool = None

    # -- the clock ------------------------------------------------------------------

    async def _run_clock(self) -> None:
        loop = asyncio.get_running_loop()
        fps = self.config.fps
        while True:
            due = self._start + self._frame / fps
            await _wait_until(loop, due)
            begun = loop.time()
            # Behind by whole frames (a long pause, an overloaded machine):
            # skip to the frame that is due now instead of computing a burst
            # of stale frames; frame numbers stay tied to time.
            behind = int((begun - self._start) * fps) - self._frame
            if behind > 0:
                self.stats.skipped += behind
                self._frame += behind
            due = self._start + self._frame / fps
            self.stats.tick_began(begun)
            self.stats.max_lateness_seconds = max(self.stats.max_lateness_seconds, begun - due)
            self.stats.recent_lateness.append(begun - due)
            started = time.perf_counter()
            self._given_back_seconds = 0.0
            try:
                await self._clock_tick(
                    loop, self._frame, self._frame / fps, due + GIVE_BACK_SHARE / fps
                )
            except Exception:  # a bug in a session must not stop every character
                logger.exception("tick %d failed", self._frame)
            spent = time.perf_counter() - started - self._given_back_seconds
            self.stats.recent_written.append(loop.time() - due)
            self.stats.last_tick_seconds = spent
            self.stats.max_tick_seconds = max(self.stats.max_tick_seconds, spent)
            self.stats.ticks += 1
            if self._frame % int(fps) == 0:  # once a second
                self._forget_idle_characters(self._frame / fps)
            self._frame += 1

    def _forget_idle_characters(self, now: float) -> None:
        """Free characters with no block, no viewer and no submitter naming
        them for ``limits.character_idle_seconds`` (viewers cannot fill the
        character table for good)."""
        used = {c for c, viewers in self.viewers.items() if viewers}
        for submitter in self.submitters:
            used.update(submitter.characters)
        for character_id in self.stage.forget_idle(
            now, self.limits.character_idle_seconds, keep=used
        ):
            self.encoders.pop(character_id, None)
            self.viewers.pop(character_id, None)

    async def _clock_tick(
        self, loop: asyncio.AbstractEventLoop, number: int, now: float, until: float
    ) -> None:
        """One tick: every session advanced, its feedback dispatched and its
        frame written to its viewers, in slices of :data:`FAN_OUT_SLICE`.

        Each character's frames are written as soon as it is ticked, its
        ``same`` messages after every character's frames: a viewer whose
        face changed is not kept waiting by those whose face did not.

        No submitter waits behind the clock: between two slices the event
        loop runs what waits for it (:meth:`_loop_wanted`: a submission read
        and handed to a planner thread, an ``accepted`` sent). No viewer
        waits behind a submitter: a character whose lock a submission holds
        (a block being admitted or committed, for a few milliseconds) is
        tried again every :data:`BUSY_RETRY_SECONDS`, so its frame goes out
        late in this period instead of not at all. Both end at ``until``
        (loop time): past it the rest of the frames are written at once and
        a character still busy misses this frame.
        """
        self._frame_offers.clear()
        self._same_offers.clear()
        self._slice_end = time.perf_counter() + FAN_OUT_SLICE
        busy: list[str] = []
        for character_id in list(self.stage.characters):
            for character_tick in self.stage.tick(now, only=(character_id,)):
                self._character_ticked(number, character_tick)
            busy.extend(self.stage.busy)
            await self._write_offers(loop, until, self._frame_offers)
        self._scene_changed()
        while busy:
            if loop.time() + BUSY_RETRY_SECONDS >= until:
                self.stats.busy_missed += len(busy)
                break
            began = time.perf_counter()
            await asyncio.sleep(BUSY_RETRY_SECONDS)
            self._given_back_seconds += time.perf_counter() - began
            retried = self.stage.tick(now, only=busy)
            busy = self.stage.busy
            self.stats.busy_retried += len(retried)
            for character_tick in retried:
                self._character_ticked(number, character_tick)
            await self._write_offers(loop, until, self._frame_offers)
        await self._write_offers(loop, until, self._same_offers)

    def _character_ticked(self, number: int, character_tick: CharacterTick) -> None:
        if character_tick.messages:
            self._dispatch(character_tick.messages)
        self._deliver_frame(number, character_tick)

    async def _write_offers(
        self, loop: asyncio.AbstractEventLoop, until: float, queue: list[_Offer]
    ) -> None:
        """Make the offers in ``queue`` (:func:`_make_offer`), emptying it;
        whenever the current slice (``_slice_end``) is over, give the event
        loop back if something waits for it and ``until`` (loop time) is not
        past (:meth:`_yield_to_loop`), and start the next slice."""
        if not queue:
            return
        offers = queue.copy()
        queue.clear()
        clock = time.perf_counter
        for viewer, subscription, data, wire, version in offers:  # _make_offer, inlined
            if viewer.subscription == subscription:
                if version < 0:
                    viewer.offer_same(data, WRITE_LIMIT, wire)
                else:
                    viewer.offer(data, WRITE_LIMIT, wire)
            if clock() >= self._slice_end:
                if loop.time() < until and self._loop_wanted(loop):
                    await self._yield_to_loop(loop, until)
                self._slice_end = clock() + FAN_OUT_SLICE

    def _write_offers_at_once(self) -> None:
        """Make every queued offer, frames then ``same`` messages, without
        giving the loop back (``realizer bench fanout`` times a whole
        fan-out this way)."""
        for queue in (self._frame_offers, self._same_offers):
            offers = queue.copy()
            queue.clear()
            for offer in offers:
                _make_offer(offer)

    def _loop_wanted(self, loop: asyncio.AbstractEventLoop) -> bool:
        """Whether something waits for the event loop that the clock should
        let run now: a callback on the ready queue (a planner thread's
        answer, a task woken), or a submitter's message unread in its socket
        (polled without reading it). Viewers' sockets are not looked at: their
        writes are the fan-out itself."""
        ready = _ready_callbacks(loop)
        if ready is None or ready > 0:
            return True
        sockets = self._submitter_sockets
        return bool(sockets.get_map()) and bool(sockets.select(0))

    async def _yield_to_loop(self, loop: asyncio.AbstractEventLoop, until: float) -> None:
        """Let the event loop run what waits for it, then come back.

        One round (``asyncio.sleep(0)``) polls the sockets and runs what was
        ready; a callback it runs often makes the next one ready (a message
        read wakes its handler, whose answer wakes a sender), so rounds go
        on while other callbacks wait, until the loop time ``until``.
        """
        began = time.perf_counter()
        self.stats.given_back += 1
        await asyncio.sleep(0)
        while (_ready_callbacks(loop) or 0) > 0 and loop.time() < until:
            await asyncio.sleep(0)
        self._given_back_seconds += time.perf_counter() - began

    def _deliver_frame(self, number: int, character_tick: CharacterTick) -> None:
        """Hook: encode one character's frame once per format and queue it
        for its viewers (:meth:`_write_offers` offers them, in slices), its
        audio offered at once (a cluster worker publishes the frame instead).

        Nothing to say, nearly nothing sent: a viewer that asked for ``same``
        messages and already has this tick's content (its FAPs, so its
        vertices and weights) gets a ``same`` of a few bytes; only the others
        get the frame, which is encoded only if someone needs it. The coded
        FAP stream is one per character, so when it codes a frame (its
        prediction moves on) every coded viewer gets that frame; and it codes
        one at least once a second (after a rest, an intra frame).
        """
        viewers = self.viewers.get(character_tick.character)
        if not viewers:
            return
        self._send_audio(character_tick.character, character_tick.time, viewers)
        encoder = self._encoder(character_tick.character)
        version = encoder.observe(character_tick.frame)
        stale = [v for v in viewers if not v.same or v.version != version]
        # The coded stream sends an intra frame once a second even while the
        # face rests (a viewer that lost a frame decodes again from it).
        intra_due = number % max(1, round(self.config.fps * CODED_INTRA_SECONDS)) == 0
        if intra_due or any(v.options.coded for v in stale):
            stale = [v for v in viewers if v.options.coded or not v.same or v.version != version]
        if len(stale) < len(viewers):
            same = codec.same_message(number)
            same_wire = binary_frame(same)
            chosen = set(stale)
            sames = self._same_offers
            for viewer in viewers:
                if viewer not in chosen:
                    sames.append((viewer, viewer.subscription, same, same_wire, -1))
        if stale:
            encoded = encoder.encode(
                number, character_tick.time, character_tick.frame, (v.options for v in stale)
            )
            # the WebSocket bytes of each format once (Viewer.offer writes them
            # as they are), with the payload: one look-up per viewer (hashing
            # a ViewOptions costs a third of a microsecond)
            wires = {options: (data, binary_frame(data)) for options, data in encoded.items()}
            frames = self._frame_offers
            for viewer in stale:
                found = wires.get(viewer.options)  # none for ARKit viewers until its fit is set up
                if found is not None:
                    frames.append((viewer, viewer.subscription, found[0], found[1], version))
                    viewer.version = version

    def _send_audio(self, character: str, now: float, viewers: Iterable[Viewer]) -> None:
        """The character's speech audio due at ``now`` to the viewers that want it."""
        listeners = [v for v in viewers if v.audio]
        if not listeners:
            self.audio_streams.pop(character, None)  # a new listener starts at the clock
            return
        found = self.stage.characters.get(character)
        if found is None:
            return
        stream = self.audio_streams.get(character)
        if stream is None:
            stream = self.audio_streams[character] = AudioStream(character)
        messages = stream.messages(found.session, now)
        backlog = backlog_limit(fps=self.config.fps)
        for message in messages:
            for viewer in listeners:
                viewer.offer_audio(message, backlog)

    def _encoder(self, character_id: str) -> FrameEncoder:
        encoder = self.encoders.get(character_id)
        if encoder is None:
            encoder = FrameEncoder(
                character_id,
                self.assets.face,
                self.assets.deform,
                self.config.fps,
                self.assets.colours,
            )
            self.encoders[character_id] = encoder
        return encoder

    # -- plain HTTP and the handshake --------------------------------------------------

    def _process_request(self, connection: ServerConnection, request: Request) -> Any:
        """Answer plain HTTP, or let a WebSocket handshake go on (None).

        Only single GET requests are served: another method is answered 405,
        bytes after the request (pipelining, a body) 400, a header that must
        appear once and appears twice 400 (401 for ``Authorization``).
        """
        if request.method != "GET":
            reply = _response(http.HTTPStatus.METHOD_NOT_ALLOWED, b"only GET is served\n")
            reply.headers["Allow"] = "GET"
            return reply
        try:
            for name in _SINGLE_HEADERS:
                if len(request.headers.get_all(name)) > 1:
                    raise MultipleValuesError(name)
            return self._route_request(request)
        except MultipleValuesError as exc:
            name = str(exc).strip("'\"")
            status = (
                http.HTTPStatus.UNAUTHORIZED
                if name.lower() == "authorization"
                else http.HTTPStatus.BAD_REQUEST
            )
            return _response(status, f"the header {name[:40]} appears more than once\n".encode())

    def _route_request(self, request: Request) -> Response | None:
        url = urlsplit(request.path)
        if url.path in (SUBMIT_PATH, VIEW_PATH):
            return self._authorise(url.path, parse_qs(url.query), request.headers)
        if request.headers.get("Upgrade", "").lower() == "websocket":
            return _response(http.HTTPStatus.NOT_FOUND, b"no WebSocket endpoint here\n")
        if url.path == "/health":
            return _json_response(self.health())
        if url.path == "/version":
            return _json_response(
                {"realizer": __version__, "protocol": PROTOCOL_VERSION, "fps": self.config.fps}
            )
        if url.path == "/avatar.json":
            return _json_response(
                {
                    "avatar": self.assets.avatar is not None,
                    "missing": list(self.assets.avatar_missing),
                }
            )
        if url.path == "/avatar.glb" and self.assets.avatar is not None:
            return _response(http.HTTPStatus.OK, self.assets.avatar, "model/gltf-binary")
        if url.path == "/favicon.ico":
            return _response(http.HTTPStatus.NO_CONTENT, b"")
        found = self._static.get(url.path)
        if found is not None:
            body, content_type = found
            return _response(http.HTTPStatus.OK, body, content_type)
        return _response(http.HTTPStatus.NOT_FOUND, b"not found\n")

    def _authorise(
        self, path: str, query: dict[str, list[str]], headers: Headers
    ) -> Response | None:
        submit, view = self.config.submit_token, self.config.view_token
        if submit is None and view is None:
            return None
        tokens = query.get("token", [""])
        if len(tokens) > 1:
            return _response(http.HTTPStatus.UNAUTHORIZED, b"one token, please\n")
        token = tokens[0]
        bearer = headers.get("Authorization", "")  # twice: MultipleValuesError, 401
        if not token and bearer.lower().startswith("bearer "):
            token = bearer[7:].strip()
        may_submit = submit is not None and _same(token, submit)
        may_view = may_submit or (view is not None and _same(token, view))
        if path == SUBMIT_PATH and not may_submit:
            if may_view:
                return _response(http.HTTPStatus.FORBIDDEN, b"this token may only view\n")
            return _response(http.HTTPStatus.UNAUTHORIZED, b"a submit token is required\n")
        if path == VIEW_PATH and not may_view:
            return _response(http.HTTPStatus.UNAUTHORIZED, b"a view or submit token is required\n")
        return None

    def health(self) -> dict[str, Any]:
        """What ``/health`` answers."""
        return {
            "status": "stopping" if self._stopping else "ok",
            "characters": len(self.stage.characters),
            "maxFrameGapSeconds": self.stats.max_frame_gap_seconds,
            "characterIds": sorted(self.stage.characters),
            "viewers": sum(len(v) for v in self.viewers.values()),
            "submitters": len(self.submitters),
            "frame": self._frame,
            "fps": self.config.fps,
            "clock": self.stats.summary(),
        }

    async def _handle(self, connection: ServerConnection) -> None:
        url = urlsplit(connection.request.path if connection.request else "/")
        query = {k: v[0] for k, v in parse_qs(url.query).items()}
        try:
            if url.path == SUBMIT_PATH:
                await self._serve_submitter(connection, query)
            elif url.path == VIEW_PATH:
                await self._serve_viewer(connection, query)
        except ConnectionClosed:
            pass

    # -- submitters -------------------------------------------------------------------

    async def _serve_submitter(self, connection: ServerConnection, query: dict[str, str]) -> None:
        fmt = query.get("format", "xml")
        character = query.get("character", self.stage.default_character)
        if fmt not in ("xml", "json"):
            await connection.close(CloseCode.POLICY_VIOLATION, "format must be xml or json")
            return
        if not valid_character_id(character):
            await connection.close(CloseCode.POLICY_VIOLATION, "invalid character id")
            return
        if len(self.submitters) >= self.limits.submitters:
            await connection.close(
                CloseCode.TRY_AGAIN_LATER, f"limit of {self.limits.submitters} submitters reached"
            )
            return
        submitter = Submitter(connection, cast(FeedbackFormat, fmt), character)
        submitter.strict = query.get("strict", "false").lower() in ("1", "true", "yes")
        if "character" in query:
            submitter.characters.add(character)
        self.submitters.add(submitter)
        polled = self._poll_submitter(connection)
        pump = self._spawn(self._pump_submitter(submitter))
        if submitter.format == "json":
            welcome = WelcomeMessage(
                type="welcome",
                protocol=PROTOCOL_VERSION,
                server=__version__,
                character=character,
                fps=self.config.fps,
                limits=asdict(self.limits),
            )
            self._push(submitter, json.dumps(welcome))
        try:
            async for message in connection:
                if isinstance(message, bytes):
                    await connection.close(
                        CloseCode.UNSUPPORTED_DATA,
                        "the submitter endpoint takes text: BML or a JSON envelope",
                    )
                    break
                await self._on_submit(submitter, message)
        finally:
            self.submitters.discard(submitter)
            if polled is not None:
                with contextlib.suppress(KeyError, ValueError, OSError):
                    self._submitter_sockets.unregister(polled)
            pump.cancel()

    def _poll_submitter(self, connection: ServerConnection) -> int | None:
        """Add a submitter's socket to those the clock polls between slices
        (:meth:`_loop_wanted`); its file descriptor, or None."""
        sock = connection.transport.get_extra_info("socket")
        if sock is None:
            return None
        fd = int(sock.fileno())
        try:
            self._submitter_sockets.register(fd, selectors.EVENT_READ)
        except (KeyError, ValueError, OSError):
            return None
        return fd

    async def _on_submit(self, submitter: Submitter, text: str) -> None:
        """Process one message on a planner thread, then send what it made.

        The message's time is its arrival; the connection's next message is
        read only when this one is done, so its messages keep their order.
        """
        now = self.now()
        loop = asyncio.get_running_loop()
        try:
            messages, character = await loop.run_in_executor(
                self._planner,
                self._realize,
                submitter.default_character,
                submitter.strict,
                text,
                now,
            )
        except RuntimeError:  # the planner is shut down: the server is stopping
            return
        except Exception:
            # A bug, not the peer's fault: log it, answer without details
            # (they may be security-sensitive), keep the connection.
            logger.exception("internal error on a submitted message")
            xml = warning_feedback_xml(
                "", submitter.default_character, "CANNOT_CREATE_BEHAVIOR", "internal error"
            )
            warning = WireFeedback(submitter.default_character, "warning", "", self.now(), xml)
            self._dispatch([warning], also=submitter)
            return
        if character == "":  # a message the endpoint could not read: only its sender hears
            for message in messages:
                self._push(submitter, _render(message, submitter.format))
            return
        if character is not None:
            submitter.characters.add(character)
        self._dispatch(messages, also=submitter)

    def _realize(
        self, default_character: str, strict: bool, text: str, now: float
    ) -> tuple[tuple[Outgoing, ...], str | None]:
        """One submitter message (on a planner thread): what to send, and the
        character the submitter now listens to (None: none new; ``""``: the
        message was unreadable and only its sender is answered)."""
        try:
            request = read_submitter_message(text)
        except BadMessage as exc:
            # the sender's own mistake: told to the sender alone (see _on_submit)
            xml = warning_feedback_xml("", default_character, exc.warning_type, exc.message)
            return (WireFeedback(default_character, "warning", "", now, xml),), ""
        if request["type"] == "bml":
            result = self.stage.submit_bml(
                request["bml"],
                now,
                character=request.get("character"),
                fallback=default_character,
                strict=strict,
                clock=self._now_any_thread,  # a slow TTS runs first; timed after it
            )
            joined = result.character if result.character in self.stage.characters else None
            return result.messages, joined
        if request["type"] == "target":  # a scene target placed or moved (realizer.scene)
            x, y, z = request["position"]
            return self.stage.place_target(request["name"], (x, y, z), now), None
        character = request.get("character", default_character)
        return self.stage.interrupt(character, request["block"], now), None

    def _dispatch(self, messages: Iterable[Outgoing], also: Submitter | None = None) -> None:
        for message in messages:
            if isinstance(message, BlockEvent):  # one log line per block state (logs.py)
                log_block(message.character, message.block_id, message.state, message.time)
            for submitter in self.submitters:
                if submitter is also or message.character in submitter.characters:
                    self._push(submitter, _render(message, submitter.format))
            if also is not None and also not in self.submitters:
                self._push(also, _render(message, also.format))

    def _push(self, submitter: Submitter, text: str | None) -> None:
        """Queue ``text`` for one submitter; close only that submitter when
        it is the one not reading.

        The backlog is judged per reader: over ``feedback_backlog`` queued
        messages, a submitter is closed (1008) only if its oldest message
        has waited ``feedback_stall_seconds`` (it does not read), or if its
        queue reaches four times the backlog (memory stays bounded). A burst
        that a prompt reader is taking does not close it.
        """
        if text is None or submitter.closing:
            return
        now = asyncio.get_running_loop().time()
        queued = len(submitter.outbox)
        if queued >= self.limits.feedback_backlog and (
            queued >= 4 * self.limits.feedback_backlog
            or now - submitter.outbox[0][0] >= self.limits.feedback_stall_seconds
        ):
            submitter.closing = True
            submitter.outbox.clear()
            self._spawn(
                submitter.connection.close(
                    CloseCode.POLICY_VIOLATION,
                    f"feedback backlog over {self.limits.feedback_backlog} messages; read faster",
                )
            )
            return
        submitter.outbox.append((now, text))
        submitter.wake.set()

    async def _pump_submitter(self, submitter: Submitter) -> None:
        with contextlib.suppress(ConnectionClosed):
            while True:
                while not submitter.outbox:
                    submitter.wake.clear()
                    await submitter.wake.wait()
                await submitter.connection.send(submitter.outbox.popleft()[1])

    # -- viewers ----------------------------------------------------------------------

    async def _serve_viewer(self, connection: ServerConnection, query: dict[str, str]) -> None:
        character = query.get("character", self.stage.default_character)
        try:
            try:
                options = ViewOptions(
                    fap=query.get("fap", "true").lower() not in ("0", "false", "no"),
                    vertices=cast(Any, query.get("vertices", "none")),
                    coded=query.get("coded", "false").lower() in ("1", "true", "yes"),
                    arkit=query.get("arkit", "false").lower() in ("1", "true", "yes"),
                )
            except BadMessage as exc:  # a bad query parameter is a policy matter: 1008
                raise PeerError(exc.message) from None
            await self._admit_viewer(character)
        except PeerError as exc:
            await connection.close(exc.close_code, exc.message[:120])
            return
        audio = query.get("audio", "pcm16").lower()
        if audio not in AUDIO_VALUES:
            await connection.close(CloseCode.POLICY_VIOLATION, "audio must be pcm16 or none")
            return
        viewer = Viewer(connection, character, options)
        viewer.audio = audio == "pcm16"
        viewer.wants_model = query.get("model", "false").lower() in ("1", "true", "yes")
        viewer.scene = query.get("scene", "false").lower() in ("1", "true", "yes")
        viewer.same = query.get("same", "false").lower() in ("1", "true", "yes")
        viewer.control.extend(await self._subscription_start(character, viewer))
        self._offer_scene(viewer, self._scene_bytes())
        self.viewers.setdefault(character, set()).add(viewer)
        self._viewers_changed(character)
        pump = self._spawn(self._pump_viewer(viewer))
        try:
            async for message in connection:
                if isinstance(message, bytes):
                    await connection.close(
                        CloseCode.UNSUPPORTED_DATA, "the viewer endpoint takes JSON text messages"
                    )
                    break
                await self._on_subscribe(viewer, message)
        finally:
            self.viewers.get(viewer.character, set()).discard(viewer)
            self._viewers_changed(viewer.character)
            pump.cancel()

    async def _admit_viewer(self, character: str) -> None:
        """Raises :class:`PeerError` when ``character`` may not get one more viewer."""
        total = sum(len(v) for v in self.viewers.values())
        if total >= self.limits.viewers:
            raise _limit(f"limit of {self.limits.viewers} viewers reached")
        if len(self.viewers.get(character, ())) >= self.limits.viewers_per_character:
            raise _limit(f"limit of {self.limits.viewers_per_character} viewers per character")
        self.stage.character(character, for_viewer=True)

    async def _subscription_start(self, character: str, viewer: Viewer) -> list[bytes]:
        """Hook: the messages that start a viewer's subscription to
        ``character``: the mesh, then the deformation model if the viewer
        asked for it; a coded-FAP viewer makes the next frame an intra frame."""
        encoder = self._encoder(character)
        if viewer.options.coded:
            encoder.want_intra()
        return (
            [encoder.mesh_bytes, encoder.model_bytes]
            if viewer.wants_model
            else [encoder.mesh_bytes]
        )

    def _viewers_changed(self, character: str) -> None:
        """Hook: a viewer of ``character`` came, left or changed format."""

    async def _on_subscribe(self, viewer: Viewer, text: str) -> None:
        try:
            request = read_subscribe_message(text)
            character = request.get("character", viewer.character)
            options = ViewOptions(
                fap=request.get("fap", viewer.options.fap),
                vertices=request.get("vertices", viewer.options.vertices),
                coded=request.get("coded", viewer.options.coded),
                arkit=request.get("arkit", viewer.options.arkit),
            )
            if character != viewer.character:
                await self._admit_viewer(character)
        except PeerError as exc:
            error = {"type": "error", "v": PROTOCOL_VERSION, "reason": exc.message}
            self._control(viewer, codec.pack(error))
            return
        self.viewers.get(viewer.character, set()).discard(viewer)
        self._viewers_changed(viewer.character)
        viewer.subscription += 1  # what the clock queued for the old one is dropped
        viewer.character, viewer.options = character, options
        if "audio" in request:
            viewer.audio = request["audio"] == "pcm16"
        if "same" in request:
            viewer.same = request["same"]
        viewer.audio_queue.clear()  # audio of the old subscription must not follow
        self.viewers.setdefault(character, set()).add(viewer)
        self._viewers_changed(character)
        viewer.latest = None  # a frame of the old subscription must not follow the new mesh
        viewer.version = -1  # the new subscription's first frame is sent whole
        mesh, *model = await self._subscription_start(character, viewer)
        self._control(viewer, mesh)
        viewer.control.extend(model)
        if "scene" in request:
            viewer.scene = request["scene"]
        viewer.scene_queued = None
        self._offer_scene(viewer, self._scene_bytes())

    # -- the scene on the viewer stream (protocols/viewer.md, protocols/scene.md) --------

    def _scene_bytes(self) -> bytes:
        """The ``scene`` viewer message of the scene as it is now."""
        message: dict[str, Any] = {"type": "scene", "v": PROTOCOL_VERSION}
        message.update(self.stage.scene.snapshot())
        return codec.pack(message)

    def _offer_scene(self, viewer: Viewer, data: bytes) -> None:
        """Queue ``data`` for a viewer that asked for the scene; an unsent
        older scene message is replaced, so a fast-moving target never fills
        a slow viewer's control queue."""
        if not viewer.scene or viewer.closing:
            return
        if viewer.scene_queued is not None:
            for index, queued in enumerate(viewer.control):
                if queued is viewer.scene_queued:
                    viewer.control[index] = data
                    viewer.scene_queued = data
                    return
        viewer.scene_queued = data
        viewer.control.append(data)
        viewer.wake.set()

    def _scene_changed(self) -> None:
        """Once per tick: when the scene changed, its new state to every
        viewer that asked for it (encoded once)."""
        version = self.stage.scene.version
        if version == self._scene_version:
            return
        self._scene_version = version
        data: bytes | None = None
        for viewers in self.viewers.values():
            for viewer in viewers:
                if viewer.scene:
                    data = data if data is not None else self._scene_bytes()
                    self._offer_scene(viewer, data)

    def _control(self, viewer: Viewer, data: bytes) -> None:
        if len(viewer.control) >= self.limits.subscribe_backlog:
            viewer.closing = True
            self._spawn(
                viewer.connection.close(CloseCode.POLICY_VIOLATION, "too many subscribe requests")
            )
            return
        viewer.control.append(data)
        viewer.wake.set()

    async def _pump_viewer(self, viewer: Viewer) -> None:
        with contextlib.suppress(ConnectionClosed):
            while True:
                if viewer.control:
                    data = viewer.control.popleft()
                elif viewer.audio_queue:
                    data = viewer.audio_queue.popleft()
                elif viewer.latest is not None:
                    data, viewer.latest = viewer.latest, None
                else:
                    viewer.wake.clear()
                    viewer.idle = True
                    try:
                        await viewer.wake.wait()
                    finally:
                        viewer.idle = False
                    continue
                await viewer.connection.send(data)

    # -- helpers -----------------------------------------------------------------------

    def _spawn(self, coroutine: Any) -> asyncio.Task[Any]:
        task: asyncio.Task[Any] = asyncio.get_running_loop().create_task(coroutine)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task


class _OneRequestConnection(ServerConnection):
    """A connection that answers 400 to bytes sent after the HTTP request.

    websockets reads whatever follows the handshake request as WebSocket
    frames, so a pipelined second request (or a request body) made it drop
    the connection without an answer. A client must wait for the handshake's
    answer before it sends frames (RFC 6455 section 4.1), so bytes after the
    request's blank line, before the answer, are refused here: 400 and close.
    At most :data:`_HEAD_BYTES` of the request are looked at.
    """

    _head = b""
    _head_done = False

    def data_received(self, data: bytes) -> None:
        if not self._head_done:
            head = self._head + data
            end = head.find(b"\r\n\r\n")
            if end >= 0:
                self._head_done = True
                self._head = b""
                if end + 4 < len(head):
                    self.transport.write(
                        _response(
                            http.HTTPStatus.BAD_REQUEST,
                            b"one request per connection, with no body\n",
                        ).serialize()
                    )
                    self.transport.close()
                    return
            elif len(head) > _HEAD_BYTES:
                self._head_done = True  # websockets refuses oversized heads itself
                self._head = b""
            else:
                self._head = head
        super().data_received(data)


#: Headers a request must not repeat (RFC 6455 section 4.2.1; one credential).
_SINGLE_HEADERS = ("Upgrade", "Sec-WebSocket-Key", "Sec-WebSocket-Version", "Authorization")

#: Bytes of a request head :class:`_OneRequestConnection` keeps looking at.
_HEAD_BYTES = 64 * 1024


def _limit(message: str) -> PeerError:
    from realizer.service.errors import LimitExceeded

    return LimitExceeded(message)


def _same(given: str, expected: str) -> bool:
    return hmac.compare_digest(given.encode(), expected.encode())


def _render(message: Outgoing, fmt: FeedbackFormat) -> str | None:
    """A stage message as this submitter's text (XML mode has no block events)."""
    if isinstance(message, WireFeedback):
        if fmt == "xml":
            return message.xml
        return json.dumps(
            FeedbackMessage(
                type="feedback",
                character=message.character,
                kind=message.kind,
                block=message.block_id,
                time=message.time,
                xml=message.xml,
            )
        )
    assert isinstance(message, BlockEvent)
    if fmt == "xml":
        return None
    return json.dumps(
        BlockMessage(
            type="block",
            character=message.character,
            block=message.block_id,
            state=message.state,
            time=message.time,
        )
    )


def _response(status: http.HTTPStatus, body: bytes, content_type: str = "text/plain") -> Response:
    headers = Headers(
        [
            ("Content-Type", content_type),
            ("Content-Length", str(len(body))),
            ("Cache-Control", "no-store"),
            ("Connection", "close"),
        ]
    )
    return Response(status.value, status.phrase, headers, body)


def _json_response(data: dict[str, Any]) -> Response:
    return _response(http.HTTPStatus.OK, json.dumps(data).encode(), "application/json")


class _StaticFiles:
    """The browser viewer's files, from the package data (read once)."""

    _TYPES: ClassVar[dict[str, str]] = {
        ".html": "text/html; charset=utf-8",
        ".js": "text/javascript; charset=utf-8",
        ".css": "text/css; charset=utf-8",
        ".xml": "application/xml",
        ".json": "application/json",
    }

    def __init__(self) -> None:
        self._files: dict[str, tuple[bytes, str]] = {}
        root = resources.files("realizer.service") / "static"
        # one level of folders: static/vendor/three/ holds three.js (scripts/setup.sh)
        pending = [(root, "/static/", 0)]
        while pending:
            folder, prefix, depth = pending.pop()
            for entry in folder.iterdir():
                suffix = "." + entry.name.rpartition(".")[2]
                if entry.is_dir() and depth < 2:
                    pending.append((entry, prefix + entry.name + "/", depth + 1))
                elif entry.is_file() and suffix in self._TYPES:
                    self._files[prefix + entry.name] = (entry.read_bytes(), self._TYPES[suffix])
        if "/static/index.html" in self._files:
            self._files["/"] = self._files["/static/index.html"]

    def get(self, path: str) -> tuple[bytes, str] | None:
        return self._files.get(path)


class Attachment(Protocol):
    """Something that runs beside a service, such as the STOMP bridge
    (realizer.service.stomp): started after the service, stopped after its
    shutdown sequence (so the feedback of the blocks it ends still goes out)."""

    async def start(self, service: RealizerService) -> None: ...

    async def stop(self) -> None: ...


async def run_service(
    config: ServiceConfig,
    stage: Stage,
    assets: FaceAssets,
    *,
    ready: Callable[[RealizerService], None] | None = None,
    attachments: Sequence[Attachment] = (),
) -> int:
    """Serve until SIGINT or SIGTERM, then shut down cleanly; returns 0."""
    service = RealizerService(config, stage, assets)
    return await run_until_stopped(service, ready=ready, attachments=attachments)


async def run_until_stopped(
    service: RealizerService,
    *,
    ready: Callable[[RealizerService], None] | None = None,
    attachments: Sequence[Attachment] = (),
) -> int:
    """Start ``service`` (or a cluster worker or gateway) and its
    ``attachments``, serve until SIGINT or SIGTERM, then run its shutdown
    sequence and stop them; returns 0."""
    freeze_start_up_heap()
    await service.start()
    for attachment in attachments:
        await attachment.start(service)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    if ready is not None:
        ready(service)
    try:
        await stop.wait()
    finally:
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(signum)
        await service.shutdown()
        for attachment in attachments:
            await attachment.stop()
    return 0


def freeze_start_up_heap() -> None:
    """Leave what start-up made out of every later garbage collection.

    What a serving process loads before its clock starts (the face, the
    engines' data, the first session, the modules: some 50,000 objects)
    lives as long as the process, yet every full collection walked all of
    it: 15 to 30 ms with the event loop stopped, measured on the 2-core
    machine, so one or two late ticks and a skipped frame whenever the
    collector's thresholds asked for one. Collect once now, before the
    clock, then freeze the survivors (``gc.freeze``); later collections see
    only what the running service makes. A process-wide setting, so only the
    process entry points (:func:`run_until_stopped`) call it, not
    :meth:`RealizerService.start` (tests run many services in one process).
    """
    gc.collect()
    gc.freeze()


def serve_until_stopped(
    config: ServiceConfig,
    stage: Stage,
    assets: FaceAssets,
    *,
    ready: Callable[[RealizerService], None] | None = None,
    attachments: Sequence[Attachment] = (),
) -> int:
    """Run the service in a new event loop until SIGINT or SIGTERM; returns
    the exit status (0). The blocking entry point of ``realizer serve``."""
    return asyncio.run(run_service(config, stage, assets, ready=ready, attachments=attachments))


def run_until_stopped_blocking(
    service: RealizerService, *, ready: Callable[[RealizerService], None] | None = None
) -> int:
    """:func:`run_until_stopped` in a new event loop (the blocking entry
    point of ``realizer worker`` and ``realizer gateway``)."""
    return asyncio.run(run_until_stopped(service, ready=ready))
