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
* a source edited since the build (the build records each source's SHA-256
  in ``_compiled.json``): its extension would run old code, so all the
  sources run instead, until the build is run again (``bash
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

import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

#: The modules compiled by ``scripts/build_compiled.py``, by import name.
MODULES: tuple[str, ...] = (
    "realizer.bml_parser.reader",
    "realizer.bml_parser.syncref",
    "realizer.bml_parser.writer",
)

#: The environment variable that makes every module run from its source.
PURE_ENV = "REALIZER_PURE"

_PACKAGE = Path(__file__).resolve().parent
#: Written by the build: each compiled module's source SHA-256.
MANIFEST = _PACKAGE / "_compiled.json"

#: Why the sources run although extensions are present ("" when they do not).
_reason = ""


def source_path(module: str) -> Path:
    """The ``.py`` file of ``module`` (one of :data:`MODULES`)."""
    parts = module.split(".")
    assert parts[0] == "realizer", module
    return _PACKAGE.joinpath(*parts[1:]).with_suffix(".py")


def extension_paths(module: str) -> list[Path]:
    """The built extensions of ``module`` for this interpreter (none or one)."""
    source = source_path(module)
    return [
        path
        for suffix in importlib.machinery.EXTENSION_SUFFIXES
        if (path := source.with_name(source.stem + suffix)).is_file()
    ]


def source_digest(module: str) -> str:
    import hashlib

    return hashlib.sha256(source_path(module).read_bytes()).hexdigest()


def _stale(modules: Sequence[str]) -> list[str]:
    """The modules whose extension was not built from their present source."""
    import json

    try:
        built: dict[str, str] = json.loads(MANIFEST.read_text(encoding="utf-8"))["sources"]
    except (OSError, ValueError, KeyError, TypeError):
        built = {}
    return [module for module in modules if built.get(module) != source_digest(module)]


class _Sources(importlib.abc.MetaPathFinder):
    """Finds :data:`MODULES` as their ``.py`` sources, passing over extensions."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MODULES:
            return None
        return importlib.util.spec_from_file_location(fullname, source_path(fullname))


def select() -> None:
    """Run the sources of :data:`MODULES` when their extensions must not run.

    Cheap when nothing is built (one ``stat`` a module); with extensions,
    hashes the sources (about 100 kB) once per process.
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
        names = ", ".join(source_path(module).name for module in stale)
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
