"""``realizer serve``'s settings: defaults, a TOML file, flags, the environment.

A configuration file (``realizer serve --config serve.toml``) holds what an
operator keeps under version control; every setting of ``realizer serve``
but the tokens has a key::

    [serve]
    host = "0.0.0.0"
    port = 8765
    fps = 60
    face = "faces/doctor.xml"      # relative to the file
    character = "doctor"
    avatar = "avatars/doctor.glb"  # relative to the file
    idle = true                    # blinks, saccades, breathing, head motion
    seed = 0                       # of the idle motion
    tts = "espeak"                 # espeak or piper
    voice = "en-gb"
    piper_model = "voices/en_GB-alba-medium.onnx"  # relative to the file
    stomp = "stomp://127.0.0.1:61613"  # login: $REALIZER_STOMP_LOGIN, ..._PASSCODE
    stomp_layout = "asap"          # asap, greta or vhmsg (protocols/stomp.md)
    log_level = "info"             # debug, info, warning, error
    log_format = "json"            # text or json
    planner_processes = 2          # parse and plan in 2 processes (default 0: threads)

    [serve.limits]                 # any named limit (protocols/README.md)
    viewers = 200

Tokens are secrets, so a file never holds them: they come from the
environment (``REALIZER_SUBMIT_TOKEN``, ``REALIZER_VIEW_TOKEN``) or, less
safely (other users see command lines), from ``--submit-token`` and
``--view-token``. A flag given on the command line wins over the file, and
the file over the defaults (for ``idle``, the default is on unless
``REALIZER_IDLE=0``). ``realizer serve --print-config`` prints the result as
TOML, a file ``--config`` reads back, with the tokens masked.

The same file may hold a ``[worker]`` table for ``realizer worker``
(:data:`WORKER_KEYS` and ``[worker.limits]``: the settings a cluster worker
shares with serve; docs/cluster.md); each command reads only its own table.

Errors read ``path:line:col: error: message``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from realizer.service.errors import ConfigError
from realizer.service.limits import DEFAULT_LIMITS
from realizer.service.logs import LEVELS

TOKEN_VARIABLES = {"submit_token": "REALIZER_SUBMIT_TOKEN", "view_token": "REALIZER_VIEW_TOKEN"}
#: Settings that name a file: a path in a settings file is relative to it.
PATHS = ("face", "avatar", "piper_model")
#: The speech backends (docs/speech.md).
TTS = ("espeak", "piper")
#: The STOMP bridge's layouts (protocols/stomp.md).
STOMP_LAYOUTS = ("asap", "greta", "vhmsg")
_TOML_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)")


@dataclass(frozen=True, slots=True)
class ServeSettings:
    host: str = "127.0.0.1"
    port: int = 8765
    fps: float = 60.0
    face: str | None = None
    character: str = "default"
    avatar: str | None = None
    idle: bool = True
    seed: int = 0
    tts: str = "espeak"
    voice: str | None = None
    piper_model: str | None = None
    stomp: str | None = None
    stomp_layout: str = "asap"
    stomp_bml_topic: str | None = None
    stomp_feedback_topic: str | None = None
    log_level: str = "info"
    log_format: str = "text"
    planner_processes: int = 0
    limits: dict[str, int] = field(default_factory=dict)
    submit_token: str | None = None
    view_token: str | None = None


_TYPES: dict[str, tuple[type, ...]] = {
    "host": (str,),
    "port": (int,),
    "fps": (int, float),
    "face": (str,),
    "character": (str,),
    "avatar": (str,),
    "idle": (bool,),
    "seed": (int,),
    "tts": (str,),
    "voice": (str,),
    "piper_model": (str,),
    "stomp": (str,),
    "stomp_layout": (str,),
    "stomp_bml_topic": (str,),
    "stomp_feedback_topic": (str,),
    "log_level": (str,),
    "log_format": (str,),
    "planner_processes": (int,),
}


def _error(path: Path | str, message: str, line: int = 1, column: int = 1) -> ConfigError:
    return ConfigError(f"{path}:{line}:{column}: error: {message}")


def _line_of(text: str, key: str) -> int:
    """The line where ``key`` is set (for messages), or 1."""
    setting = re.compile(rf"\s*\[?\s*(?:serve\.|worker\.)?{re.escape(key)}\s*[=\].]")
    for number, line in enumerate(text.splitlines(), 1):
        if setting.match(line):
            return number
    return 1


#: The tables a settings file may hold: ``realizer serve``'s and ``realizer
#: worker``'s (one file can configure both; each reads its own).
TABLES = ("serve", "worker")
#: The settings of a ``[worker]`` table: what a cluster worker shares with
#: ``realizer serve`` (its clock, face, characters' idle motion and speech,
#: planner and limits; host and port are those of its /health). The
#: cluster's own options (--nats, --id, --lease-ttl, --drain) are flags.
WORKER_KEYS = (
    "host", "port", "fps", "face", "character", "idle", "seed", "tts", "voice",
    "piper_model", "planner_processes",
)  # fmt: skip


def read_file(
    path: Path, table: str = "serve", keys: tuple[str, ...] | None = None
) -> dict[str, Any]:
    """The ``[serve]`` (or ``table``) table of a TOML file, checked (only
    ``keys`` and ``limits`` allowed, when given); paths made relative to it."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: error: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise _error(path, f"cannot read it: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        found = _TOML_POSITION.search(str(exc))
        line, column = (int(found.group(1)), int(found.group(2))) if found else (1, 1)
        message = _TOML_POSITION.sub("", str(exc)).strip()
        raise _error(path, message, line, column) from None
    unknown = set(data) - set(TABLES)
    if unknown:
        name = sorted(unknown)[0]
        expected = " or ".join(f"[{t}]" for t in TABLES)
        raise _error(path, f"unknown table {name!r}; expected {expected}", _line_of(text, name))
    serve = data.get(table, {})
    if not isinstance(serve, dict):
        raise _error(path, f"{table} must be a table ([{table}])", _line_of(text, table))
    allowed = keys if keys is not None else tuple(_TYPES)
    out: dict[str, Any] = {}
    for key, value in serve.items():
        line = _line_of(text, key)
        if key in TOKEN_VARIABLES:
            raise _error(
                path,
                f"{key} does not belong in a file: set ${TOKEN_VARIABLES[key]} instead",
                line,
            )
        if key == "limits":
            out["limits"] = _limits(value, path, text)
            continue
        if key not in allowed:
            known = ", ".join(sorted([*allowed, "limits"]))
            raise _error(path, f"unknown setting {key!r}; known: {known}", line)
        wanted = _TYPES[key]
        if not isinstance(value, wanted) or (isinstance(value, bool) and bool not in wanted):
            raise _error(path, f"{key} has the wrong type ({type(value).__name__})", line)
        out[key] = value
    for key in PATHS:
        if key in out:
            out[key] = str((path.parent / out[key]).resolve())
    return out


