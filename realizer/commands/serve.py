"""``realizer serve``: the real-time service (protocols/, realizer.service).

One process serves many characters, each a session made on first use with
the face: submitters send BML to ws://HOST:PORT/bml, viewers watch frames on
ws://HOST:PORT/view, and a browser shows the face at http://HOST:PORT/.
Without tokens it binds to a loopback address only. Stops cleanly on
SIGINT or SIGTERM (exit 0). Settings come from flags, a TOML file (--config:
every flag but the tokens has a key; --print-config shows the result as a
file --config reads) and, for tokens, the environment (REALIZER_SUBMIT_TOKEN,
REALIZER_VIEW_TOKEN). Logs go to stderr, one line per
connection, refused handshake and block state at the default level, info.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from realizer.commands import add_idle_options, error_line, plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="run the real-time BML service (WebSocket + browser viewer)",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("--config", type=Path, metavar="FILE", help="a TOML settings file")
    parser.add_argument(
        "--print-config", action="store_true", help="print the effective settings and exit"
    )
    parser.add_argument("--host", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=int, help="port (default 8765; 0 = any free)")
    parser.add_argument("--fps", type=float, help="frames per second (default 60)")
    parser.add_argument("--face", metavar="PATH", help="face parameter file")
    parser.add_argument("--character", help="character for BML that names none")
    parser.add_argument(
        "--submit-token",
        help="token that allows submitting BML (better: $REALIZER_SUBMIT_TOKEN)",
    )
    parser.add_argument(
        "--view-token",
        help="token that allows only viewing (better: $REALIZER_VIEW_TOKEN)",
    )
    parser.add_argument(
        "--avatar",
        default=None,
        metavar="MODEL.glb",
        help="a glTF 2.0 binary avatar with ARKit-named morph targets for the browser viewer",
    )
    parser.add_argument(
        "--limit",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a named limit, e.g. --limit viewers=200 (see protocols/README.md)",
    )
    parser.add_argument(
        "--stomp",
        metavar="URL",
        help="also take BML from an ActiveMQ/STOMP broker, e.g. stomp://127.0.0.1:61613 "
        "(login in $REALIZER_STOMP_LOGIN and $REALIZER_STOMP_PASSCODE; protocols/stomp.md)",
    )
    parser.add_argument(
        "--stomp-layout",
        choices=("asap", "greta", "vhmsg"),
        help="topic names and message layout: AsapRealizer's (default), Greta's, or the "
        "Virtual Human messaging SmartBody uses",
    )
    parser.add_argument("--stomp-bml-topic", metavar="DEST", help="BML destination (/topic/...)")
    parser.add_argument(
        "--stomp-feedback-topic", metavar="DEST", help="feedback destination (/topic/...)"
    )
    add_idle_options(parser)
    # None: not given, so the settings file or the default decides
    parser.set_defaults(idle=None, seed=None)
    parser.add_argument("--tts", choices=("espeak", "piper"), help="speech backend (espeak)")
    parser.add_argument(
        "--voice", default=None, help="default voice: a language tag such as en-gb (en)"
    )
    parser.add_argument(
        "--piper-model", default=None, metavar="PATH.onnx", help="Piper voice model (--tts piper)"
    )
    parser.add_argument(
        "--log-level",
        choices=("debug", "info", "warning", "error"),
        help="least severe log lines shown on stderr (default info)",
    )
    parser.add_argument(
        "--log-format", choices=("text", "json"), help="log lines as text (default) or JSON"
    )
    parser.add_argument(
        "--planner-processes",
        type=int,
        metavar="N",
        help="processes that parse and plan submitted BML, so no submitter takes CPU from "
        "the frame clock (default 0: threads of the service's own process)",
    )
    parser.set_defaults(run=run)


def _limits(pairs: list[str]) -> dict[str, int]:
    from dataclasses import fields

    from realizer.service.limits import DEFAULT_LIMITS

    names = {f.name for f in fields(DEFAULT_LIMITS)}
    changes: dict[str, int] = {}
    for pair in pairs:
        name, _, value = pair.partition("=")
        if name not in names or not value.isdigit():
            raise ValueError(
                f"--limit {pair!r}: expected NAME=INTEGER with NAME one of {sorted(names)}"
            )
        changes[name] = int(value)
    return changes


def with_avatar(assets: Any, path: str) -> Any:
    """``assets`` serving the GLB at ``path`` to the browser viewer; warns once,
    on stderr, listing the ARKit morph targets it lacks (the rest animate)."""
    from dataclasses import replace
    from pathlib import Path

    from realizer.face.gltf import avatar_report

    data = Path(path).read_bytes()
    report = avatar_report(data)
    if not report.targets:
        raise ValueError(f"{path}: no ARKit-named morph targets (see docs/viewer-formats.md)")
    if report.missing:
        print(
            f"realizer serve: warning: {path} lacks {len(report.missing)} of the 52 ARKit "
            f"morph targets: {', '.join(report.missing)}; the others animate",
            file=sys.stderr,
        )
    if not report.bones:
        print(
            f"realizer serve: warning: {path} has no head or eye bones; head and eye turns "
            "are not shown",
            file=sys.stderr,
        )
    return replace(assets, avatar=data, avatar_missing=report.missing)


def stomp_bridge(args: Any) -> Any:
    """The STOMP bridge of ``--stomp`` (needs the ``stomp`` extra); the
    broker's login comes from the environment only. ``args``: the command
    line's namespace or the effective settings (the same names)."""
    from realizer.extras import require

    require("stomp", "realizer serve --stomp")
    from realizer.service.stomp import (
        LOGIN_VARIABLE,
        PASSCODE_VARIABLE,
        StompBridge,
        StompConfig,
    )

    return StompBridge(
        StompConfig(
            args.stomp,
            layout=args.stomp_layout,
            bml_topic=args.stomp_bml_topic,
            feedback_topic=args.stomp_feedback_topic,
            login=os.environ.get(LOGIN_VARIABLE) or None,
            passcode=os.environ.get(PASSCODE_VARIABLE) or None,
        )
    )


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from realizer.errors import RealizerError
    from realizer.service import logs
    from realizer.service.limits import DEFAULT_LIMITS
    from realizer.service.settings import read_file, resolve, to_toml

    try:
        from_file = read_file(args.config) if args.config is not None else {}
        flags = {
            "host": args.host,
            "port": args.port,
            "fps": args.fps,
            "face": args.face,
            "character": args.character,
            "avatar": args.avatar,
            "idle": args.idle,
            "seed": args.seed,
            "tts": args.tts,
            "voice": args.voice,
            "piper_model": args.piper_model,
            "stomp": args.stomp,
            "stomp_layout": args.stomp_layout,
            "stomp_bml_topic": args.stomp_bml_topic,
            "stomp_feedback_topic": args.stomp_feedback_topic,
            "submit_token": args.submit_token,
            "view_token": args.view_token,
            "log_level": args.log_level,
            "log_format": args.log_format,
            "planner_processes": args.planner_processes,
            "limits": _limits(args.limit),
        }
        settings = resolve(from_file, flags, os.environ)
    except (RealizerError, ValueError) as exc:
        print(error_line("serve", exc), file=sys.stderr)
        return 2
    if args.print_config:
        print(to_toml(settings), end="")
        return 0
    from realizer.extras import require

    require("serve", "realizer serve")  # scipy: the scheduler and the face's deformation
    logs.configure(settings.log_level, "json" if settings.log_format == "json" else "text")

    from realizer.service.assets import face_assets, load_face, sessions_from_settings
    from realizer.service.server import RealizerService, ServiceConfig, serve_until_stopped
    from realizer.service.stage import Stage

    try:
        limits = replace(DEFAULT_LIMITS, **settings.limits)
        config = ServiceConfig(
            host=settings.host,
            port=settings.port,
            fps=settings.fps,
            submit_token=settings.submit_token,
            view_token=settings.view_token,
            limits=limits,
            planner_processes=settings.planner_processes,
        )
        face = load_face(settings.face)
        make_session = sessions_from_settings(face, settings)
        # The first session loads the engines' data (tens of ms): do it now,
        # not on the clock's time when the first character appears.
        make_session(settings.character)
        stage = Stage(make_session, limits, default_character=settings.character)
        assets = face_assets(face)
        if settings.avatar:
            assets = with_avatar(assets, settings.avatar)
        attachments = [stomp_bridge(settings)] if settings.stomp else []
    except (RealizerError, ValueError, OSError, ImportError) as exc:
        print(error_line("serve", exc), file=sys.stderr)
        return 2

    def ready(service: RealizerService) -> None:
        host = f"[{settings.host}]" if ":" in settings.host else settings.host
        print(
            f"realizer: serving on {host}:{service.port} "
            f"(viewer http://{host}:{service.port}/, BML ws://{host}:{service.port}/bml)",
            file=sys.stderr,
            flush=True,
        )

    try:
        return serve_until_stopped(config, stage, assets, ready=ready, attachments=attachments)
    except OSError as exc:  # e.g. the port is in use
        print(error_line("serve", exc), file=sys.stderr)
        return 2
