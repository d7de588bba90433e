"""``realizer gateway``: the service's endpoints, no characters (protocols/cluster.md).

A gateway is a :class:`~realizer.service.server.RealizerService` without a
clock whose stage stays empty: it serves the same ``/bml``, ``/view``,
``/``, ``/health`` and ``/version``, with the same tokens, limits, close
codes and messages, so a client cannot tell it from ``realizer serve``.
What ``realizer serve`` does on its stage, a gateway asks of the
character's owner over NATS:

* a submitter's BML goes to the character it names (the same precedence
  as ``realizer serve``: the envelope's ``character``, the block's
  ``characterId``, the connection's character) as a request on
  ``realizer.v2.req.<c>``; where no worker answers there, on the claim
  subject, where one worker takes the character; while a character is
  between owners (a worker died or is leaving) the gateway asks again until
  ``owner_wait`` has passed, then refuses the block with a warning;
* feedback comes from ``realizer.v2.fb.*`` and goes to the submitters that
  follow the character, and to the one that sent the request;
* a viewer's frames come from ``realizer.v2.frame.<c>.*``, subscribed while
  the character has viewers here, one frame tick per tick and format:
  a whole frame (offered to each viewer's one-frame mailbox as the owner
  encoded it, never decoded or retimed) or a ``same``; each viewer gets
  what ``realizer serve`` would send it: a ``same`` when it asked for
  them and already has what the tick shows, else the whole frame (for one
  that just joined on a ``same`` tick, the last whole frame of that
  content moved to this tick's ``n`` and ``t``), and nothing on a tick
  whose content this gateway never received whole (a lost NATS message)
  until the next whole frame (at most a second later). Ticks are fanned
  out once the ones at hand are read (the newest two of each character
  and format: a backlog is not sent in turn). The gateway tells the
  workers which formats its viewers want (``realizer.v2.want``);
* when a character's owner changes (a lease watched in the bucket), its
  viewers get the mesh message again: a new subscription, whose frames
  carry the new owner's clock.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, cast

import nats.errors
from lxml import etree
from nats.aio.client import Client
from nats.aio.msg import Msg
from nats.aio.subscription import Subscription

from realizer.service import codec
from realizer.service.cluster.bus import (
    HOST,
    ClusterConfig,
    connect,
    default_node_id,
    lease_bucket,
)
from realizer.service.cluster.leases import LeaseTable
from realizer.service.cluster.protocol import (
    CLUSTER_VERSION,
    FEEDBACK_WILDCARD,
    PREFIX,
    SUBJECT_CLAIM,
    SUBJECT_WANT,
    ClusterMessageError,
    FrameTick,
    OwnerReply,
    OwnerRequest,
    format_key,
    frame_wildcard,
    pack_want,
    request_subject,
    restamp,
    unpack_feedback,
    untoken,
)
from realizer.service.cluster.timing import Durations, summaries
from realizer.service.errors import BadMessage, CloseCode, LimitExceeded, PeerError
from realizer.service.limits import valid_character_id
from realizer.service.messages import (
    SubmitterRequest,
    ViewOptions,
    read_submitter_message,
    warning_feedback_xml,
)
from realizer.service.server import (
    WRITE_LIMIT,
    FaceAssets,
    RealizerService,
    ServiceConfig,
    Submitter,
    Viewer,
    _render,
    binary_frame,
)
from realizer.service.stage import BlockEvent, Outgoing, Stage, WireFeedback

logger = logging.getLogger("realizer.cluster")

#: The part of a BML document read to find its ``characterId`` (bytes).
ROOT_SCAN_BYTES = 4096
#: Frame ticks of one character and format a fan-out sends at most: the
#: newest of those read since the last one, and the one before it (a worker
#: whose clock ran two ticks back to back publishes them in one write: both
#: go out); older ones are superseded (the gateway is behind).
FRAMES_KEPT = 2
#: Characters whose last whole frames a gateway keeps (per format) beyond
#: those its viewers watch.
STREAMS_KEPT = 64
#: Messages of one submitter forwarded at once (to different characters;
#: each character's in order); the connection's next message is read when
#: one of them is done.
IN_FLIGHT = 16


@dataclass(slots=True)
class LastWhole:
    """A character's last whole frame in one format at this gateway, and
    its content id: what a viewer that needs a whole frame on a ``same``
    tick of that content is sent (moved to the tick)."""

    content: int
    frame: bytes


class NoOwner(PeerError):
    """No worker took the character within the gateway's wait."""

    warning_type = "CANNOT_CREATE_BEHAVIOR"
    close_code = CloseCode.TRY_AGAIN_LATER


