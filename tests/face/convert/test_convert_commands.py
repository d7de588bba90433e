"""``realizer facs`` and ``realizer emotion`` on the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from realizer.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_facs_prints_fap_values_as_json(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(capsys, "facs", "1", "2", "12L:0.8", "--json")
    values = json.loads(out)
    assert status == 0
    assert values["31"] == 300.0 and values["33"] == 220.0
    assert values["59"] == pytest.approx(200.0) and "60" not in values


def test_facs_prints_a_table_with_fap_names(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(capsys, "facs", "51")
    assert status == 0 and "head_yaw" in out and "60000.0" in out


def test_facs_reads_another_mapping_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    mapping = tmp_path / "mine.map"
    mapping.write_text("23 L\n53 0.0 1.0 0 -300\n", encoding="utf-8")
    status, out, _ = run(capsys, "facs", "23L:0.5", "--mapping", str(mapping), "--json")
    assert status == 0 and json.loads(out) == {"53": -150.0}


def test_facs_rejects_unknown_aus_with_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = run(capsys, "facs", "99")
    assert status == 2 and "AU 99" in err


def test_emotion_by_word_prints_ranges_as_json(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(capsys, "emotion", "--word", "terrified", "--json")
    ranges = json.loads(out)
    assert status == 0
    assert ranges["3"] == pytest.approx([400 * 6.3 / 4.9, 560 * 6.3 / 4.9])


def test_emotion_by_wheel_point_with_chosen_profiles(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(
        capsys, "emotion", "--angle", "261", "--activation", "3.8", "--wheel", "ideal",
        "--profile", "anger=1", "--profile", "joy=3", "--weighting", "as-printed", "--json",
    )  # fmt: skip
    assert status == 0
    low, high = json.loads(out)["20"]
    assert (round(low), round(high)) == (-301, -202)


def test_emotion_prints_a_readable_profile(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(capsys, "emotion", "--word", "guilty")
    assert status == 0 and "Fear 8 and Sadness 0" in out and "open_jaw" in out


@pytest.mark.parametrize(
    "argv",
    [
        ("emotion", "--word", "boredom"),
        ("emotion", "--angle", "90"),
        ("emotion", "--word", "afraid", "--profile", "fear=99"),
        ("emotion", "--word", "afraid", "--profile", "fear"),
    ],
)
def test_emotion_errors_exit_2(capsys: pytest.CaptureFixture[str], argv: tuple[str, ...]) -> None:
    status, _, err = run(capsys, *argv)
    assert status == 2 and err
