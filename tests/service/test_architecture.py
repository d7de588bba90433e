"""ARCHITECTURE.md decision 1: only realizer/service/ imports asyncio or
websockets; the rest of the realizer is sans-I/O."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "realizer"
IO_MODULES = {"asyncio", "websockets"}


def imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    roots: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


def test_nothing_outside_the_service_package_imports_asyncio_or_websockets() -> None:
    offenders = {
        str(path.relative_to(PACKAGE)): sorted(imported_roots(path) & IO_MODULES)
        for path in PACKAGE.rglob("*.py")
        if "service" not in path.relative_to(PACKAGE).parts
    }
    assert {name: found for name, found in offenders.items() if found} == {}


def test_within_the_service_only_the_server_and_the_client_do_io() -> None:
    service = PACKAGE / "service"
    doing_io = {path.name for path in service.glob("*.py") if imported_roots(path) & IO_MODULES}
    # the transports of the asyncio shell: the server, its client, and the
    # STOMP bridge that attaches to the server (ARCHITECTURE.md, service/)
    assert doing_io == {"server.py", "client.py", "stomp.py"}


def test_only_the_stomp_bridge_imports_the_stomp_client() -> None:
    users = {
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if "stomp" in imported_roots(path)
    }
    assert users == {"service/stomp.py"}
