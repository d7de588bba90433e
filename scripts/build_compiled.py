"""Compile the realizer's hot modules with mypyc, in place; or say why not.

    python scripts/build_compiled.py           # build (scripts/setup.sh runs it)
    python scripts/build_compiled.py --clean   # remove the extensions: pure Python
    python scripts/build_compiled.py --check   # exit 1 unless the built ones are current

The modules are :data:`realizer.compiled.MODULES` (the one list). mypyc
(part of mypy, the dev extra) type-checks them with the project's mypy
settings and writes C; setuptools and the system's C compiler build one
extension per module plus their shared library (``realizer/_native__mypyc``),
which are copied beside the sources (gitignored), with ``_compiled.txt``
recording each source's size, time and SHA-256: ``realizer.compiled.select``
runs the sources instead when one changed. The C and objects are built in a
temporary directory, so nothing else lands in the tree.

Without mypy, setuptools, a C compiler or Python's headers nothing is built
and the realizer runs as pure Python; the script says so and exits 0
(``--require``: exits 1, for CI).
"""

from __future__ import annotations

import argparse
import importlib.machinery
import os
import runpy
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "realizer"
#: The shared library of the compiled modules: realizer/_native__mypyc.*.so
GROUP = "realizer._native"

# realizer.compiled without importing the realizer (whose import selects modules)
_compiled = runpy.run_path(str(PACKAGE / "compiled.py"), run_name="realizer_compiled")
MODULES: tuple[str, ...] = _compiled["MODULES"]
source_record = _compiled["source_record"]
stale = _compiled["_stale"]
MANIFEST = Path(_compiled["MANIFEST"])


def source_path(module: str) -> Path:
    return Path(_compiled["source_path"](module))


def built_files() -> list[Path]:
    """Every extension of the compiled modules and their library, for any interpreter."""
    found = [
        path
        for module in MODULES
        for path in source_path(module).parent.glob(source_path(module).stem + ".*.so")
    ]
    found += PACKAGE.glob(GROUP.rpartition(".")[2] + "__mypyc.*.so")
    return found


def clean() -> None:
    for path in built_files():
        path.unlink()
    MANIFEST.unlink(missing_ok=True)


def missing_tools() -> str:
    """Why nothing can be built here, or ``""``."""
    try:
        import mypyc.build  # noqa: F401
        import setuptools  # noqa: F401
    except ImportError as error:
        return f"{error.name} is not installed (pip install -e '.[dev]')"
    compiler = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if shutil.which(compiler) is None:
        return f"no C compiler ({compiler}) on PATH"
    include = Path(sysconfig.get_paths()["include"]) / "Python.h"
    if not include.is_file():
        return f"no Python headers ({include}; Debian: python3-dev)"
    return ""


def build() -> None:
    from mypyc.build import mypycify
    from setuptools import Distribution

    sources = [str(source_path(module)) for module in MODULES]
    clean()
    with tempfile.TemporaryDirectory(prefix="realizer-mypyc-") as scratch:
        work = Path(scratch)
        here = Path.cwd()
        # setuptools reads a pyproject.toml in the working directory; the
        # project's is not for it (hatchling builds the package)
        os.chdir(work)
        try:
            extensions = mypycify(
                [f"--config-file={ROOT / 'pyproject.toml'}", *sources],
                opt_level="3",
                group_name=GROUP,
                target_dir=str(work / "c"),
            )
            distribution = Distribution({"name": "realizer-compiled", "ext_modules": extensions})
            command = distribution.get_command_obj("build_ext")
            command.build_lib = str(work / "lib")
            command.build_temp = str(work / "tmp")
            command.inplace = False
            distribution.run_command("build_ext")
        finally:
            os.chdir(here)
        copied = []
        suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
        for built in (work / "lib").rglob("*" + suffix):
            target = ROOT / built.relative_to(work / "lib")
            if not target.resolve().is_relative_to(PACKAGE):
                raise RuntimeError(f"mypyc built {built.name} outside the package")
            shutil.copyfile(built, target)
            copied.append(target.relative_to(ROOT))
    MANIFEST.write_text(
        "".join(source_record(module) + "\n" for module in MODULES), encoding="utf-8"
    )
    print(f"build_compiled: {len(copied)} extensions: {', '.join(map(str, sorted(copied)))}")


def current() -> bool:
    """True when every module is built from its present source."""
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    built = all(source_path(module).with_suffix(suffix).is_file() for module in MODULES)
    return built and not stale(MODULES)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clean", action="store_true", help="remove the extensions")
    parser.add_argument("--check", action="store_true", help="exit 1 unless they are current")
    parser.add_argument(
        "--require", action="store_true", help="exit 1 when nothing can be built here"
    )
    args = parser.parse_args()
    if args.clean:
        clean()
        print("build_compiled: removed; the realizer runs as pure Python")
        return 0
    if args.check:
        ok = current()
        print(f"build_compiled: {'current' if ok else 'not built, or stale'}")
        return 0 if ok else 1
    missing = missing_tools()
    if missing:
        print(f"build_compiled: not compiled, the realizer runs as pure Python: {missing}")
        return 1 if args.require else 0
    build()
    return 0


if __name__ == "__main__":
    sys.exit(main())
