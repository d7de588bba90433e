"""``realizer worker --nats URL``: run characters for a cluster (protocols/cluster.md).

A worker runs the same stage, sessions and clock as ``realizer serve`` for
the characters whose lease it holds in the NATS server's key-value bucket,
and publishes their feedback and frames on NATS subjects; gateways
(``realizer gateway``) serve the clients. Its own port serves only /health
and /version. On SIGTERM it hands its characters over (running blocks
finish first, up to --drain seconds) and exits 0. Needs the ``cluster``
extra (nats-py) and a NATS server with JetStream (``nats-server -js``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from realizer.commands import plain_text


def register(subparsers: Any) -> None:
    parser = cluster_parser(
        subparsers,
        "worker",
        "run characters for a cluster of workers and gateways over NATS",
        __doc__,
        "characters=100",
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="address of /health (default 127.0.0.1)"
    )
    parser.add_argument(
        "--port", type=int, default=0, help="port of /health (default 0 = any free)"
    )
    parser.add_argument("--fps", type=float, default=60.0, help="frames per second (default 60)")
    parser.add_argument("--face", default=None, metavar="PATH", help="face parameter file")
    parser.add_argument(
        "--drain",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="on SIGTERM, how long running blocks may finish (default 10)",
    )
    parser.set_defaults(run=run)


def cluster_parser(
    subparsers: Any, name: str, summary: str, doc: str | None, limit_example: str
) -> argparse.ArgumentParser:
    """The sub-command ``name`` (its description: the second paragraph of
    its module's ``doc``) with the options a worker and a gateway share."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        name, help=summary, description=plain_text(doc.split("\n\n")[1]) if doc else None
    )
    parser.add_argument("--character", default="default", help="character for BML that names none")
    parser.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"override a named limit, e.g. --limit {limit_example}",
    )
    parser.add_argument(
        "--nats",
        required=True,
        metavar="URL",
        help="NATS server(s) with JetStream, e.g. nats://127.0.0.1:4222",
    )
    parser.add_argument(
        "--id", default="", help="this process's id in the cluster (default: ROLE-HOST-PID-xxxx)"
    )
    parser.add_argument(
        "--planner-processes",
        type=int,
        default=0,
        metavar="N",
        help="processes that parse and plan this worker's blocks (default 0: threads)",
    )
    parser.add_argument(
        "--lease-ttl",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="lease lifetime without renewal; a dead worker's characters move "
        "after 0.75-1.1 times it (default 2; the same on every process)",
    )
    return parser


def run(args: argparse.Namespace) -> int:
    def build() -> tuple[Any, Callable[[int], str]]:
        import secrets
        from dataclasses import replace

        from realizer.commands.serve import _limits
        from realizer.service.assets import face_assets, load_face, session_factory
        from realizer.service.cluster.worker import ClusterWorker
        from realizer.service.limits import DEFAULT_LIMITS
        from realizer.service.server import ServiceConfig
        from realizer.service.stage import Stage

        limits = replace(DEFAULT_LIMITS, **_limits(args.limit))
        # A worker's port serves only /health and /version, nothing a token
        # guards; a token nobody knows lets it bind to any address.
        config = ServiceConfig(
            host=args.host,
            port=args.port,
            fps=args.fps,
            limits=limits,
            submit_token=secrets.token_hex(16),
            planner_processes=args.planner_processes,
        )
        cluster = cluster_config(args, drain_timeout=args.drain)
        face = load_face(args.face)
        make_session = session_factory(face)
        make_session(args.character)  # load the engines' data now, not on the clock
        stage = Stage(make_session, limits, default_character=args.character)
        worker = ClusterWorker(config, stage, face_assets(face), cluster)

        def ready(port: int) -> str:
            return (
                f"realizer: worker {worker.worker_id} on {args.nats} "
                f"(health http://{args.host}:{port}/health)"
            )

        return worker, ready

    return run_cluster_role("worker", build)


def cluster_config(args: argparse.Namespace, **settings: Any) -> Any:
    """The :class:`~realizer.service.cluster.bus.ClusterConfig` of the shared
    options (:func:`add_cluster_options`) and a role's own ``settings``."""
    from realizer.service.cluster.bus import ClusterConfig

    return ClusterConfig(args.nats, node_id=args.id, lease_ttl=args.lease_ttl, **settings)


def run_cluster_role(role: str, build: Callable[[], tuple[Any, Callable[[int], str]]]) -> int:
    """What ``realizer worker`` and ``realizer gateway`` share: the ``cluster``
    extra checked, the service made by ``build`` (which also gives the
    "ready" line for the port it got; an error in it exits 2), run until
    SIGINT or SIGTERM, its failure to start (a port in use, NATS out of
    reach) said in one line and exit 2."""
    import logging

    from realizer.errors import RealizerError
    from realizer.extras import require
    from realizer.service.server import RealizerService, run_until_stopped_blocking

    logging.basicConfig(level=logging.WARNING, format="realizer: %(message)s")
    require("cluster", f"realizer {role}")
    try:
        service, ready_line = build()
    except (RealizerError, ValueError, OSError) as exc:
        print(f"realizer {role}: {exc}", file=sys.stderr)
        return 2

    def ready(running: RealizerService) -> None:
        print(ready_line(running.port), file=sys.stderr, flush=True)

    try:
        return run_until_stopped_blocking(service, ready=ready)
    except Exception as exc:  # the port is in use, NATS cannot be reached
        print(f"realizer {role}: {exc or type(exc).__name__}", file=sys.stderr)
        return 2
