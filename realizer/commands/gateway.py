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
from collections.abc import Callable
from typing import Any


def register(subparsers: Any) -> None:
    from realizer.commands.worker import cluster_parser

    parser = cluster_parser(
        subparsers,
        "gateway",
        "serve the realizer's endpoints for a cluster of workers over NATS",
        __doc__,
        "viewers=2000",
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 = any free)")
    parser.add_argument(
        "--fps", type=float, default=60.0, help="the workers' frames per second (reported)"
    )
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
        "--owner-wait",
        type=float,
        default=15.0,
        metavar="SECONDS",
        help="how long a request waits for a character to get an owner (default 15)",
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from realizer.commands.worker import cluster_config, run_cluster_role

    def build() -> tuple[Any, Callable[[int], str]]:
        from dataclasses import replace

        from realizer.commands.serve import _limits
        from realizer.service.cluster.gateway import ClusterGateway
        from realizer.service.limits import DEFAULT_LIMITS
        from realizer.service.server import ServiceConfig

        config = ServiceConfig(
            host=args.host,
            port=args.port,
            fps=args.fps,
            submit_token=args.submit_token or None,
            view_token=args.view_token or None,
            limits=replace(DEFAULT_LIMITS, **_limits(args.limit)),
        )
        cluster = cluster_config(args, owner_wait=args.owner_wait)
        gateway = ClusterGateway(config, cluster, default_character=args.character)
        host = f"[{args.host}]" if ":" in args.host else args.host

        def ready(port: int) -> str:
            return (
                f"realizer: gateway {gateway.gateway_id} serving on {host}:{port} "
                f"(viewer http://{host}:{port}/, BML ws://{host}:{port}/bml) "
                f"for the workers on {args.nats}"
            )

        return gateway, ready

    return run_cluster_role("gateway", build)
