"""The layers of docs/architecture.md hold: each package imports only those below it.

Every module of the package is read as source and its imports (also those
inside functions, which run later) are found by walking its syntax tree, so
a lazy import cannot hide a dependency that goes the wrong way.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "realizer"

#: Lower index = lower layer. A module may import from its own layer and below.
LAYERS: tuple[tuple[str, ...], ...] = (
    # the package root only holds its version; extras names missing optional imports
    ("realizer.errors", "realizer", "realizer.extras"),
    ("realizer.bml_parser",),
    ("realizer.face",),
    ("realizer.scheduler",),
    ("realizer.engines",),
    ("realizer.feedback", "realizer.session", "realizer.scene", "realizer.control"),
    ("realizer.service", "realizer.client"),
    ("realizer.commands", "realizer.cli", "realizer.__main__"),
)


def layer_of(module: str) -> int:
    """The layer of a module: its longest listed prefix (the root matches only itself)."""
    best, best_len = len(LAYERS) - 1, -1  # an unlisted module counts as the top
    for index, names in enumerate(LAYERS):
        for name in names:
            inside = module == name or (name != "realizer" and module.startswith(name + "."))
            if inside and len(name) > best_len:
                best, best_len = index, len(name)
    return best


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path, module: str | None = None) -> list[tuple[str, int]]:
    """Every ``realizer`` module the file (module ``module``) imports, with its line."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    module = module or module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join([*base, node.module] if node.module else base)
            else:
                target = node.module or ""
            found.append((target, node.lineno))
    return [(name, line) for name, line in found if name.split(".")[0] == "realizer"]


MODULES = sorted(PACKAGE.rglob("*.py"))


def test_the_package_has_modules_in_every_layer() -> None:
    layers = {layer_of(module_name(p)) for p in MODULES}
    assert layers == set(range(len(LAYERS)))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: module_name(p))
def test_no_module_imports_from_a_layer_above_it(path: Path) -> None:
    own = layer_of(module_name(path))
    wrong = [f"line {line}: {target}" for target, line in imports(path) if layer_of(target) > own]
    assert not wrong, f"{module_name(path)} imports from above its layer: {wrong}"


def test_the_scheduler_imports_no_engine_and_nothing_of_the_face() -> None:
    for path in (PACKAGE / "scheduler").rglob("*.py"):
        for target, line in imports(path):
            assert not target.startswith(("realizer.engines", "realizer.face")), (
                f"{module_name(path)} line {line} imports {target}"
            )


def test_the_checker_sees_lazy_and_relative_imports(tmp_path: Path) -> None:
    probe = tmp_path / "probe.py"
    probe.write_text(
        "import numpy\n"
        "def later():\n"
        "    from realizer.engines import EngineRegistry\n"
        "    from ..face import tracks\n"
    )
    found = [name for name, _ in imports(probe, "realizer.scheduler.probe")]
    assert found == ["realizer.engines", "realizer.face"]
    assert layer_of("realizer.engines") > layer_of("realizer.scheduler.probe")
