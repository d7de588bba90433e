"""A command whose extra is missing names the extra to install, in one line."""

from __future__ import annotations

import importlib.util
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from realizer import extras
from realizer.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "bml" / "01_smile.xml"


@pytest.fixture
def without(monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    """Make find_spec report the given top-level modules as not installed."""
    real = importlib.util.find_spec

    def hide(*names: str) -> None:
        def find_spec(name: str, package: str | None = None) -> Any:
            return None if name.partition(".")[0] in names else real(name, package)

        monkeypatch.setattr(importlib.util, "find_spec", find_spec)

    return hide


def test_every_extra_of_the_helper_is_an_extra_of_the_package() -> None:
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    optional = declared["optional-dependencies"]
    assert set(extras.EXTRAS) <= set(optional)
    assert "all" in optional
    bundled = optional["all"][0]
    for extra in optional:
        # piper-tts is GPL: opt-in only, never pulled in by [all]
        if extra not in {"all", "dev", "piper"}:
            assert extra in bundled, f"[all] lacks {extra}"


def test_a_plot_without_matplotlib_names_the_plots_extra(
    without: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    without("matplotlib")
    assert main(["plot", str(EXAMPLE), "-o", "never.png"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("realizer: error: realizer plot needs the 'plots' extra")
    assert "pip install 'realizer[plots]'" in err
    assert not Path("never.png").exists()


def test_render_without_opengl_names_the_render_extra(
    without: Callable[..., None], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    without("OpenGL")
    assert main(["render", str(EXAMPLE), "-o", str(tmp_path / "x.mp4")]) == 2
    assert "'render' extra (no module named 'OpenGL')" in capsys.readouterr().err


def test_a_module_not_found_late_is_explained_too() -> None:
    error = ModuleNotFoundError("No module named 'trimesh'", name="trimesh")
    explained = extras.explain(error, "realizer bench")
    assert explained is not None and explained.extra == "bench"
    assert extras.explain(ModuleNotFoundError("x", name="not_ours"), "realizer bench") is None


def test_require_passes_when_the_extra_is_installed() -> None:
    pytest.importorskip("matplotlib")
    extras.require("plots", "realizer plot")


def test_serve_without_scipy_names_the_serve_extra(
    without: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    without("scipy")
    assert main(["serve", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("realizer: error: realizer serve needs the 'serve' extra")
    assert "(no module named 'scipy'): pip install 'realizer[serve]'" in err


def test_serve_print_config_needs_no_extra(
    without: Callable[..., None], capsys: pytest.CaptureFixture[str]
) -> None:
    without("scipy")
    assert main(["serve", "--print-config"]) == 0
    assert capsys.readouterr().out.startswith("[serve]")


def test_a_module_that_needs_scipy_raises_the_missing_extra_error() -> None:
    error = ModuleNotFoundError("No module named 'scipy'", name="scipy.sparse")
    raised = extras.missing_module(error, "schedule", "the scheduler")
    assert isinstance(raised, extras.MissingExtraError) and isinstance(raised, ImportError)
    assert str(raised) == (
        "the scheduler needs the 'schedule' extra (no module named 'scipy'): "
        "pip install 'realizer[schedule]'"
    )
    # a module the extra does not bring is a broken install, not a missing extra
    other = ModuleNotFoundError("No module named 'numpy'", name="numpy")
    assert extras.missing_module(other, "schedule", "the scheduler") is other


def test_the_command_names_its_own_extra_for_a_module_several_extras_bring() -> None:
    from_module = extras.MissingExtraError("schedule", "scipy", "the scheduler")
    for command, extra in [("serve", "serve"), ("schedule", "schedule"), ("plot", "plots")]:
        named = extras.explain(from_module, f"realizer {command}", command)
        assert named is not None and named.extra == extra
        assert str(named).startswith(f"realizer {command} needs the {extra!r} extra")
    late = ModuleNotFoundError("No module named 'scipy'", name="scipy")
    named = extras.explain(late, "realizer render", "render")
    assert named is not None and named.extra == "render"
    assert extras.explain(ImportError("cannot import name x"), "realizer serve", "serve") is None


def test_every_extra_that_brings_scipy_declares_it() -> None:
    optional = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    core = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert not any(dependency.startswith("scipy") for dependency in core)
    for extra, modules in extras.EXTRAS.items():
        if "scipy" in modules:
            assert any(d.startswith("scipy") for d in optional[extra]), extra
    from realizer.cli import SUMMARIES

    for command, extra in extras.COMMAND_EXTRAS.items():
        assert command in SUMMARIES and extra in extras.EXTRAS, command
