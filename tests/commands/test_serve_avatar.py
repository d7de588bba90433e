"""``realizer serve --avatar``: the GLB is checked once, its missing ARKit
targets named in one warning."""

from __future__ import annotations

from pathlib import Path

import pytest

from realizer.commands.serve import with_avatar
from realizer.face.arkit import has_targets
from realizer.face.errors import FaceError
from realizer.face.gltf import avatar_report, default_face_glb, glb_json
from tests.service.test_end_to_end import real_assets


@pytest.mark.skipif(not has_targets(), reason="ARKit targets not extracted")
def test_an_avatar_missing_targets_is_served_with_one_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "avatar.glb"
    path.write_bytes(default_face_glb(omit=("tongueOut",)))
    assets = with_avatar(real_assets(), str(path))
    assert assets.avatar == path.read_bytes()
    assert assets.avatar_missing == ("tongueOut",)
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "tongueOut" in warnings[0] and "1 of the 52" in warnings[0]
    document = glb_json(path.read_bytes())
    assert {node["name"] for node in document["nodes"]} >= {"head", "leftEye", "rightEye"}


def test_files_that_are_not_avatars_are_refused(tmp_path: Path) -> None:
    with pytest.raises(FaceError):
        avatar_report(b"not a glb at all, certainly not")
    with pytest.raises(FaceError):
        avatar_report(b"glTF" + b"\x02\x00\x00\x00" + b"\xff" * 40)
    empty = tmp_path / "empty.glb"
    import json
    import struct

    text = json.dumps({"asset": {"version": "2.0"}}).encode()
    text += b" " * (-len(text) % 4)
    empty.write_bytes(
        struct.pack("<III", 0x46546C67, 2, 20 + len(text))
        + struct.pack("<II", len(text), 0x4E4F534A)
        + text
    )
    with pytest.raises(ValueError, match="no ARKit-named morph targets"):
        with_avatar(real_assets(), str(empty))
