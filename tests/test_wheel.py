"""The built wheel installs into a fresh virtual environment and runs there.

What a user gets from ``pip install realizer``: the core (parser, scheduler,
session, client) with no extra, then ``pip install 'realizer[all]'``. The test
builds the wheel from this checkout, installs it into a new venv (pip's cache
makes the second run quick) and runs the commands as a user would, from a
directory outside the checkout so nothing of the source tree can leak in.

Slow (a minute or two: the core's numpy and scipy, then the extras); it needs
PyPI or a warm pip cache, and skips when neither can install the core.
"""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "bml" / "01_smile.xml"

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


def _run(args: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    environment = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    environment.update({"PIP_DISABLE_PIP_VERSION_CHECK": "1", **env})
    return subprocess.run(
        args, cwd=cwd, env=environment, capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    try:
        import build  # noqa: F401
        import hatchling  # noqa: F401
    except ImportError as error:
        pytest.skip(f"building the wheel needs the dev extra's build and hatchling: {error}")
    done = _run(
        [sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(out), "."],
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    (found,) = out.glob("realizer-*.whl")
    return found


@pytest.fixture(scope="module")
def fresh_venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new venv with the wheel's core installed (no extra)."""
    directory = tmp_path_factory.mktemp("venv")
    venv.EnvBuilder(with_pip=True, clear=True).create(directory)
    python = directory / "bin" / "python"
    done = _run([str(python), "-m", "pip", "install", "-q", str(wheel)], cwd=directory)
    if done.returncode != 0 and "No matching distribution" in done.stderr:
        pytest.skip(f"the core's dependencies cannot be installed here: {done.stderr[-500:]}")
    assert done.returncode == 0, done.stderr
    return directory


def realizer(venv_dir: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """Run the installed console script from outside the checkout."""
    return _run([str(venv_dir / "bin" / "realizer"), *args], cwd=venv_dir)


def test_the_wheel_carries_types_licence_and_benchmarks(wheel: Path) -> None:
    import zipfile

    names = set(zipfile.ZipFile(wheel).namelist())
    assert "realizer/py.typed" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "realizer/benchmarks/bench_parser.py" in names
    assert "realizer/service/static/index.html" in names
    assert not any(n.startswith("tests/") for n in names)


def test_the_core_alone_parses_schedules_and_names_missing_extras(fresh_venv: Path) -> None:
    python = str(fresh_venv / "bin" / "python")
    installed = _run([python, "-m", "pip", "list", "--format=freeze"], cwd=fresh_venv).stdout
    for heavy in ("matplotlib", "PyOpenGL", "Pillow", "trimesh", "tqdm"):
        assert f"{heavy}==" not in installed, f"the core pulled {heavy}"

    helped = realizer(fresh_venv, "--help")
    assert helped.returncode == 0 and "schedule" in helped.stdout

    parsed = realizer(fresh_venv, "parse", str(EXAMPLE))
    assert parsed.returncode == 0, parsed.stderr
    assert "faceLexeme" in parsed.stdout

    scheduled = realizer(fresh_venv, "schedule", "--json", str(EXAMPLE))
    assert scheduled.returncode == 0, scheduled.stderr
    assert '"start"' in scheduled.stdout

    client = _run([python, "-c", "import realizer.client as c; print(c.SubmitClient)"], fresh_venv)
    assert client.returncode == 0, client.stderr

    plotted = realizer(fresh_venv, "plot", str(EXAMPLE), "-o", "t.png")
    assert plotted.returncode == 2
    assert "'plots' extra" in plotted.stderr and "pip install 'realizer[plots]'" in plotted.stderr
    assert "Traceback" not in plotted.stderr

    rendered = realizer(fresh_venv, "face", "--faps", "3=400", "-o", "f.png")
    assert rendered.returncode == 2
    assert "'render' extra" in rendered.stderr and "Traceback" not in rendered.stderr

    listed = realizer(fresh_venv, "bench", "--list")
    assert listed.returncode == 0, listed.stderr
    assert {"parser", "scheduler", "service"} <= set(listed.stdout.split())


def test_with_the_extras_every_command_runs(fresh_venv: Path, wheel: Path) -> None:
    python = str(fresh_venv / "bin" / "python")
    done = _run([python, "-m", "pip", "install", "-q", f"{wheel}[all]"], cwd=fresh_venv)
    assert done.returncode == 0, done.stderr

    listed = realizer(fresh_venv, "bench", "--list")
    assert listed.returncode == 0 and "deform" in listed.stdout.split()

    quick = realizer(fresh_venv, "bench", "convert", "--quick")
    assert quick.returncode == 0, quick.stderr

    plotted = realizer(fresh_venv, "plot", str(EXAMPLE), "-o", "t.png")
    assert plotted.returncode == 0, plotted.stderr
    assert (fresh_venv / "t.png").stat().st_size > 1000

    rendered = realizer(fresh_venv, "face", "--faps", "3=400 31=200", "-o", "f.png")
    if rendered.returncode != 0 and "OpenGL" in rendered.stderr and "context" in rendered.stderr:
        pytest.skip(f"no OpenGL offscreen context here: {rendered.stderr[-300:]}")
    assert rendered.returncode == 0, rendered.stderr
    assert (fresh_venv / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