def root_attribute(text: str, name: str) -> str | None:
    """An attribute of a BML document's root element (``characterId``,
    ``id``), or None.

    Reads only the root's start tag, with lxml's incremental parser fed at
    most :data:`ROOT_SCAN_BYTES` bytes (linear, no regular expression); a
    document it cannot read goes to the connection's character, whose owner
    then answers the parse error as ``realizer serve`` would.
    """
    parser = etree.XMLPullParser(events=("start",), resolve_entities=False, no_network=True)
    # A syntax error after the root's start tag (the rest is the owner's to
    # judge) still leaves the start event to read.
    with contextlib.suppress(etree.XMLSyntaxError):
        parser.feed(text[:ROOT_SCAN_BYTES].encode("utf-8", "replace"))
    for _, element in parser.read_events():
        if isinstance(element, etree._Element):
            value = element.get(name)
            return value if isinstance(value, str) else None
        return None
    return None


def _no_session(character_id: str) -> Any:
    raise RuntimeError("a gateway holds no character")


class ClusterGateway(RealizerService):
    """A gateway; ``await start()``, then ``await shutdown()``."""

    runs_clock = False

    def __init__(
        self,
        config: ServiceConfig,
        cluster: ClusterConfig,
        default_character: str = "default",
    ) -> None:
        # The stage only answers what needs no character (the refusal of an
        # interrupt for a character nobody made); the face is the workers'.
        stage = Stage(_no_session, config.limits, default_character)
        super().__init__(config, stage, cast(FaceAssets, None))
        self.cluster = cluster
        self.gateway_id = cluster.node_id or default_node_id("gateway")
        self.table = LeaseTable(cluster.lease_ttl)
        self.nats: Client | None = None
        self.meshes: dict[str, bytes] = {}
        self.models: dict[str, bytes] = {}
        self.by_format: dict[str, dict[str, set[Viewer]]] = {}
        self.frames_received = 0
        #: frames superseded at the gateway before its fan-out ran (it was behind)
        self.frames_superseded = 0
        #: per (character, format key) the newest frame ticks not yet fanned
        #: out (at most FRAMES_KEPT, oldest first), each with its due time on
        #: this host's loop clock (0.0: not known)
        self._newest: dict[tuple[str, str], list[tuple[FrameTick, float]]] = {}
        #: per (character, format key) the last whole frame received
        self._whole: dict[tuple[str, str], LastWhole] = {}
        #: the owner before its lease was deleted, of characters watched here
        self._last_owner: dict[str, str] = {}
        self.frames_restamped = 0  # whole frames made here for a viewer on a same tick
        self.frames_unknown = 0  # same ticks of a content never received whole here
        #: per submitter, the last forwarding task of each character
        self._lanes: dict[Submitter, dict[str, asyncio.Task[None]]] = {}
        #: forward: a bml message's arrival -> the owner's reply (the block
        #: accepted or refused); frame_received, frame_written: a frame's due
        #: time on its owner's clock -> read from NATS here, -> written to
        #: the last viewer here (owners on this host only)
        self.timings = {
            name: Durations() for name in ("forward", "frame_received", "frame_written")
        }
        self._fan_out_due = False
        self._frame_subscriptions: dict[str, Subscription] = {}
        self._want_changed = asyncio.Event()
        self._subscribing = asyncio.Lock()

    # -- life cycle ---------------------------------------------------------------

    async def start(self) -> None:
        self.nats = await connect(self.cluster, self.gateway_id)
        kv = await lease_bucket(self.nats)
        watcher = await kv.watchall()
        await self.nats.subscribe(FEEDBACK_WILDCARD, cb=self._on_feedback)
        await self.nats.flush()
        await super().start()
        self._spawn(self._watch_leases(watcher))
        self._spawn(self._announce())

    async def shutdown(self, reason: str = "server shutting down") -> None:
        await super().shutdown(reason)
        if self.nats is not None:
            with contextlib.suppress(Exception):
                await self.nats.close()

    def health(self) -> dict[str, Any]:
        report = super().health()
        report.update(
            role="gateway",
            gateway=self.gateway_id,
            cluster=CLUSTER_VERSION,
            characters=len(self.table.leases),
            characterIds=sorted(self.table.leases),
            workers=sorted(self.table.owners()),
            framesReceived=self.frames_received,
            framesSuperseded=self.frames_superseded,
            framesRestamped=self.frames_restamped,
            framesUnknown=self.frames_unknown,
            nats=bool(self.nats is not None and self.nats.is_connected),
            timings=summaries(self.timings),
        )
        report.pop("frame", None)
        return report

    # -- asking owners ------------------------------------------------------------

    def _submitter_name(self, submitter: Submitter) -> str:
        return f"{self.gateway_id}/{id(submitter)}"

    async def _ask(self, request: OwnerRequest) -> OwnerReply:
        """The owner's reply, finding or making an owner; raises
        :class:`NoOwner` after ``owner_wait`` seconds without one."""
        assert self.nats is not None
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.cluster.owner_wait
        payload = request.pack()
        timeout = self.cluster.request_timeout
        pause = 0.02
        last = "no worker answered"
        while True:
            for subject in (request_subject(request.character), SUBJECT_CLAIM):
                try:
                    msg = await self.nats.request(subject, payload, timeout=timeout)
                except nats.errors.NoRespondersError:
                    continue  # no owner: claim; no worker at all: wait
                except nats.errors.TimeoutError:
                    last = "a worker did not answer in time"
                    break
                try:
                    reply = OwnerReply.unpack(msg.data)
                except ClusterMessageError as exc:
                    logger.warning("unreadable reply from a worker: %s", exc)
                    break
                if reply.status in ("ok", "none", "error"):
                    return reply
                last = reply.reason or reply.status
                break  # retry / full: ask again after a pause
            if loop.time() + pause > deadline:
                raise NoOwner(
                    f"no realizer took character {request.character!r} within "
                    f"{self.cluster.owner_wait:g} s ({last})"
                )
            await asyncio.sleep(pause)
            pause = min(pause * 2, 0.2)

    async def _on_submit(self, submitter: Submitter, text: str) -> None:
        """What ``realizer serve`` does with a submitter message, with the
        stage's work done by the character's owner.

        A character's messages are forwarded one at a time, in the order
        they came (each waits for the owner's reply to the one before);
        messages to different characters are forwarded at once, up to
        :data:`IN_FLIGHT` per submitter, beyond which the connection's next
        message is read only when one of them is done. So one character's
        slow round (its owner's plan and lease write) does not hold back a
        block for another, as it did when every message waited for the one
        before it."""
        now = self.now()
        try:
            request = read_submitter_message(text)
        except BadMessage as exc:  # the sender's own mistake: told to the sender alone
            xml = warning_feedback_xml(
                "", submitter.default_character, exc.warning_type, exc.message
            )
            warning = WireFeedback(submitter.default_character, "warning", "", now, xml)
            self._push(submitter, _render(warning, submitter.format))
            return
        character = self._character_of(submitter, request)
        lanes = self._lanes.setdefault(submitter, {})
        before = lanes.get(character)
        task = self._spawn(self._forward_in_turn(before, submitter, request, character, now))
        lanes[character] = task

        def done(finished: asyncio.Task[None]) -> None:
            if lanes.get(character) is finished:
                del lanes[character]
            if not lanes and self._lanes.get(submitter) is lanes:
                del self._lanes[submitter]

        task.add_done_callback(done)
        if len(lanes) >= IN_FLIGHT:
            await asyncio.wait(list(lanes.values()), return_when=asyncio.FIRST_COMPLETED)

    def _character_of(self, submitter: Submitter, request: SubmitterRequest) -> str:
        """The character a message goes to, with ``realizer serve``'s
        precedence (the envelope's, the block's ``characterId``, the
        connection's)."""
        if request["type"] == "bml":
            return (
                request.get("character")
                or root_attribute(request["bml"], "characterId")
                or submitter.default_character
            )
        if request["type"] == "target":
            return ""
        return request.get("character", submitter.default_character)

    async def _forward_in_turn(
        self,
        before: asyncio.Task[None] | None,
        submitter: Submitter,
        request: SubmitterRequest,
        character: str,
        now: float,
    ) -> None:
        if before is not None:
            with contextlib.suppress(Exception):
                await asyncio.shield(before)
        try:
            await self._forward(submitter, request, character, now)
        except Exception:
            logger.exception("internal error on a submitted message")
            xml = warning_feedback_xml(
                "", submitter.default_character, "CANNOT_CREATE_BEHAVIOR", "internal error"
            )
            warning = WireFeedback(submitter.default_character, "warning", "", self.now(), xml)
            self._dispatch([warning], also=submitter)

    async def _forward(
        self, submitter: Submitter, request: SubmitterRequest, character: str, now: float
    ) -> None:
        if request["type"] == "bml":
            text = request["bml"]
            if not valid_character_id(character):
                # What the stage answers; it needs no session for this.
                self._dispatch(self.stage.submit_bml(text, now, character=character).messages,
                               also=submitter)  # fmt: skip
                return
            owner_request = OwnerRequest(
                "bml",
                character,
                self._submitter_name(submitter),
                bml=text,
                strict=submitter.strict,
            )
        elif request["type"] == "target":
            # Scene targets live in one server's scene (realizer.scene); a
            # gateway holds no scene to forward them to yet.
            xml = warning_feedback_xml(
                "", submitter.default_character, "NO_SUCH_TARGET",
                "scene targets are not forwarded through a cluster gateway",
            )  # fmt: skip
            warning = WireFeedback(submitter.default_character, "warning", "", now, xml)
            self._dispatch([warning], also=submitter)
            return
        else:
            if not valid_character_id(character):
                self._dispatch(
                    self.stage.interrupt(character, request["block"], now), also=submitter
                )
                return
            owner_request = OwnerRequest(
                "interrupt", character, self._submitter_name(submitter), block=request["block"]
            )
        try:
            reply = await self._ask(owner_request)
        except NoOwner as exc:
            self._refuse(submitter, owner_request, exc.message)
            return
        if owner_request.op == "bml":
            self.timings["forward"].add(self.now() - now)
        if reply.status == "none":
            self._dispatch(
                self.stage.interrupt(character, owner_request.block, now), also=submitter
            )
        elif reply.status == "error":
            self._refuse(submitter, owner_request, reply.reason)

    def _refuse(self, submitter: Submitter, request: OwnerRequest, text: str) -> None:
        now = self.now()
        block = (
            request.block
            if request.op == "interrupt"
            else (root_attribute(request.bml, "id") or "")
        )
        xml = warning_feedback_xml(block, request.character, NoOwner.warning_type, text)
        messages: list[Outgoing] = [WireFeedback(request.character, "warning", block, now, xml)]
        if request.op == "bml":
            messages.append(BlockEvent(request.character, block, "rejected", now))
        self._dispatch(messages, also=submitter)

    # -- feedback ---------------------------------------------------------------------

    async def _on_feedback(self, msg: Msg) -> None:
        try:
            envelope = unpack_feedback(msg.data)
        except ClusterMessageError as exc:
            logger.warning("ignored a feedback message: %s", exc)
            return
        also: Submitter | None = None
        if envelope.reply_to.startswith(self.gateway_id + "/"):
            for submitter in self.submitters:
                if self._submitter_name(submitter) == envelope.reply_to:
                    also = submitter
                    if envelope.follow:
                        submitter.characters.add(envelope.message.character)
                    break
        self._dispatch([envelope.message], also=also)

    # -- viewers --------------------------------------------------------------------------

    async def _admit_viewer(self, character: str) -> None:
        total = sum(len(v) for v in self.viewers.values())
        if total >= self.limits.viewers:
            raise LimitExceeded(f"limit of {self.limits.viewers} viewers reached")
        if len(self.viewers.get(character, ())) >= self.limits.viewers_per_character:
            raise LimitExceeded(
                f"limit of {self.limits.viewers_per_character} viewers per character"
            )
        if not valid_character_id(character):
            raise PeerError(f"invalid character id {character[:80]!r}")
        reply = await self._ask(OwnerRequest("view", character))
        if reply.status != "ok" or not reply.mesh:
            raise LimitExceeded(reply.reason or f"character {character!r} cannot be viewed")
        if len(self.meshes) >= self.limits.characters:  # keep it bounded
            for unwatched in [c for c in self.meshes if not self.viewers.get(c)]:
                del self.meshes[unwatched]
                self.models.pop(unwatched, None)
        self.meshes[character] = reply.mesh

    async def _subscription_start(self, character: str, viewer: Viewer) -> list[bytes]:
        mesh = self.meshes[character]
        model = viewer.wants_model and character not in self.models
        if model or viewer.options.coded:
            # The model once per character; an intra frame for each coded viewer.
            request = OwnerRequest("view", character, model=model, intra=viewer.options.coded)
            reply = await self._ask(request)
            if model:
                self.models[character] = reply.model
        return [mesh, self.models[character]] if viewer.wants_model else [mesh]

    def _viewers_changed(self, character: str) -> None:
        viewers = self.viewers.get(character, set())
        groups: dict[str, set[Viewer]] = {}
        for viewer in viewers:
            groups.setdefault(format_key(viewer.options), set()).add(viewer)
        if groups:
            self.by_format[character] = groups
        else:
            self.by_format.pop(character, None)
            self.viewers.pop(character, None)
            self._last_owner.pop(character, None)
            unwatched = {c for c, _ in self._whole if c not in self.by_format}
            if len(unwatched) > STREAMS_KEPT:  # keep it bounded
                self._whole = {k: v for k, v in self._whole.items() if k[0] in self.by_format}
        self._spawn(self._subscribe_frames(character))
        self._want_changed.set()

    async def _subscribe_frames(self, character: str) -> None:
        assert self.nats is not None
        async with self._subscribing:  # one change at a time: never two subscriptions
            wanted = character in self.by_format
            subscription = self._frame_subscriptions.get(character)
            if wanted and subscription is None:
                self._frame_subscriptions[character] = await self.nats.subscribe(
                    frame_wildcard(character), cb=self._on_frame
                )
            elif not wanted and subscription is not None:
                del self._frame_subscriptions[character]
                await subscription.unsubscribe()

    async def _on_frame(self, msg: Msg) -> None:
        """Keep the newest frame ticks of each character and format (and the
        last whole frame); the fan-out to the viewers runs once the ticks at
        hand are read.

        A tick supersedes the last but one before it, so a gateway that
        falls behind (ticks piling up in its NATS connection while it
        waited for the CPU) sends each viewer the two newest ticks of the
        backlog, not every old one in turn: it drops frames instead of
        adding latency, as ``realizer serve``'s clock skips ticks when it
        is behind by whole frames. Two ticks read at once are not a
        backlog: a worker's clock that is late runs its next tick at once,
        and both ticks leave in one write, where ``realizer serve`` would
        have sent both (keeping only the newest, the cluster dropped 552 of
        78090 frames at 50 x 200 where ``realizer serve`` dropped 20). A
        superseded whole frame is not lost to the viewers: the last whole
        frame is kept apart, and a viewer that lacks its content gets it
        on the next tick."""
        # realizer.v2.frame.<token>.<format>
        parts = msg.subject.split(".")
        if len(parts) != 5:
            return
        key = (untoken(parts[3]), parts[4])
        if key[1] not in self.by_format.get(key[0], {}):
            return
        try:
            tick = FrameTick.unpack(msg.data)
        except ClusterMessageError as exc:
            logger.warning("ignored a frame message: %s", exc)
            return
        self.frames_received += 1
        if tick.frame is not None:
            self._whole[key] = LastWhole(tick.content, tick.frame)
        due = self._due(key[0], tick.number)
        if due:
            self.timings["frame_received"].add(asyncio.get_running_loop().time() - due)
        kept = self._newest.get(key)
        if kept is None:
            self._newest[key] = [(tick, due)]
        else:
            kept.append((tick, due))
            if len(kept) > FRAMES_KEPT:
                del kept[0]
                self.frames_superseded += 1
        if not self._fan_out_due:
            self._fan_out_due = True
            asyncio.get_running_loop().call_soon(self._fan_out)

    def _due(self, character: str, number: int) -> float:
        """Frame ``number``'s due time on this host's loop clock, from its
        owner's frame 0 (the lease); 0.0 when the owner runs on another host
        (its monotonic clock is not this one's)."""
        lease = self.table.leases.get(character)
        if lease is None or lease.value.host != HOST or not lease.value.clock:
            return 0.0
        return lease.value.clock + number / self.config.fps

    def _fan_out(self) -> None:
        self._fan_out_due = False
        newest, self._newest = self._newest, {}
        written = self.timings["frame_written"]
        for (character, key), ticks in newest.items():
            viewers = self.by_format.get(character, {}).get(key, ())
            for tick, due in ticks:
                if viewers:
                    self._offer_tick(viewers, (character, key), tick)
                if due:
                    written.add(asyncio.get_running_loop().time() - due)

    def _offer_tick(self, viewers: Iterable[Viewer], key: tuple[str, str], tick: FrameTick) -> None:
        """What ``realizer serve`` offers each viewer on this tick
        (RealizerService._deliver_frame): a ``same`` to one that asked for
        them and already has this content, the whole frame to the others;
        on a coded tick sent whole (the coder coded) every viewer gets it.
        Each message's WebSocket bytes are built once for all viewers (the
        viewers of one key share their options, so ``coded`` is the key's)."""
        content = tick.content
        same: tuple[bytes, bytes] | None = None
        whole: tuple[bytes, bytes] | None = None
        coded = False
        if tick.frame is not None:
            whole = (tick.frame, binary_frame(tick.frame))
        for viewer in viewers:
            if viewer.version == content and viewer.same:
                coded = viewer.options.coded
                if not (coded and whole):
                    if same is None:
                        data = codec.same_message(tick.number)
                        same = (data, binary_frame(data))
                    viewer.offer_same(same[0], WRITE_LIMIT, same[1])
                    continue
            if whole is None:
                last = self._whole.get(key)
                if viewer.options.coded or last is None or last.content != content:
                    # This content never reached this gateway whole (a NATS
                    # message lost, or it joined the stream on a same):
                    # nothing rather than a stale picture; the next whole
                    # frame (at most a second away) brings it.
                    self.frames_unknown += 1
                    continue
                data = restamp(last.frame, tick.number, tick.time)
                whole = (data, binary_frame(data))
                self.frames_restamped += 1
            viewer.offer(whole[0], WRITE_LIMIT, whole[1])
            viewer.version = content

    def _wants(self) -> tuple[dict[str, set[ViewOptions]], dict[str, set[ViewOptions]]]:
        """The formats this gateway's viewers want per character, and those
        of them that some viewer here wants whole every tick (it asked for
        no ``same``)."""
        wants: dict[str, set[ViewOptions]] = {}
        every: dict[str, set[ViewOptions]] = {}
        for character, viewers in self.viewers.items():
            for viewer in viewers:
                wants.setdefault(character, set()).add(viewer.options)
                if not viewer.same:
                    every.setdefault(character, set()).add(viewer.options)
        return wants, every

    async def _announce(self) -> None:
        """Tell the workers what formats this gateway's viewers want: at
        once on a change, and every ``want_interval`` seconds anyway (a
        worker forgets a gateway it has not heard for 3.5 intervals)."""
        assert self.nats is not None
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._want_changed.wait(), self.cluster.want_interval)
            self._want_changed.clear()
            with contextlib.suppress(Exception):
                await self.nats.publish(SUBJECT_WANT, pack_want(self.gateway_id, *self._wants()))

    async def _watch_leases(self, watcher: Any) -> None:
        async for entry in watcher:
            if entry is None:
                continue
            character = untoken(entry.key)
            before = self.table.owner(character)
            deleted = entry.operation in ("DEL", "PURGE")
            self.table.observe(
                character, entry.revision, None if deleted else entry.value, time.monotonic()
            )
            after = self.table.owner(character)
            # A graceful handover deletes the lease before another worker
            # creates it: the owner before the deletion counts (regression:
            # viewers then got no mesh message, only n and t jumping).
            before = before or self._last_owner.get(character)
            if after is None and before is not None and character in self.viewers:
                self._last_owner[character] = before
            else:
                self._last_owner.pop(character, None)
            if before is not None and after is not None and after != before:
                self._restart_viewers(character)

    def _restart_viewers(self, character: str) -> None:
        """The character moved to another worker: its viewers start again
        from the mesh message (its frames now carry the new owner's clock).

        The last whole frames are kept: they are known by their content id,
        which means the same picture whichever worker encoded it (the same
        face on every worker), and a whole frame moved to a tick's ``n`` and
        ``t`` is what that tick's owner would have encoded. Regression: they
        were dropped here, and the new owner's first tick (whole: it has
        sent nothing yet) can reach this gateway before the lease change
        does (a frame is a plain publish, the lease's change comes through
        the bucket's stream); its viewers, restarted after it, then got
        nothing on the ``same`` ticks that followed until the next key
        frame, up to a second later."""
        for key in [k for k in self._newest if k[0] == character]:
            del self._newest[key]  # the old owner's frames must not follow the new mesh
        mesh = self.meshes.get(character)
        if mesh is None:
            return
        model = self.models.get(character)
        for viewer in self.viewers.get(character, set()):
            viewer.latest = None
            viewer.version = -1  # the new subscription's first frame is sent whole
            self._control(viewer, mesh)
            if viewer.wants_model and model:
                viewer.control.append(model)


__all__ = ["PREFIX", "ClusterGateway", "root_attribute"]
