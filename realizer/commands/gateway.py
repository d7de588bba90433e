"""``realizer gateway --nats URL``: the service's endpoints for a cluster (protocols/cluster.md).

A gateway serves exactly what ``realizer serve`` serves (/bml, /view, the
browser viewer at /, /health, /version; the same tokens and limits) but
holds no character: it forwards BML to each character's owner among the
workers (``realizer worker``) and fans their feedback and frames out to its
own connections. Run as many as you like behind one address. Needs the
``cluster`` extra (nats-py) and a NATS server with JetStream.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from realizer.commands import plain_text


def register(subparsers: Any) -> None:
    from realizer.commands.worker import add_cluster_options

    parser = subparsers.add_parser(
        "gateway",
        help="serve the realizer's endpoints for a cluster of workers over NATS",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    add_cluster_options(parser)
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 = any free)")
    parser.add_argument(
        "--fps", type=float, default=60.0, help="the workers' frames per second (reported)"
    )
    parser.add_argument("--character", default="default", help="character for BML that names none")
    parser.add_argument(
        "--submit-token",
        default=os.environ.get("REALIZER_SUBMIT_TOKEN"),
        help="token that allows submitting BML (default: $REALIZER_SUBMIT_TOKEN)",
    )
    parser.add_argument(
        "--view-token",
        default=os.environ.get("REALIZER_VIEW_TOKEN"),
        help="token that allows only viewing (default: $REALIZER_VIEW_TOKEN)",
    )
    parser.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a named limit, e.g. --limit viewers=2000",
    )
    parser.add_argument(
        "--owner-wait",
        type=float,
        default=15.0,
        metavar="SECONDS",
        help="how long a request waits for a character to get an owner (default 15)",
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import logging
    from dataclasses import replace

    from realizer.commands.serve import _limits
    from realizer.service.limits import DEFAULT_LIMITS
    from realizer.service.server import RealizerService, ServiceConfig, run_until_stopped_blocking

    logging.basicConfig(level=logging.WARNING, format="realizer: %(message)s")
    from realizer.extras import require

    require("cluster", "realizer gateway")
    from realizer.service.cluster.bus import ClusterConfig
    from realizer.service.cluster.gateway import ClusterGateway

    try:
        config = ServiceConfig(
            host=args.host,
            port=args.port,
            fps=args.fps,
            submit_token=args.submit_token or None,
            view_token=args.view_token or None,
            limits=replace(DEFAULT_LIMITS, **_limits(args.limit)),
        )
        cluster = ClusterConfig(
            args.nats, node_id=args.id, lease_ttl=args.lease_ttl, owner_wait=args.owner_wait
        )
        gateway = ClusterGateway(config, cluster, default_character=args.character)
    except ValueError as exc:
        print(f"realizer gateway: {exc}", file=sys.stderr)
        return 2

    def ready(service: RealizerService) -> None:
        host = f"[{args.host}]" if ":" in args.host else args.host
        print(
            f"realizer: gateway {gateway.gateway_id} serving on {host}:{service.port} "
            f"(viewer http://{host}:{service.port}/, BML ws://{host}:{service.port}/bml) "
            f"for the workers on {args.nats}",
            file=sys.stderr,
            flush=True,
        )

    try:
        return run_until_stopped_blocking(gateway, ready=ready)
    except Exception as exc:  # the port is in use, NATS cannot be reached
        print(f"realizer gateway: {exc or type(exc).__name__}", file=sys.stderr)
        return 2
