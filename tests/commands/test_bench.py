"""``realizer bench``: every area's figures, goals and ratios reach ``--json FILE``."""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path

import pytest

from realizer.cli import main
from realizer.commands import bench

FAKE = """
import sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import figure, skipped

def run(quick=False, port=None):
    figure("speed", 50.0, "us", goal=100.0)
    figure("throughput", 2.0, "x", goal=4.0, higher_is_better=True)
    figure("nothing", float("nan"), "ms")
    skipped("java", "no reference here")
    figure("port", -1.0 if port is None else float(port), "")
"""


@pytest.fixture
def fake_benchmarks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(bench.benchmarks_dir() / "_timing.py", tmp_path / "_timing.py")
    (tmp_path / "bench_fake.py").write_text(FAKE)
    (tmp_path / "bench_plain.py").write_text("def run(quick=False):\n    print('hi')\n")
    monkeypatch.setattr(bench, "benchmarks_dir", lambda: tmp_path)
    monkeypatch.setattr(sys, "path", list(sys.path))
    return tmp_path


def test_json_holds_each_figure_with_its_goal_ratio_and_verdict(
    fake_benchmarks: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = fake_benchmarks / "out.json"
    assert main(["bench", "fake", "plain", "--quick", "--json", str(out), "--port", "8"]) == 0
    printed = capsys.readouterr().out
    assert "speed: 50.0 us  [goal <= 100 us, ratio 0.500: met]" in printed
    assert "throughput: 2.00 x  [goal >= 4.00 x, ratio 0.500: NOT met]" in printed
    report = json.loads(out.read_text())  # strict JSON: no NaN
    assert report["format"] == "realizer-bench/1" and report["quick"] is True
    assert report["machine"]["cpus"] >= 1
    fake = report["areas"]["fake"]
    by_name = {f["name"]: f for f in fake["figures"]}
    assert by_name["speed"] == {
        "name": "speed", "value": 50.0, "unit": "us", "goal": 100.0,
        "higher_is_better": False, "ratio": 0.5, "met": True,
    }  # fmt: skip
    assert by_name["throughput"]["met"] is False and by_name["throughput"]["ratio"] == 0.5
    assert by_name["nothing"]["value"] is None
    assert fake["skipped"] == [{"name": "java", "reason": "no reference here"}]
    # --port reaches the area whose run takes it, and not the one that does not.
    assert by_name["port"]["value"] == 8.0 and fake["options"] == {"port": 8}
    assert report["areas"]["plain"] == {
        "seconds": report["areas"]["plain"]["seconds"], "options": {}, "figures": [],
        "skipped": [],
    }  # fmt: skip
    assert math.isfinite(report["areas"]["plain"]["seconds"])


def test_unknown_area_is_refused(fake_benchmarks: Path) -> None:
    assert main(["bench", "nosuch"]) == 2
