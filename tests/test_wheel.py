"""The built wheel installs into a fresh virtual environment and runs there.

What a user gets from ``pip install realizer``: the core (parser, session,
client, the command line) with no extra, then ``pip install
'realizer[all]'``. The test builds the wheel from this checkout, installs it
into new venvs and runs the commands as a user would, from a directory
outside the checkout so nothing of the source tree can leak in.

The core is installed with ``pip --no-index --find-links`` from a wheelhouse
(``.cache/wheels/core``, gitignored): the first run fills it with ``pip
download`` (PyPI or the configured index, as any install), later runs need
no network, and an install with no index proves the core needs nothing
beyond what it declares. The core venv's size is bounded by
:data:`CORE_VENV_MIB` (README.md, "Installing it elsewhere", quotes it).

Slow (a minute or two: numpy and lxml, then the extras into a second venv);
it skips when the core's dependencies can be found neither in the
wheelhouse nor on an index.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "bml" / "01_smile.xml"
BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
WHEELHOUSE = ROOT / ".cache" / "wheels" / "core"

#: The most a venv with the core alone may take, in MiB (``du -sk`` / 1024,
#: the venv's own pip and setuptools, 25 MiB, included): 118 MiB measured
#: with numpy 2.4.6 (72), lxml 6.1 (12), websockets, msgpack and the realizer
#: (5). scipy 1.17 adds 142 MiB: the core with it was 260 MiB.
CORE_VENV_MIB = 140
#: Heavy distributions the core must not pull in.
HEAVY = ("scipy", "matplotlib", "PyOpenGL", "Pillow", "trimesh", "tqdm", "psutil", "nats-py")

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


def _new_venv(directory: Path) -> Path:
    venv.EnvBuilder(with_pip=True, clear=True).create(directory)
    return directory / "bin" / "python"


def _install_offline(python: Path, wheel: Path) -> subprocess.CompletedProcess[str]:
    return _run(
        [str(python), "-m", "pip", "install", "-q", "--no-index", "--find-links",
         str(WHEELHOUSE), str(wheel)],
        cwd=python.parent,
        PIP_FIND_LINKS="",
        PIP_EXTRA_INDEX_URL="",
        PIP_CONFIG_FILE=os.devnull,
    )  # fmt: skip


@pytest.fixture(scope="module")
def core_venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new venv with the wheel's core alone, installed with no index."""
    directory = tmp_path_factory.mktemp("core-venv")
    python = _new_venv(directory)
    done = _install_offline(python, wheel)
    if done.returncode != 0:  # an empty or stale wheelhouse: fill it once
        WHEELHOUSE.mkdir(parents=True, exist_ok=True)
        fetched = _run(
            [str(python), "-m", "pip", "download", "-q", "--dest", str(WHEELHOUSE), str(wheel)],
            cwd=directory,
        )
        if fetched.returncode != 0:
            pytest.skip(f"the core's dependencies cannot be downloaded: {fetched.stderr[-500:]}")
        done = _install_offline(python, wheel)
    assert done.returncode == 0, done.stderr
    return directory


@pytest.fixture(scope="module")
def full_venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Another new venv with the wheel and every extra (``[all]``)."""
    directory = tmp_path_factory.mktemp("full-venv")
    python = _new_venv(directory)
    done = _run([str(python), "-m", "pip", "install", "-q", f"{wheel}[all]"], cwd=directory)
    if done.returncode != 0 and "No matching distribution" in done.stderr:
        pytest.skip(f"the extras cannot be installed here: {done.stderr[-500:]}")
    assert done.returncode == 0, done.stderr
    return directory


def size_mib(directory: Path) -> float:
    """``du -sk``'s figure for ``directory``, in MiB."""
    done = subprocess.run(["du", "-sk", str(directory)], capture_output=True, text=True)
    return int(done.stdout.split()[0]) / 1024


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
    assert "realizer/service/static/realizer-client.js" in names
    assert "realizer/examples/bml/01_smile.xml" in names  # what bench parser times
    assert not any(n.startswith("tests/") for n in names)