def _limits(value: Any, path: Path, text: str) -> dict[str, int]:
    names = {f.name for f in fields(DEFAULT_LIMITS)}
    if not isinstance(value, dict):
        raise _error(path, "limits must be a table ([serve.limits])", _line_of(text, "limits"))
    out: dict[str, int] = {}
    for name, number in value.items():
        if name not in names:
            raise _error(
                path,
                f"unknown limit {name!r}; known: {', '.join(sorted(names))}",
                _line_of(text, name),
            )
        if not isinstance(number, int) or isinstance(number, bool) or number < 0:
            raise _error(path, f"limit {name} must be a whole number >= 0", _line_of(text, name))
        out[name] = number
    return out


def resolve(
    file_settings: Mapping[str, Any],
    flags: Mapping[str, Any],
    environ: Mapping[str, str],
) -> ServeSettings:
    """Defaults, then the file, then flags that were given (not None), then tokens."""
    merged: dict[str, Any] = {}
    merged.update(file_settings)
    limits = dict(file_settings.get("limits", {}))
    for key, value in flags.items():
        if key == "limits":
            limits.update(value)
        elif value is not None:
            merged[key] = value
    merged["limits"] = limits
    for key, variable in TOKEN_VARIABLES.items():
        if merged.get(key) is None:
            merged[key] = environ.get(variable) or None
    if "idle" not in merged:
        merged["idle"] = environ.get("REALIZER_IDLE", "1") != "0"
    settings = ServeSettings(**merged)
    if settings.log_level not in LEVELS:
        raise ConfigError(f"log_level must be one of {', '.join(LEVELS)}")
    if settings.log_format not in ("text", "json"):
        raise ConfigError("log_format must be text or json")
    if not 0 <= settings.port <= 65535:
        raise ConfigError(f"port {settings.port} is not between 0 and 65535")
    if not (math.isfinite(settings.fps) and 0 < settings.fps <= 1000):
        raise ConfigError(f"fps {settings.fps} is not between 0 and 1000")
    if settings.tts not in TTS:
        raise ConfigError(f"tts must be one of {', '.join(TTS)}")
    if isinstance(settings.planner_processes, bool) or not 0 <= settings.planner_processes <= 64:
        raise ConfigError(f"planner_processes {settings.planner_processes} is not between 0 and 64")
    if settings.stomp_layout not in STOMP_LAYOUTS:
        raise ConfigError(f"stomp_layout must be one of {', '.join(STOMP_LAYOUTS)}")
    return settings


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def to_toml(settings: ServeSettings, table: str = "serve") -> str:
    """The effective settings as a TOML file; tokens shown only as set or
    not. ``table="worker"``: a ``[worker]`` table of :data:`WORKER_KEYS`."""
    lines = [f"[{table}]"]
    names = WORKER_KEYS if table == "worker" else (
        "host", "port", "fps", "face", "character", "avatar", "idle", "seed",
        "tts", "voice", "piper_model", "stomp", "stomp_layout", "stomp_bml_topic",
        "stomp_feedback_topic", "log_level", "log_format", "planner_processes",
    )  # fmt: skip
    for name in names:
        value = getattr(settings, name)
        if value is None:
            lines.append(f"# {name}: not set")
        else:
            lines.append(f"{name} = {_toml_value(value)}")
    for name, variable in TOKEN_VARIABLES.items() if table == "serve" else ():
        state = "set (***)" if getattr(settings, name) else "not set"
        lines.append(f"# {name}: {state}; from ${variable} or --{name.replace('_', '-')}")
    lines.append("")
    lines.append(f"[{table}.limits]")
    effective = {f.name: getattr(DEFAULT_LIMITS, f.name) for f in fields(DEFAULT_LIMITS)}
    effective.update(settings.limits)
    for name in sorted(effective):
        lines.append(f"{name} = {effective[name]}")
    return "\n".join(lines) + "\n"
