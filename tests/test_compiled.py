"""The compiled modules (mypyc) and their fallback to the Python sources.

``scripts/build_compiled.py`` (run by ``scripts/setup.sh``) compiles
:data:`realizer.compiled.MODULES` beside their sources; this suite then runs
against the compiled modules. Here: CI runs them compiled (where it can
build), the parser's own tests pass against the sources too
(``REALIZER_PURE=1``), a source edited after the build makes every module
run from its source, and what the compiled reader returns pickles (the
service's planner processes send parse results) and equals what the
sources return.
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from realizer import compiled
from realizer.bml_parser import parse_bml, serialise
from tests.conftest import EXAMPLES, conformance_files

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "scripts" / "build_compiled.py"


def _built() -> bool:
    return all(compiled.extension_paths(module) for module in compiled.MODULES)


def _touched_since_the_build() -> list[str]:
    """The built modules whose source's size or time differ from the build's record."""
    try:
        lines = Path(compiled.MANIFEST).read_text(encoding="utf-8").splitlines()
    except OSError:
        return []
    recorded = {fields[0]: fields[1:3] for fields in map(str.split, lines) if len(fields) == 4}
    touched = []
    for module in compiled.MODULES:
        if not compiled.extension_paths(module) or module not in recorded:
            continue
        status = os.stat(compiled.source_path(module))
        if recorded[module] != [str(status.st_size), str(status.st_mtime_ns)]:
            touched.append(module)
    return touched


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != compiled.PURE_ENV}
    env.update(extra)
    return env


def _describe(cwd: Path, **env: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", "from realizer import compiled; print(compiled.describe())"],
        cwd=cwd,
        env=_env(PYTHONPATH=str(cwd), **env),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_every_listed_module_has_its_source() -> None:
    for module in compiled.MODULES:
        assert os.path.isfile(compiled.source_path(module)), module
        assert module.startswith("realizer."), module


def test_ci_runs_the_compiled_modules() -> None:
    """CI's set-up (scripts/setup.sh) builds them; had it not, the suite would
    quietly test the sources alone."""
    if not os.environ.get("CI"):
        pytest.skip("only CI must run compiled (a developer may not have built them)")
    if os.environ.get(compiled.PURE_ENV, "") not in ("", "0"):
        pytest.skip(f"{compiled.PURE_ENV} is set")
    why = subprocess.run(
        [sys.executable, str(BUILD), "--check"], capture_output=True, text=True, timeout=60
    )
    assert compiled.mode() == "compiled", compiled.describe() + " " + why.stdout


def test_pure_env_and_a_stale_source_make_the_sources_run(tmp_path: Path) -> None:
    """The package copied with its extensions: compiled as built; with
    REALIZER_PURE=1 or an edited reader.py, every module from its source."""
    if not _built():
        pytest.skip(f"no compiled modules here ({compiled.describe()})")
    copy = tmp_path / "realizer"
    shutil.copytree(
        ROOT / "realizer",
        copy,
        ignore=shutil.ignore_patterns("__pycache__", "face", "service"),
    )
    assert _describe(tmp_path).startswith("compiled")
    assert _describe(tmp_path, **{compiled.PURE_ENV: "1"}).startswith(
        f"pure Python ({compiled.PURE_ENV} is set"
    )
    reader = copy / "bml_parser" / "reader.py"
    reader.write_text(reader.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    stale = _describe(tmp_path)
    assert stale.startswith("pure Python (stale extensions: reader.py changed"), stale
    assert "writer" not in stale.partition("changed")[0]  # only the edited one is named


def test_the_compiled_readers_results_pickle_and_equal_the_sources() -> None:
    documents = [*sorted(EXAMPLES.glob("*.xml")), *conformance_files()[:20]]
    results = []
    for path in documents:
        try:
            result = parse_bml(path.read_bytes())
        except Exception:  # refused documents are the hardening tests' business
            continue
        again = pickle.loads(pickle.dumps(result))
        assert again == result and again.block.behaviours == result.block.behaviours
        results.append((path.name, repr(result), serialise(result.block, from_source=False)))
    assert len(results) >= 10
    # the same documents through the sources, in a process of their own
    script = (
        "import sys\n"
        "from pathlib import Path\n"
        "from realizer import compiled\n"
        "from realizer.bml_parser import parse_bml, serialise\n"
        "assert compiled.mode() == 'pure', compiled.describe()\n"
        "for name in sys.argv[1:]:\n"
        "    r = parse_bml(Path(name).read_bytes())\n"
        "    print(repr((Path(name).name, repr(r), serialise(r.block, from_source=False))))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, *(str(p) for p in documents if p.name in dict(
            (name, 0) for name, _, _ in results))],
        cwd=ROOT,
        env=_env(**{compiled.PURE_ENV: "1"}),
        capture_output=True,
        text=True,
        timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [repr(item) for item in results]


@pytest.mark.slow
def test_the_parser_tests_pass_against_the_sources() -> None:
    """tests/bml_parser once more with every module from its source (the
    rest of the suite ran against whatever this process loaded)."""
    if compiled.mode() == "pure":
        pytest.skip("this run is already against the sources")
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:randomly", "tests/bml_parser"],
        cwd=ROOT,
        env=_env(**{compiled.PURE_ENV: "1", "REALIZER_EXPECT_MODE": "pure"}),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert " passed" in done.stdout


def test_choosing_imports_nothing_heavy_at_start_up() -> None:
    """``import realizer`` runs the choice for every command (``realizer
    --help`` has a 50 ms budget): no hashing, JSON or importlib.abc (which
    pulls in importlib.resources, pathlib and tempfile) unless a source
    was touched since the build."""
    touched = _touched_since_the_build()
    if touched:
        # a checkout or rebase rewrites a source's time without changing it:
        # its hash is then checked at every import until the next build
        pytest.skip(
            f"{', '.join(touched)} touched since the build: python scripts/build_compiled.py"
        )
    done = subprocess.run(
        [sys.executable, "-c", "import sys, realizer; "
         "print(sorted(m for m in ('hashlib', 'json', 'importlib.abc', 'importlib.util') "
         "if m in sys.modules))"],
        cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]", compiled.describe()
