"""Which of the realizer's modules run compiled, and the fallback to Python.

The hot modules named in :data:`MODULES` can be compiled into C extensions
by mypyc (part of mypy: it compiles type-annotated Python, and these
modules are ``mypy --strict`` clean) with ``python scripts/build_compiled.py``,
which ``scripts/setup.sh`` runs. The extensions sit beside their sources
(``reader.cpython-311-x86_64-linux-gnu.so`` next to ``reader.py``), and
Python's import system prefers them; the sources stay the reference, and
every module works as plain Python too:

* no compiler or no mypy: nothing is built and the sources run (a wheel from
  ``pip install realizer`` is pure Python);
* ``REALIZER_PURE=1`` in the environment: the sources run even where the
  extensions are built (the test suite runs the parser's tests both ways);
* a source edited since the build (the build records each source's size,
  modification time and SHA-256 in ``_compiled.txt``; the hash is computed
  only when size or time differ): its extension would run old code, so all
  the sources run instead, until the build is run again (``bash
  scripts/setup.sh``). All or none: a compiled module calls the compiled
  code of the others directly.

:func:`select` makes that choice; ``realizer/__init__.py`` calls it before
any of these modules is imported. :func:`describe` says which one is
running (``realizer --version``, ``realizer bench parser``).

This module is the one list of compiled modules: the build script reads
:data:`MODULES` from here. A module on it must be ``mypy --strict`` clean,
define no class that is pickled, replaced with ``dataclasses.replace`` or
built by :func:`realizer.bml_parser.nodes.builder` (compiled classes are
native: such classes live in plain modules, as
:mod:`realizer.bml_parser.result` does for the reader), and not be
monkeypatched by tests.
"""

from __future__ import annotations

import importlib.machinery
import os
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any

#: The modules compiled by ``scripts/build_compiled.py``, by import name.
MODULES: tuple[str, ...] = (
    "realizer.bml_parser.reader",
    "realizer.bml_parser.syncref",
    "realizer.bml_parser.writer",
    # the scheduler's pure-Python path for small blocks (2.6 to 3 times
    # faster compiled: docs/performance.md, "Scheduling")
    "realizer.scheduler.tiny",
)

#: The environment variable that makes every module run from its source.
PURE_ENV = "REALIZER_PURE"

# os.path, not pathlib, and nothing else imported at start-up: this runs at
# every ``import realizer`` (``realizer --help`` has a 50 ms budget)
_PACKAGE = os.path.dirname(os.path.abspath(__file__))
#: Written by the build, a line a module: name, size, mtime_ns, SHA-256 of its source.
MANIFEST = os.path.join(_PACKAGE, "_compiled.txt")

#: Why the sources run although extensions are present ("" when they do not).
_reason = ""


def source_path(module: str) -> str:
    """The ``.py`` file of ``module`` (one of :data:`MODULES`)."""
    parts = module.split(".")
    assert parts[0] == "realizer", module
    return os.path.join(_PACKAGE, *parts[1:]) + ".py"


def extension_paths(module: str) -> list[str]:
    """The built extensions of ``module`` for this interpreter (none or one)."""
    stem = source_path(module)[: -len(".py")]
    return [
        stem + suffix
        for suffix in importlib.machinery.EXTENSION_SUFFIXES
        if os.path.isfile(stem + suffix)
    ]


def source_digest(module: str) -> str:
    """The SHA-256 of ``module``'s source, hexadecimal."""
    import hashlib

    with open(source_path(module), "rb") as source:
        return hashlib.sha256(source.read()).hexdigest()


def source_record(module: str) -> str:
    """The manifest's line for ``module``: name, size, mtime_ns, SHA-256."""
    status = os.stat(source_path(module))
    return f"{module} {status.st_size} {status.st_mtime_ns} {source_digest(module)}"


def _stale(modules: Sequence[str]) -> list[str]:
    """The modules whose extension was not built from their present source."""
    recorded: dict[str, list[str]] = {}
    try:
        with open(MANIFEST, encoding="utf-8") as manifest:
            for line in manifest:
                fields = line.split()
                if len(fields) == 4:
                    recorded[fields[0]] = fields[1:]
    except OSError:
        pass
    stale = []
    for module in modules:
        entry = recorded.get(module)
        if entry is None:
            stale.append(module)
            continue
        status = os.stat(source_path(module))
        if entry[:2] == [str(status.st_size), str(status.st_mtime_ns)]:
            continue  # untouched since the build
        if entry[2] != source_digest(module):  # touched: changed only if the hash differs
            stale.append(module)
    return stale


class _Sources:
    """A meta path finder: :data:`MODULES` as their ``.py`` sources, passing
    over the extensions beside them."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> Any:
        if fullname not in MODULES:
            return None
        import importlib.util

        return importlib.util.spec_from_file_location(fullname, source_path(fullname))


def select() -> None:
    """Run the sources of :data:`MODULES` when their extensions must not run.

    Cheap: a ``stat`` a module when nothing is built; with extensions, a
    ``stat`` a source and the manifest read (a source's hash only when its
    size or time changed).
    """
    global _reason
    built = [module for module in MODULES if extension_paths(module)]
    if not built:
        return
    if os.environ.get(PURE_ENV, "") not in ("", "0"):
        _reason = f"{PURE_ENV} is set"
    else:
        stale = _stale(built)
        if not stale:
            return
        names = ", ".join(os.path.basename(source_path(module)) for module in stale)
        _reason = (
            f"stale extensions: {names} changed since the build; "
            "run bash scripts/setup.sh or python scripts/build_compiled.py"
        )
    if not any(isinstance(finder, _Sources) for finder in sys.meta_path):
        sys.meta_path.insert(0, _Sources())


def compiled_modules() -> list[str]:
    """The modules of :data:`MODULES` that run compiled in this process.

    Imports them (``realizer.bml_parser.reader`` imports the parser).
    """
    import importlib

    running = []
    for module in MODULES:
        loaded = importlib.import_module(module)
        spec = loaded.__spec__
        if spec is not None and isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
            running.append(module)
    return running


def mode() -> str:
    """``"compiled"`` (every module of :data:`MODULES`), ``"partly compiled"`` or ``"pure"``."""
    running = compiled_modules()
    if len(running) == len(MODULES):
        return "compiled"
    return "partly compiled" if running else "pure"


def describe() -> str:
    """One line: compiled or pure, and why pure where extensions exist."""
    running = compiled_modules()
    if running and len(running) == len(MODULES):
        return f"compiled (mypyc: {', '.join(m.rpartition('.')[2] for m in running)})"
    if running:
        return f"partly compiled ({', '.join(running)})"
    if _reason:
        return f"pure Python ({_reason})"
    return "pure Python (no compiled modules built: python scripts/build_compiled.py)"
