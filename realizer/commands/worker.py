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
from typing import Any

from realizer.commands import plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "worker",
        help="run characters for a cluster of workers and gateways over NATS",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    add_cluster_options(parser)
    parser.add_argument(
        "--host", default="127.0.0.1", help="address of /health (default 127.0.0.1)"
    )
    parser.add_argument(
        "--port", type=int, default=0, help="port of /health (default 0 = any free)"
    )
    parser.add_argument("--fps", type=float, default=60.0, help="frames per second (default 60)")
    parser.add_argument("--face", default=None, metavar="PATH", help="face parameter file")
    parser.add_argument("--character", default="default", help="character for BML that names none")
    parser.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a named limit, e.g. --limit characters=100",
    )
    parser.add_argument(
        "--drain",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="on SIGTERM, how long running blocks may finish (default 10)",
    )
    parser.set_defaults(run=run)


def add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """The options a worker and a gateway share."""
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
        "--lease-ttl",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="lease lifetime without renewal; a dead worker's characters move "
        "after 0.75-1.1 times it (default 2; the same on every process)",
    )


def run(args: argparse.Namespace) -> int:
    import logging
    import secrets
    from dataclasses import replace

    from realizer.commands.serve import _limits
    from realizer.errors import RealizerError
    from realizer.service.assets import face_assets, load_face, session_factory
    from realizer.service.limits import DEFAULT_LIMITS
    from realizer.service.server import RealizerService, ServiceConfig, run_until_stopped_blocking
    from realizer.service.stage import Stage

    logging.basicConfig(level=logging.WARNING, format="realizer: %(message)s")
    from realizer.extras import require

    require("cluster", "realizer worker")
    from realizer.service.cluster.bus import ClusterConfig
    from realizer.service.cluster.worker import ClusterWorker

    try:
        limits = replace(DEFAULT_LIMITS, **_limits(args.limit))
        # A worker's port serves only /health and /version, nothing a token
        # guards; a token nobody knows lets it bind to any address.
        config = ServiceConfig(
            host=args.host,
            port=args.port,
            fps=args.fps,
            limits=limits,
            submit_token=secrets.token_hex(16),
        )
        cluster = ClusterConfig(
            args.nats, node_id=args.id, lease_ttl=args.lease_ttl, drain_timeout=args.drain
        )
        face = load_face(args.face)
        make_session = session_factory(face)
        make_session(args.character)  # load the engines' data now, not on the clock
        stage = Stage(make_session, limits, default_character=args.character)
        worker = ClusterWorker(config, stage, face_assets(face), cluster)
    except (RealizerError, ValueError, OSError) as exc:
        print(f"realizer worker: {exc}", file=sys.stderr)
        return 2

    def ready(service: RealizerService) -> None:
        print(
            f"realizer: worker {worker.worker_id} on {args.nats} "
            f"(health http://{args.host}:{service.port}/health)",
            file=sys.stderr,
            flush=True,
        )

    try:
        return run_until_stopped_blocking(worker, ready=ready)
    except Exception as exc:  # the port is in use, NATS cannot be reached
        print(f"realizer worker: {exc or type(exc).__name__}", file=sys.stderr)
        return 2
