"""``realizer worker``: runs characters for the cluster (protocols/cluster.md).

A worker is a :class:`~realizer.service.server.RealizerService` with its
frame clock, its :class:`~realizer.service.stage.Stage` and sessions, but
no submitters or viewers of its own: its port serves only ``/health`` and
``/version``. Instead it

* answers requests for the characters it owns (``realizer.v2.req.<c>``),
  and claims unowned characters offered on ``realizer.v2.claim`` (a queue
  group: one worker answers) by creating their lease;
* publishes every feedback message on ``realizer.v2.fb.<c>`` and each
  tick's frame, for each viewer format that some gateway wants, on
  ``realizer.v2.frame.<c>.<format>`` (frames carry this worker's clock):
  whole (encoded once per format) when what it shows changed since the
  last whole frame of that format, once a second, and every tick for a
  format some gateway's viewer wants whole; otherwise as a ``same`` of a
  few bytes, as ``realizer serve`` sends its viewers;
* renews its leases by compare-and-set, watches everyone's leases, and
  takes over a character whose lease it has seen unrenewed for the lease
  time (realizer.service.cluster.leases), ending the blocks the lost owner
  had open with a ``warningFeedback`` and an interrupted block end;
* on SIGTERM hands its characters over: it takes no new character, lets
  running blocks finish (up to ``drain_timeout``) while new BML for them
  waits at the gateway, and deletes each lease as soon as the character is
  idle, so the next request or a viewer makes another worker take it.

Every publish goes through one outbox in program order, so a request's
feedback always precedes its reply and a tick's feedback precedes the next.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import http
import logging
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from nats.aio.client import Client
from nats.aio.msg import Msg
from nats.aio.subscription import Subscription
from nats.js.errors import KeyWrongLastSequenceError
from nats.js.kv import KeyValue
from websockets.asyncio.server import ServerConnection
from websockets.http11 import Request

from realizer.feedback import block_progress
from realizer.service.cluster.bus import (
    HOST,
    ClusterConfig,
    connect,
    default_node_id,
    lease_bucket,
)
from realizer.service.cluster.leases import LeaseTable, ObservedLease
from realizer.service.cluster.protocol import (
    CLUSTER_LIMITS,
    CLUSTER_VERSION,
    SUBJECT_CLAIM,
    SUBJECT_WANT,
    WORKER_QUEUE,
    ClusterMessageError,
    Formats,
    FrameTick,
    LeaseValue,
    OwnerReply,
    OwnerRequest,
    content_id,
    feedback_subject,
    frame_subject,
    pack_feedback,
    request_subject,
    token,
    unpack_want,
    untoken,
)
from realizer.service.cluster.timing import Durations, summaries
from realizer.service.messages import ViewOptions, warning_feedback_xml
from realizer.service.server import (
    FaceAssets,
    RealizerService,
    ServiceConfig,
    Submitter,
    _response,
)
from realizer.service.stage import (
    CODED_INTRA_SECONDS,
    BlockEvent,
    CharacterTick,
    Outgoing,
    Stage,
    WireFeedback,
)

logger = logging.getLogger("realizer.cluster")

#: Messages the outbox may hold while NATS is slow or away; over it the
#: oldest are dropped (and counted): frames are superseded anyway, and an
#: owner that cannot publish for long loses its leases.
OUTBOX_LIMIT = 65536
#: Gateways whose interest a worker keeps.
MAX_GATEWAYS = 256


@dataclass(eq=False, slots=True)
class Owned:
    """A character this worker owns: the lease revision it last wrote and
    when (monotonic seconds), and its request subscription."""

    revision: int
    renewed: float
    subscription: Subscription | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    dirty: bool = False
    recorded: tuple[str, ...] = ()  # the open blocks the lease last said
    held: list[Outgoing] = field(default_factory=list)  # feedback while not fresh


@dataclass(slots=True)
class FrameStreams:
    """What a character's owner last published in each viewer format.

    ``version``, ``content``: the encoder's content version last seen and
    its :func:`~realizer.service.cluster.protocol.content_id`; ``sent``:
    per format, the content id of the last whole frame published; ``force``:
    formats whose next tick goes whole (a gateway began to want it, or a
    coded viewer joined and its intra frame must reach it)."""

    version: int = -1
    content: int = 0
    sent: dict[ViewOptions, int] = field(default_factory=dict)
    force: set[ViewOptions] = field(default_factory=set)


class ClusterWorker(RealizerService):
    """A worker; ``await start()``, then ``await shutdown()`` (graceful)."""

    def __init__(
        self, config: ServiceConfig, stage: Stage, assets: FaceAssets, cluster: ClusterConfig
    ) -> None:
        super().__init__(config, stage, assets)
        self.cluster = cluster
        self.worker_id = cluster.node_id or default_node_id("worker")
        self.table = LeaseTable(cluster.lease_ttl)
        self.owned: dict[str, Owned] = {}
        #: per gateway: when last heard, its formats per character, and those
        #: of them that some viewer there wants whole every tick
        self.wants: dict[str, tuple[float, Formats, Formats]] = {}
        self.wanted: Formats = {}
        self.every: Formats = {}
        self.streams: dict[str, FrameStreams] = {}
        self.frames_whole = 0
        self.frames_same = 0
        self.draining = False
        self.takeovers = 0
        self.lost_blocks = 0
        self.dropped = 0
        self.nats: Client | None = None
        self.kv: KeyValue | None = None
        #: (subject, body, frame due time in loop seconds or 0.0) to publish, in order
        self._outbox: deque[tuple[str, bytes, float]] = deque()
        #: request: a bml request's arrival -> its reply; plan: its parse and
        #: plan; lease_write: the lease write that records the accepted
        #: block; frame_published: a frame's due time -> handed to NATS
        self.timings = {
            name: Durations() for name in ("request", "plan", "lease_write", "frame_published")
        }
        self._outbox_wake = asyncio.Event()
        self._claims: Subscription | None = None
        self.idle_epoch = 0.0  # set at start

    # -- life cycle ---------------------------------------------------------------

    async def start(self) -> None:
        await super().start()
        # the Unix time of this worker's frame 0: its characters' idle time
        self.idle_epoch = time.time() - self.now()
        self.nats = await connect(self.cluster, self.worker_id)
        self.kv = await lease_bucket(self.nats)
        watcher = await self.kv.watchall()
        self._spawn(self._publish_outbox())
        self._spawn(self._watch_leases(watcher))
        await self.nats.subscribe(SUBJECT_WANT, cb=self._on_want)
        self._claims = await self.nats.subscribe(
            SUBJECT_CLAIM, queue=WORKER_QUEUE, cb=self._on_claim
        )
        await self.nats.flush()
        self._spawn(self._keep_leases())

    async def shutdown(self, reason: str = "worker shutting down") -> None:
        """Hand over, then stop: no new characters; each owned character is
        released as soon as it has no open block; after ``drain_timeout``
        the rest are interrupted (their submitters get the end feedback) and
        released; then the service's own shutdown sequence."""
        if self._stopping or self.nats is None:
            await super().shutdown(reason)
            return
        self.draining = True
        loop = asyncio.get_running_loop()
        with contextlib.suppress(Exception):
            if self._claims is not None:
                await self._claims.unsubscribe()
        deadline = loop.time() + self.cluster.drain_timeout
        while self.owned and loop.time() < deadline:
            for character in list(self.owned):
                found = self.stage.characters.get(character)
                if found is None or not found.open_blocks:
                    await self._release(character)
            await asyncio.sleep(0.02)
        await super().shutdown(reason)  # interrupts what is left, publishes its feedback
        for character in list(self.owned):
            await self._release(character)
        # The outbox task was cancelled with the others: flush by hand.
        with contextlib.suppress(Exception):
            while self._outbox:
                subject, data, _ = self._outbox.popleft()
                await self.nats.publish(subject, data)
            await self.nats.flush(timeout=max(1, int(self.config.shutdown_timeout)))
        with contextlib.suppress(Exception):
            await self.nats.close()

    # -- what this process serves over HTTP ----------------------------------------

    def _process_request(self, connection: ServerConnection, request: Request) -> Any:
        if urlsplit(request.path).path in ("/health", "/version"):
            return super()._process_request(connection, request)
        return _response(
            http.HTTPStatus.NOT_FOUND,
            b"this is a realizer cluster worker: it serves /health and /version; "
            b"submitters and viewers connect to a gateway\n",
        )

    def health(self) -> dict[str, Any]:
        report = super().health()
        report.update(
            role="worker",
            worker=self.worker_id,
            cluster=CLUSTER_VERSION,
            draining=self.draining,
            owned=sorted(self.owned),
            takeovers=self.takeovers,
            lostBlocks=self.lost_blocks,
            droppedMessages=self.dropped,
            framesWhole=self.frames_whole,
            framesSame=self.frames_same,
            idleEpoch=self.idle_epoch,
            nats=bool(self.nats is not None and self.nats.is_connected),
            timings=summaries(self.timings),
        )
        return report

    # -- publishing -------------------------------------------------------------------

    def _send(self, subject: str, data: bytes, due: float = 0.0) -> None:
        if len(self._outbox) >= OUTBOX_LIMIT:
            self._outbox.popleft()
            self.dropped += 1
        self._outbox.append((subject, data, due))
        self._outbox_wake.set()

    async def _publish_outbox(self) -> None:
        assert self.nats is not None
        loop = asyncio.get_running_loop()
        published = self.timings["frame_published"]
        while True:
            while not self._outbox:
                self._outbox_wake.clear()
                await self._outbox_wake.wait()
            subject, data, due = self._outbox.popleft()
            try:
                await self.nats.publish(subject, data)
            except Exception as exc:  # disconnected, buffer full: the message is lost
                self.dropped += 1
                logger.debug("publish on %s failed: %s", subject, exc)
                continue
            if due:
                published.add(loop.time() - due)

    def _dispatch(self, messages: Any, also: Submitter | None = None) -> None:
        """The clock's and the shutdown's feedback goes to the gateways.

        Feedback of a character whose lease this worker could not renew for
        half its time is held back (bounded) until a renewal succeeds, and
        dropped when another worker turns out to own it: a paused owner
        that comes back must not report progress of blocks the new owner
        has already ended."""
        ready: list[Outgoing] = []
        for message in messages:
            owned = self.owned.get(message.character)
            if owned is not None and (owned.held or not self._fresh(owned)):
                if len(owned.held) < self.limits.feedback_backlog:
                    owned.held.append(message)
            else:
                ready.append(message)
        self._publish_feedback(ready)

    def _publish_feedback(self, messages: Any, reply_to: str = "", follow: bool = False) -> None:
        for message in messages:
            self._send(
                feedback_subject(message.character), pack_feedback(message, reply_to, follow)
            )
            if isinstance(message, BlockEvent) and message.state in ("done", "interrupted"):
                owned = self.owned.get(message.character)
                if owned is not None:
                    owned.dirty = True  # the lease's open blocks changed

    def _deliver_frame(self, number: int, character_tick: CharacterTick) -> None:
        """Publish this tick of the character in each format some gateway
        wants: whole, or as a ``same`` when it shows what the format's last
        whole frame showed, by ``realizer serve``'s rule for its viewers.

        Whole in a format: when the content changed since that format's
        last whole frame; once a second (the coded stream's intra frames,
        and a key frame for a gateway that lost one: it then knows the
        content again, protocols/cluster.md); every tick for a format that
        some gateway's viewer wants whole (it asked for no ``same``); and on
        the tick after a gateway began to want the format. A coded frame
        goes whole whenever the coder codes one, so no coded viewer's
        prediction chain is broken (as in ``realizer serve``)."""
        character = character_tick.character
        formats = self.wanted.get(character)
        owned = self.owned.get(character)
        if not formats or owned is None or not self._fresh(owned):
            return
        encoder = self._encoder(character)
        streams = self.streams.get(character)
        if streams is None:
            streams = self.streams[character] = FrameStreams()
        version = encoder.observe(character_tick.frame)
        if version != streams.version:
            streams.version = version
            streams.content = content_id(character_tick.frame.mask, character_tick.frame.values)
        content = streams.content
        key_due = number % max(1, round(self.config.fps * CODED_INTRA_SECONDS)) == 0
        every = self.every.get(character, frozenset())
        whole = {
            options
            for options in formats
            if key_due
            or options in every
            or options in streams.force
            or streams.sent.get(options) != content
        }
        encoded = (
            encoder.encode(number, character_tick.time, character_tick.frame, whole)
            if whole
            else {}
        )
        due = self._start + number / self.config.fps
        same = b""
        for options in formats:
            data = encoded.get(options)
            if data is not None:
                streams.sent[options] = content
                streams.force.discard(options)
                tick = FrameTick(number, character_tick.time, content, data)
                self._send(frame_subject(character, options), tick.pack(), due)
                self.frames_whole += 1
            elif options not in whole:
                same = same or FrameTick(number, character_tick.time, content).pack()
                self._send(frame_subject(character, options), same, due)
                self.frames_same += 1
            # else: wanted whole but not encoded yet (the ARKit fit is being
            # set up): nothing this tick, as realizer serve's viewers get

    # -- requests -----------------------------------------------------------------------

    def _reply(self, msg: Msg, reply: OwnerReply) -> None:
        if msg.reply:
            self._send(msg.reply, reply.pack())

    async def _on_claim(self, msg: Msg) -> None:
        try:
            request = OwnerRequest.unpack(msg.data)
        except ClusterMessageError as exc:
            self._reply(msg, OwnerReply("error", self.worker_id, str(exc)))
            return
        character = request.character
        if character in self.owned:
            await self._carry_out(request, msg)
            return
        if self.draining:
            self._reply(msg, OwnerReply("retry", self.worker_id, "worker leaving"))
            return
        lease = self.table.leases.get(character)
        if request.op == "interrupt" and lease is None:
            self._reply(msg, OwnerReply("none", self.worker_id, f"no character {character!r}"))
            return
        if not self._has_room():
            self._reply(msg, OwnerReply("full", self.worker_id, "worker full"))
            return
        viewer = request.op == "view"
        if lease is None and viewer and not self._viewer_room():
            # As realizer serve: viewers cannot take the submitters' characters.
            reason = (
                f"limit of {self.limits.viewer_characters} characters made for viewers "
                f"reached; character {character!r} not created"
            )
            self._reply(msg, OwnerReply("error", self.worker_id, reason))
            return
        if lease is None:
            won = await self._create(character, for_viewer=viewer)
        elif time.monotonic() - lease.seen > self.table.ttl:
            won = await self._take_over(lease)
        else:
            won = False
        if won:
            await self._carry_out(request, msg)
        else:
            self._reply(msg, OwnerReply("retry", self.worker_id, "owned elsewhere"))

    async def _on_request(self, msg: Msg) -> None:
        arrived = time.perf_counter()
        try:
            request = OwnerRequest.unpack(msg.data)
            if request_subject(request.character) != msg.subject:
                raise ClusterMessageError("request for another character")
        except ClusterMessageError as exc:
            self._reply(msg, OwnerReply("error", self.worker_id, str(exc)))
            return
        await self._carry_out(request, msg)
        if request.op == "bml":
            self.timings["request"].add(time.perf_counter() - arrived)

    async def _carry_out(self, request: OwnerRequest, msg: Msg) -> None:
        """Carry out a request for a character this worker owns, on the
        stage, exactly as ``realizer serve`` does for its own submitters."""
        character = request.character
        owned = self.owned.get(character)
        leaving = self.draining and request.op != "interrupt"
        if owned is None or leaving or not self._fresh(owned):
            self._reply(msg, OwnerReply("retry", self.worker_id, "not the owner now"))
            return
        now = self.now()
        if request.op == "bml":
            # Parsed and planned on a planner thread, as realizer serve does:
            # the clock of every character here never waits for a submitter.
            # Requests of one character stay in order (one subscription's
            # callbacks run one at a time).
            planning = time.perf_counter()
            try:
                result = await asyncio.get_running_loop().run_in_executor(
                    self._planner,
                    functools.partial(
                        self.stage.submit_bml,
                        request.bml,
                        now,
                        character=character,
                        strict=request.strict,
                        clock=self._now_any_thread,  # a slow TTS runs first, as in serve
                    ),
                )
            except RuntimeError:  # the planner is shut down: the worker is stopping
                self._reply(msg, OwnerReply("retry", self.worker_id, "worker stopping"))
                return
            self.timings["plan"].add(time.perf_counter() - planning)
            current = self.owned.get(character)
            if current is None:  # lost while it was planned
                self._publish_feedback(result.messages, request.reply_to)
                self._drop(character)  # submit_bml made it again on the stage
                if result.accepted:
                    why = f"{self.worker_id} lost character {character!r} while planning it"
                    self._end_lost_blocks(character, [result.block_id], why)
                self._reply(msg, OwnerReply("ok", self.worker_id))
                return
            owned = current
            self._publish_feedback(
                result.messages, request.reply_to, character in self.stage.characters
            )
            if result.accepted:
                # Record the open block before answering, so a taker-over
                # knows to end it if this worker dies now.
                owned.dirty = True
                writing = time.perf_counter()
                await self._write_lease(character)
                self.timings["lease_write"].add(time.perf_counter() - writing)
        elif request.op == "interrupt":
            messages = self.stage.interrupt(character, request.block, now)
            self._publish_feedback(messages, request.reply_to)
        else:
            encoder = self._encoder(character)
            if request.intra:
                encoder.want_intra()
                # the intra frame goes whole, so the joining viewer gets it
                streams = self.streams.setdefault(character, FrameStreams())
                streams.force.update(o for o in self.wanted.get(character, ()) if o.coded)
            model = encoder.model_bytes if request.model else b""
            self._reply(msg, OwnerReply("ok", self.worker_id, mesh=encoder.mesh_bytes, model=model))
            return
        self._reply(msg, OwnerReply("ok", self.worker_id))

    # -- viewers' interest ----------------------------------------------------------------

    async def _on_want(self, msg: Msg) -> None:
        try:
            gateway, wants, every = unpack_want(msg.data)
        except ClusterMessageError as exc:
            logger.warning("ignored a want message: %s", exc)
            return
        if gateway not in self.wants and len(self.wants) >= MAX_GATEWAYS:
            return
        before = self.wants.get(gateway, (0.0, {}, {}))[1]
        for character, formats in wants.items():
            streams = self.streams.get(character)
            added = formats - before.get(character, frozenset())
            if streams is not None and added:
                # that gateway has no whole frame of these yet: send one next tick
                streams.force.update(added)
        self.wants[gateway] = (time.monotonic(), wants, every)
        self._recompute_wanted()

    def _recompute_wanted(self) -> None:
        wanted: dict[str, set[ViewOptions]] = {}
        every: dict[str, set[ViewOptions]] = {}
        for _, wants, whole in self.wants.values():
            for character, formats in wants.items():
                wanted.setdefault(character, set()).update(formats)
            for character, formats in whole.items():
                every.setdefault(character, set()).update(formats)
        self.wanted = {character: frozenset(formats) for character, formats in wanted.items()}
        self.every = {character: frozenset(formats) for character, formats in every.items()}

    def _forget_idle_characters(self, now: float) -> None:
        """Free characters with no open block for ``character_idle_seconds``
        that no gateway's viewer watches, and give their leases back.

        The service's own rule keeps the characters of its local viewers and
        submitters; a worker has none (they are at the gateways), so that
        rule freed characters still watched through a gateway while the
        worker kept their leases: their viewers got no frames any more."""
        for character in self.stage.forget_idle(
            now, self.limits.character_idle_seconds, keep=self.wanted
        ):
            self.encoders.pop(character, None)
            self.streams.pop(character, None)
            owned = self.owned.pop(character, None)  # at once: no request is taken now
            if owned is not None:
                self._spawn(self._give_back(character, owned))

    # -- leases ---------------------------------------------------------------------------

    def _has_room(self) -> bool:
        return len(self.stage.characters) < self.limits.characters

    def _fresh(self, owned: Owned) -> bool:
        """Whether this worker may still act as owner (renewed within ttl/2)."""
        return time.monotonic() - owned.renewed < self.table.ttl / 2

    def _lease_value(self, character: str) -> LeaseValue:
        found = self.stage.characters.get(character)
        blocks = tuple(found.open_blocks)[: CLUSTER_LIMITS.lease_blocks] if found else ()
        return LeaseValue(self.worker_id, blocks, HOST, self._start)

    def _viewer_room(self) -> bool:
        """Whether viewers alone may make one more character here
        (``limits.viewer_characters``, counted per worker)."""
        made = sum(1 for c in self.stage.characters.values() if c.viewer_made)
        return made < self.limits.viewer_characters

    async def _create(self, character: str, *, for_viewer: bool = False) -> bool:
        assert self.kv is not None
        try:
            revision = await self.kv.create(token(character), self._lease_value(character).pack())
        except KeyWrongLastSequenceError:
            return False
        return await self._own(character, revision, for_viewer=for_viewer)

    async def _take_over(self, lease: ObservedLease) -> bool:
        """Compare-and-set on the revision seen unrenewed: one worker wins."""
        assert self.kv is not None
        character = lease.character
        try:
            revision = await self.kv.update(
                token(character), self._lease_value(character).pack(), last=lease.revision
            )
        except KeyWrongLastSequenceError:
            return False
        if not await self._own(character, revision):
            return False
        self.takeovers += 1
        self._end_lost_blocks(
            character,
            lease.value.blocks,
            f"the realizer that ran it ({lease.value.owner or 'unknown'}) stopped; "
            f"character {character!r} is now run by {self.worker_id}",
        )
        logger.warning(
            "took over character %r from %s (%d blocks lost)",
            character,
            lease.value.owner,
            len(lease.value.blocks),
        )
        return True

    def _end_lost_blocks(self, character: str, blocks: Iterable[str], why: str) -> None:
        """End blocks nobody will run any more: a ``warningFeedback``
        saying why, the block's end (interrupted) and its block event."""
        now = self.now()
        lost: list[Outgoing] = []
        for block in blocks:
            text = f"block {block!r} was lost: {why}"
            xml = warning_feedback_xml(block, character, "CANNOT_CREATE_BEHAVIOR", text)
            end = block_progress(block, "end", now, character, status="INTERRUPTED")
            lost += [
                WireFeedback(character, "warning", block, now, xml),
                WireFeedback(character, end.kind, block, now, end.xml),
                BlockEvent(character, block, "interrupted", now),
            ]
            self.lost_blocks += 1
        self._publish_feedback(lost)

    async def _own(self, character: str, revision: int, *, for_viewer: bool = False) -> bool:
        assert self.nats is not None and self.kv is not None
        try:
            found = self.stage.character(character, for_viewer=for_viewer)
        except Exception as exc:  # a limit reached meanwhile: give the lease back
            logger.warning("cannot run character %r: %s", character, exc)
            with contextlib.suppress(Exception):
                await self.kv.delete(token(character), last=revision)
            return False
        session = found.session
        if session.idle is not None:
            # The idle motion follows the wall clock here, not this worker's
            # own (realizer.face.idle): a new owner carries on the pose.
            session.idle.offset = self.idle_epoch
        owned = Owned(revision, time.monotonic())
        self.owned[character] = owned
        owned.subscription = await self.nats.subscribe(
            request_subject(character), cb=self._on_request
        )
        await self.nats.flush()
        return True

    async def _write_lease(self, character: str) -> bool:
        """Renew (compare-and-set) the lease of an owned character."""
        assert self.kv is not None
        owned = self.owned.get(character)
        if owned is None:
            return False
        async with owned.lock:
            if self.owned.get(character) is not owned:
                return False
            owned.dirty = False
            value = self._lease_value(character)
            try:
                revision = await self.kv.update(token(character), value.pack(), last=owned.revision)
            except KeyWrongLastSequenceError:
                self._lose(character, "its lease was taken over")
                return False
            except Exception as exc:  # NATS away or slow: try again next round
                logger.debug("lease renewal of %r failed: %s", character, exc)
                owned.dirty = True
                return False
            owned.revision = revision
            owned.renewed = time.monotonic()
            owned.recorded = value.blocks
            if owned.held:
                held, owned.held = owned.held, []
                self._publish_feedback(held)
            return True

    def _lose(self, character: str, why: str) -> None:
        """Stop running ``character`` at once (another worker owns it)."""
        owned = self.owned.pop(character, None)
        if owned is None:
            return
        logger.warning("lost character %r: %s", character, why)
        if owned.subscription is not None:
            self._spawn(owned.subscription.unsubscribe())
        # The taker-over ends the blocks the lease recorded; the ones
        # accepted since then only this worker knows of: end them here.
        found = self.stage.characters.get(character)
        unrecorded = [b for b in (found.open_blocks if found else ()) if b not in owned.recorded]
        self._end_lost_blocks(
            character, unrecorded, f"{self.worker_id} lost character {character!r} ({why})"
        )
        self._drop(character)

    async def _release(self, character: str) -> None:
        """Give a character up on purpose: delete its lease."""
        owned = self.owned.pop(character, None)
        if owned is None:
            return
        await self._give_back(character, owned)
        self._drop(character)

    async def _give_back(self, character: str, owned: Owned) -> None:
        """Stop taking requests for a character no longer owned here, and
        delete its lease (if nobody has taken it meanwhile)."""
        assert self.kv is not None
        with contextlib.suppress(Exception):
            if owned.subscription is not None:
                await owned.subscription.unsubscribe()
            await self.kv.delete(token(character), last=owned.revision)

    def _drop(self, character: str) -> None:
        # The stage has no removal of its own: a character it no longer
        # runs is simply forgotten, with its encoder.
        self.stage.characters.pop(character, None)
        self.encoders.pop(character, None)
        self.streams.pop(character, None)

    async def _watch_leases(self, watcher: Any) -> None:
        async for entry in watcher:
            if entry is None:
                continue  # the end of the initial values
            character = untoken(entry.key)
            deleted = entry.operation in ("DEL", "PURGE")
            self.table.observe(
                character, entry.revision, None if deleted else entry.value, time.monotonic()
            )
            owner = self.table.owner(character)
            if character in self.owned and owner is not None and owner != self.worker_id:
                self._lose(character, f"taken over by {owner}")

    async def _keep_leases(self) -> None:
        """Renew, take over the expired, pick up what viewers want."""
        ttl = self.table.ttl
        while True:
            await asyncio.sleep(ttl / 16)
            try:
                await self._lease_round(ttl)
            except Exception:
                logger.exception("lease round failed")

    async def _lease_round(self, ttl: float) -> None:
        now = time.monotonic()
        for character, owned in list(self.owned.items()):
            if owned.dirty or now - owned.renewed >= ttl / 4:
                await self._write_lease(character)
        stale = [
            g
            for g, (seen, _, _) in self.wants.items()
            if now - seen > 3.5 * self.cluster.want_interval
        ]
        for gateway in stale:
            del self.wants[gateway]
        if stale:
            self._recompute_wanted()
        if self.draining:
            return
        for lease in self.table.expired(time.monotonic()):
            if lease.character in self.owned or lease.value.owner == self.worker_id:
                continue
            if not self._has_room():
                break
            await self._take_over(lease)
        for character in list(self.wanted):
            if character in self.owned or character in self.table.leases:
                continue
            if not self._has_room() or not self._viewer_room():
                break
            await self._create(character, for_viewer=True)
