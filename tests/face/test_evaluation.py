"""The default face's evaluation by eye (thesis section 4.4): the scores
cover every displacement once, carry Table 4.3's weights, and the figure the
docs state is the one the scores give."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from realizer.face.evaluation import (
    displacements,
    format_scores,
    load_scores,
    parse_scores,
    weighted_score,
)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "default-face.md"

#: Table 4.3's weights (w), transcribed; 51 and 52 are illegible in the
#: text of the table and take those of 4 and 5.
TABLE_4_3_WEIGHTS = {
    **{f: 3 for f in (3, 17, 19, 20, 21, 22, 31, 32, 33, 34, 37, 38, 59, 60)},
    **{f: 1 for f in (4, 5, 14, 27, 28, 29, 30, 35, 36, 51, 52)},
    **{f: 1 for f in range(43, 51)},
    **{f: 1 for f in range(61, 69)},
}
for _fap in range(3, 69):
    TABLE_4_3_WEIGHTS.setdefault(_fap, 2)


def test_there_are_127_displacements_as_in_the_thesis() -> None:
    assert len(displacements()) == 127


def test_the_scores_cover_each_displacement_once_with_table_4_3_weights() -> None:
    rows = load_scores()
    assert [(r.fap, r.direction) for r in rows] == displacements()
    assert {r.fap: r.weight for r in rows} == TABLE_4_3_WEIGHTS
    assert all(r.remark.strip() and r.date and r.commit for r in rows)


def test_a_missing_or_doubled_displacement_is_refused() -> None:
    header = "fap,direction,weight,score,remark,date,commit\n"
    good = "".join(f"{f},{d},2,3,ok,2026-12-02,abc\n" for f, d in displacements())
    assert len(parse_scores(header + good)) == 127
    with pytest.raises(ValueError, match="missing"):
        parse_scores(header + good.split("\n", 1)[1])
    with pytest.raises(ValueError, match="twice"):
        parse_scores(header + good + "3,+,2,3,again,2026-12-02,abc\n")
    with pytest.raises(ValueError, match=r"1\.\.3"):
        parse_scores(header + good.replace("3,+,2,3,", "3,+,2,4,", 1))


def test_the_weighted_score_is_the_weighted_mean() -> None:
    rows = parse_scores(
        "fap,direction,weight,score,remark,date,commit\n"
        + "".join(
            f"{f},{d},{3 if f == 3 else 1},{1 if f == 3 else 3},x,d,c\n" for f, d in displacements()
        )
    )
    assert weighted_score(rows) == pytest.approx((3 * 1 + 126 * 3) / (3 + 126))


def test_the_docs_state_the_figure_the_scores_give() -> None:
    figure = f"{weighted_score(load_scores()):.2f}"
    stated = re.findall(r"weighted score of \*\*(\d\.\d\d)\*\*", DOCS.read_text("utf-8"))
    assert stated == [figure]
    assert figure in format_scores(load_scores())


def test_the_command_prints_the_scores() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "fap-audit", "--scores", "--every"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert "127 displacements" in done.stdout
    assert f"weighted score {weighted_score(load_scores()):.2f}" in done.stdout