def test_the_core_alone_is_small_and_parses_and_names_missing_extras(core_venv: Path) -> None:
    python = str(core_venv / "bin" / "python")
    installed = _run([python, "-m", "pip", "list", "--format=freeze"], cwd=core_venv).stdout
    for heavy in HEAVY:
        assert f"{heavy.lower()}==" not in installed.lower(), f"the core pulled {heavy}"
    size = size_mib(core_venv)
    print(f"core venv: {size:.0f} MiB (du -sk), bound {CORE_VENV_MIB}; {installed.split()}")
    assert size <= CORE_VENV_MIB

    helped = realizer(core_venv, "--help")
    assert helped.returncode == 0 and "schedule" in helped.stdout

    parsed = realizer(core_venv, "parse", str(EXAMPLE))
    assert parsed.returncode == 0, parsed.stderr
    assert "faceLexeme" in parsed.stdout

    plotted = realizer(core_venv, "plot", str(EXAMPLE), "-o", "t.png")
    assert plotted.returncode == 2
    assert "'plots' extra" in plotted.stderr and "pip install 'realizer[plots]'" in plotted.stderr
    assert "Traceback" not in plotted.stderr

    rendered = realizer(core_venv, "face", "--faps", "3=400", "-o", "f.png")
    assert rendered.returncode == 2
    assert "'render' extra" in rendered.stderr and "Traceback" not in rendered.stderr

    served = realizer(core_venv, "serve", "--port", "0")
    assert served.returncode == 2
    assert "pip install 'realizer[serve]'" in served.stderr and "Traceback" not in served.stderr

    listed = realizer(core_venv, "bench", "--list")
    assert listed.returncode == 0, listed.stderr
    assert {"parser", "scheduler", "service"} <= set(listed.stdout.split())


def test_the_core_schedules_a_small_block_or_names_the_schedule_extra(core_venv: Path) -> None:
    """The scheduler imports scipy only for big blocks (its sparse path): a
    small block schedules with the core, a big one names the extra. (Had the
    solver imported scipy at module level, every block would name it.)"""
    python = str(core_venv / "bin" / "python")
    lazy = _run([python, "-c", "import realizer.scheduler.solver"], core_venv)
    scheduled = realizer(core_venv, "schedule", "--json", str(EXAMPLE))
    assert "Traceback" not in scheduled.stderr
    if lazy.returncode == 0:
        assert scheduled.returncode == 0, scheduled.stderr
        assert '"start"' in scheduled.stdout
        # a block past the dense path's size needs the sparse solver: scipy
        heads = "".join(
            f'<head id="h{i}" lexeme="NOD" start="{i / 2}" end="{i / 2 + 0.4}"/>' for i in range(60)
        )
        big = core_venv / "big.xml"
        big.write_text(f'<bml xmlns="{BML_NS}" id="big">{heads}</bml>', encoding="utf-8")
        refused = realizer(core_venv, "schedule", str(big))
        assert refused.returncode == 2 and "Traceback" not in refused.stderr
        assert refused.stderr.startswith(
            "realizer: error: realizer schedule needs the 'schedule' extra"
        ), refused.stderr
    else:
        assert "the 'schedule' extra (no module named 'scipy')" in lazy.stderr
        assert scheduled.returncode == 2
        assert scheduled.stderr.startswith(
            "realizer: error: realizer schedule needs the 'schedule' extra"
        )
        assert "pip install 'realizer[schedule]'" in scheduled.stderr


def test_the_core_client_says_clearly_that_nothing_listens(core_venv: Path) -> None:
    with socket.socket() as probe:  # a port where nothing listens
        probe.bind(("127.0.0.1", 0))
        free = probe.getsockname()[1]
    code = f"""
import sys
from realizer.client import ClientError, ServerUnavailable, SubmitClient
try:
    SubmitClient("ws://127.0.0.1:{free}", character="Alice")
except ServerUnavailable as error:
    assert isinstance(error, ClientError)
    print("unavailable:", error)
assert "scipy" not in sys.modules
"""
    done = _run([str(core_venv / "bin" / "python"), "-c", code], core_venv)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("unavailable:") and str(free) in done.stdout


