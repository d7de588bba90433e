"""The Docker image, checked by reading (no Docker engine runs the tests) and
its health check run against a real server."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType

from tests.service.process import serve_process

ROOT = Path(__file__).resolve().parents[1]
DOCKERFILE = (ROOT / "docker" / "Dockerfile").read_text(encoding="utf-8")


def healthcheck() -> ModuleType:
    spec = importlib.util.spec_from_file_location("healthcheck", ROOT / "docker" / "healthcheck.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_image_is_multi_stage_on_a_pinned_base_with_bench_and_a_port_agnostic_check() -> None:
    base = re.search(r"^ARG PYTHON_IMAGE=(\S+)$", DOCKERFILE, re.MULTILINE)
    assert base is not None and re.fullmatch(r"python:\d+\.\d+\.\d+-slim-\w+", base.group(1))
    assert len(re.findall(r"^FROM ", DOCKERFILE, re.MULTILINE)) == 2
    assert "COPY --from=build" in DOCKERFILE
    assert "MPLCONFIGDIR=" in DOCKERFILE and "realizer bench --list" in DOCKERFILE
    assert "8765/health" not in DOCKERFILE  # the check reads the service's own port
    assert 'CMD ["python", "/opt/realizer/healthcheck.py"]' in DOCKERFILE
    ignored = (ROOT / "docker" / "Dockerfile.dockerignore").read_text(encoding="utf-8")
    for copied in re.findall(r"^COPY (?!--from)(\S+)", DOCKERFILE, re.MULTILINE):
        assert f"!{copied}" in ignored or f"!{copied}/**" in ignored, copied


def test_the_health_check_follows_the_port_on_the_command_line(tmp_path: Path) -> None:
    check = healthcheck()
    cmdline = tmp_path / "cmdline"
    cmdline.write_bytes(b"realizer\0serve\0--port=9123\0")
    assert check.port(str(cmdline)) == "9123"
    with serve_process() as server:
        cmdline.write_bytes(b"/opt/realizer/bin/realizer\0serve\0--port\0%d\0" % server.port)
        assert check.main(str(cmdline)) == 0
    assert check.main(str(cmdline)) == 1  # the server is gone
