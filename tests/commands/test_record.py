"""``realizer record``: a real service, the command in a subprocess as a viewer."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from realizer.client import SubmitClient
from realizer.face.fapfile import read_fap_file
from tests.service.browser import service_in_thread
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_sessions, smile

ROOT = Path(__file__).resolve().parents[2]


def record(port: int, fmt: str, output: Path, seconds: float = 1.5) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "record", "--port", str(port), "--character", "Rec",
         "--format", fmt, "--seconds", str(seconds), "-o", str(output)],
        cwd=ROOT, capture_output=True, text=True, timeout=60 * UNIT, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.slow
def test_record_writes_faps_arkit_and_message_logs(tmp_path: Path) -> None:
    with service_in_thread(real_sessions(), real_assets(), fps=25.0) as service:
        with SubmitClient(f"ws://127.0.0.1:{service.port}", character="Rec") as submitter:
            # a smile rising for 25 s: the face moves in every frame, so whole
            # frames (not `same`, sent for a face that rests) are measured
            rising = smile("recsmile", 0.0, 30.0).replace(' end="', ' attackPeak="25" end="')
            submitter.submit(rising)
        names = {"coded": "c.fap", "fap": "f.fap", "arkit": "a.csv", "int16": "v.jsonl"}
        out = {fmt: tmp_path / name for fmt, name in names.items()}
        # the first ARKit viewer makes the server build its fit (about a second on a
        # loaded machine), so that recording runs longer
        printed = {
            fmt: record(service.port, fmt, path, 4.0 if fmt == "arkit" else 1.5)
            for fmt, path in out.items()
        }
        bad = subprocess.run(
            [sys.executable, "-m", "realizer", "record", "--port", str(service.port),
             "--format", "int16", "-o", str(tmp_path / "x.csv")],
            cwd=ROOT, capture_output=True, text=True, timeout=60 * UNIT, check=False,
        )  # fmt: skip
    assert bad.returncode == 2 and ".csv needs --format arkit" in bad.stderr
    for fmt in ("coded", "fap"):
        fap = read_fap_file(out[fmt])
        assert fap.frames > 10
        assert fap.mask.any(axis=1).all()  # the smile is on in every frame
    rate = {
        fmt: float(text.split(" bytes/s")[0].rsplit(" ", 1)[1]) for fmt, text in printed.items()
    }
    assert rate["coded"] < rate["fap"] < rate["int16"]
    rows = out["arkit"].read_text().splitlines()
    assert rows[0].split(",")[1] == "eyeBlinkLeft" and len(rows) > 5
    smile_column = rows[0].split(",").index("mouthSmileLeft")
    assert max(float(r.split(",")[smile_column]) for r in rows[1:]) > 0.05
    lines = [json.loads(line) for line in out["int16"].read_text().splitlines()]
    assert {line["type"] for line in lines} <= {"frame", "same"}
    # vertex deltas of a smiling face; a tick that shows the same: a few bytes
    assert all(line["bytes"] > 100 for line in lines if line["type"] == "frame")
    assert all(line["bytes"] <= 21 for line in lines if line["type"] == "same")
    assert sum(line["type"] == "frame" for line in lines) > 10