def test_with_the_extras_every_command_runs(full_venv: Path) -> None:
    fresh_venv = full_venv
    print(f"[all] venv: {size_mib(full_venv):.0f} MiB (du -sk)")

    scheduled = realizer(fresh_venv, "schedule", "--json", str(EXAMPLE))
    assert scheduled.returncode == 0, scheduled.stderr
    assert '"start"' in scheduled.stdout

    listed = realizer(fresh_venv, "bench", "--list")
    assert listed.returncode == 0 and "deform" in listed.stdout.split()

    quick = realizer(fresh_venv, "bench", "convert", "--quick")
    assert quick.returncode == 0, quick.stderr
    parser = realizer(fresh_venv, "bench", "parser", "--quick")
    assert parser.returncode == 0, parser.stderr
    documents = re.search(r"^corpus \+ examples: (\d+) documents", parser.stdout, re.MULTILINE)
    assert documents is not None and int(documents.group(1)) >= 20, parser.stdout

    plotted = realizer(fresh_venv, "plot", str(EXAMPLE), "-o", "t.png")
    assert plotted.returncode == 0, plotted.stderr
    assert (fresh_venv / "t.png").stat().st_size > 1000

    rendered = realizer(fresh_venv, "face", "--faps", "3=400 31=200", "-o", "f.png")
    if rendered.returncode != 0 and "OpenGL" in rendered.stderr and "context" in rendered.stderr:
        pytest.skip(f"no OpenGL offscreen context here: {rendered.stderr[-300:]}")
    assert rendered.returncode == 0, rendered.stderr
    assert (fresh_venv / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_installed_commands_run_and_the_core_client_talks_to_the_installed_server(
    core_venv: Path, full_venv: Path
) -> None:
    """The rest of the commands from the [all] venv, then ``realizer serve``
    from it with ``realizer send`` from the core venv and ``record`` against it."""
    for args in (
        ("facs", "AU12"),
        ("emotion", "--word", "joy"),
        ("faps", str(EXAMPLE), "-o", "smile.fap"),
        ("plot-faps", str(EXAMPLE), "-o", "faps.png"),
        ("serve", "--print-config"),
    ):
        done = realizer(full_venv, *args)
        assert done.returncode == 0, (args, done.stderr)
    assert (full_venv / "smile.fap").stat().st_size > 100
    assert (full_venv / "faps.png").read_bytes()[:4] == b"\x89PNG"

    environment = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    server = subprocess.Popen(
        [str(full_venv / "bin" / "realizer"), "serve", "--port", "0", "--no-idle"],
        cwd=full_venv,
        env=environment,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stderr is not None
        seen: list[str] = []
        found = None
        for line in server.stderr:  # log lines, then "realizer: serving on HOST:PORT (...)"
            seen.append(line)
            found = re.search(r"serving on \S+:(\d+)", line)
            if found is not None or len(seen) > 50:
                break
        assert found is not None, "".join(seen)
        port = found.group(1)
        sent = realizer(core_venv, "send", str(EXAMPLE), "--port", port, "--character", "Ann")
        assert sent.returncode == 0, sent.stderr
        assert "blockProgress" in sent.stdout and ":end" in sent.stdout
        recorded = realizer(
            full_venv, "record", "--port", port, "--seconds", "1", "-o", "frames.jsonl"
        )
        assert recorded.returncode == 0, recorded.stderr
        assert (full_venv / "frames.jsonl").read_text().count("\n") > 10
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            stopped = server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
            stopped = server.wait()
        assert server.stderr is not None
        server.stderr.close()
    assert stopped == 0  # SIGTERM: a clean stop
