"""realizer fap-audit: every displacement of FAPs 3..68 on the default face
has no folds, moves the right way and side, and far enough to see."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from realizer.commands.fap_sheet import load_sheet_entries
from realizer.face.audit import AuditRow, audit_displacement, audit_face, format_audit
from realizer.face.default import load_default_face


def test_all_127_displacements_of_the_default_face_pass() -> None:
    poses = [(e.fap, e.value, e.jaw_open) for e in load_sheet_entries()]
    rows = audit_face(load_default_face(), poses)
    table = format_audit(rows)
    print(table)
    assert len(rows) == 127
    assert table.splitlines()[-1] == "127 displacements: 127 pass, 0 fail"


def test_the_audit_catches_a_wrong_direction_a_wrong_side_and_a_fold() -> None:
    opened = audit_displacement(load_default_face(), 19, -512)
    assert opened.direction_ok and opened.along_mm > 4  # the sign is taken into account
    flipped = AuditRow(19, 512, "3.1", -4.5, 0.0, 0)
    assert not flipped.direction_ok and not flipped.ok
    other_side = AuditRow(8, 512, "2.6", 9.0, 5.0, 0)
    assert other_side.side_ok is False and not other_side.ok
    folded = AuditRow(4, 512, "2.2", 9.0, None, 3)
    assert not folded.ok
    unseen = AuditRow(31, 128, "4.1", 0.2, 0.0, 0)
    assert not unseen.visible and not unseen.ok


def test_a_fold_is_counted_on_a_real_mesh() -> None:
    face = load_default_face()
    from realizer.face.audit import count_folds

    crushed = np.asarray(face.vertices, dtype=np.float64).copy()
    lip = face.feature_vertex("8.1")
    crushed[lip, 2] -= 0.02  # push one vertex 2 cm through the head
    assert count_folds(face, face.vertices, crushed) > 0
    assert count_folds(face, face.vertices, face.vertices) == 0


def test_the_command_prints_the_table_and_exits_0() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "realizer", "fap-audit"],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    assert "127 displacements: 127 pass, 0 fail" in done.stdout
    assert "close_t_l_eyelid" in done.stdout
