"""``realizer worker --nats URL``: run characters for a cluster (protocols/cluster.md).

A worker runs the same stage, sessions and clock as ``realizer serve`` for
the characters whose lease it holds in the NATS server's key-value bucket,
and publishes their feedback and frames on NATS subjects; gateways
(``realizer gateway``) serve the clients. Its own port serves only /health
and /version. On SIGTERM it hands its characters over (running blocks
finish first, up to --drain seconds) and exits 0. Its characters have
realizer serve's idle motion (blinks, saccades, breathing, head motion; on
unless --no-idle or REALIZER_IDLE=0) and speech; settings come from flags
and the [worker] table of a TOML file (--config; --print-config shows the
result). Needs the ``cluster`` extra (nats-py) and a NATS server with
JetStream (``nats-server -js``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from realizer.commands import add_idle_options, error_line, plain_text


def register(subparsers: Any) -> None:
    parser = cluster_parser(
        subparsers,
        "worker",
        "run characters for a cluster of workers and gateways over NATS",
        __doc__,
        "characters=100",
    )
    parser.add_argument(
        "--config", type=Path, metavar="FILE", help="a TOML settings file (its [worker] table)"
    )
    parser.add_argument(
        "--print-config", action="store_true", help="print the effective settings and exit"
    )
    parser.add_argument("--host", help="address of /health (default 127.0.0.1)")
    parser.add_argument("--port", type=int, help="port of /health (default 0 = any free)")
    parser.add_argument("--fps", type=float, help="frames per second (default 60)")
    parser.add_argument("--face", metavar="PATH", help="face parameter file")
    add_idle_options(parser)
    parser.add_argument("--tts", choices=("espeak", "piper"), help="speech backend (espeak)")
    parser.add_argument(
        "--voice", default=None, help="default voice: a language tag such as en-gb (en)"
    )
    parser.add_argument(
        "--piper-model", default=None, metavar="PATH.onnx", help="Piper voice model (--tts piper)"
    )
    parser.add_argument(
        "--drain",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="on SIGTERM, how long running blocks may finish (default 10)",
    )
    # None: not given, so the settings file or the default decides (as serve)
    parser.set_defaults(run=run, idle=None, seed=None, character=None, planner_processes=None)


def worker_settings(args: argparse.Namespace) -> Any:
    """The worker's effective :class:`~realizer.service.settings.ServeSettings`:
    ``realizer serve``'s defaults (but port 0), then the file's ``[worker]``
    table, then the flags given, by serve's rules (``idle``: on unless
    ``REALIZER_IDLE=0``)."""
    import os

    from realizer.commands.serve import _limits
    from realizer.service.settings import WORKER_KEYS, read_file, resolve

    from_file: dict[str, Any] = {"port": 0}
    if args.config is not None:
        from_file.update(read_file(args.config, "worker", WORKER_KEYS))
    flags = {key: getattr(args, key) for key in WORKER_KEYS}
    flags["limits"] = _limits(args.limit)
    environ = {k: v for k, v in os.environ.items() if k == "REALIZER_IDLE"}  # no tokens
    return resolve(from_file, flags, environ)


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
    from realizer.errors import RealizerError

    try:
        settings = worker_settings(args)
    except (RealizerError, ValueError) as exc:
        print(error_line("worker", exc), file=sys.stderr)
        return 2
    if args.print_config:
        from realizer.service.settings import to_toml

        print(to_toml(settings, "worker"), end="")
        return 0

    def build() -> tuple[Any, Callable[[int], str]]:
        import secrets
        from dataclasses import replace

        from realizer.service.assets import face_assets, load_face, sessions_from_settings
        from realizer.service.cluster.worker import ClusterWorker
        from realizer.service.limits import DEFAULT_LIMITS
        from realizer.service.server import ServiceConfig
        from realizer.service.stage import Stage

        limits = replace(DEFAULT_LIMITS, **settings.limits)
        # A worker's port serves only /health and /version, nothing a token
        # guards; a token nobody knows lets it bind to any address.
        config = ServiceConfig(
            host=settings.host,
            port=settings.port,
            fps=settings.fps,
            limits=limits,
            submit_token=secrets.token_hex(16),
            planner_processes=settings.planner_processes,
        )
        cluster = cluster_config(args, drain_timeout=args.drain)
        face = load_face(settings.face)
        # The same sessions as realizer serve's: idle motion seeded by the
        # seed and the character's id (realizer.service.assets).
        make_session = sessions_from_settings(face, settings)
        make_session(settings.character)  # load the engines' data now, not on the clock
        stage = Stage(make_session, limits, default_character=settings.character)
        worker = ClusterWorker(config, stage, face_assets(face), cluster)

        def ready(port: int) -> str:
            return (
                f"realizer: worker {worker.worker_id} on {args.nats} "
                f"(health http://{settings.host}:{port}/health)"
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
