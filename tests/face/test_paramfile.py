"""The face parameter file (seed 000 Appendix C) loads and saves without loss."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from realizer.face.deform import deform
from realizer.face.errors import FaceFileError
from realizer.face.model import EaseDeformer, SmoothDeformer
from realizer.face.paramfile import (
    load_face,
    parse_parameters,
    save_face,
    serialise_parameters,
)
from realizer.face.testhead import build_test_head

from .helpers import fap_vector

APPENDIX_C = b"""<?xml version="1.0" encoding="UTF-8"?>
<!-- written by hand in the shape of FaceEditor's files -->
<faceeditor-parameters version="2" xmlns:x="urn:example:extra">
  <fp-positions>
    <fp-position fp="2.2" x="0.0" y="-0.045" z="0.09"/>
    <fp-position fp="3.5" x="0.032" y="0.025" z="0.08" x:note="pupil"/>
  </fp-positions>
  <keep-syncs>19  20 21 22</keep-syncs>
  <deformers>
    <!-- the top middle lip -->
    <ease-deformer x="0" y="-1.0" z="0" fap="4" size="0.012" scalex="1" scaley="0.5"
        scalez="1" use-vertex-mask="true" invert-vertex-mask="false" ease="-20"
        colour="red"/>
    <smooth-deformer x="1" y="0" z="0" fap="39" size="0.025" scalex="1" scaley="1"
        scalez="1" use-vertex-mask="false" invert-vertex-mask="false"
        smooth-center="50" smooth-side="25"/>
    <deformer x="0" y="1" z="0" fap="63"/>
    <muscle-deformer fap="12" origin="zygomatic"/>
    <facedef-mesh fap="6" intervals="-1000 0 500 1000">
      <displacement vertex="50">1 0 0, 0.9 0 0, 1.5 0 4</displacement>
    </facedef-mesh>
  </deformers>
  <vertex-masks>
    <vertex-mask fap="4">1 2 3
      4 5</vertex-mask>
  </vertex-masks>
  <x:extra>kept</x:extra>
</faceeditor-parameters>
"""


def c14n(data: bytes) -> bytes:
    return etree.tostring(etree.fromstring(data), method="c14n")


def test_appendix_c_content_is_read():
    params = parse_parameters(APPENDIX_C)
    assert params.feature_points["3.5"] == (0.032, 0.025, 0.08)
    assert params.keep_syncs == (19, 20, 21, 22)
    ease, smooth, point, table = params.deformers
    assert isinstance(ease, EaseDeformer)
    assert (ease.fap, ease.direction, ease.size, ease.scale) == (4, (0, -1, 0), 0.012, (1, 0.5, 1))
    assert (ease.use_vertex_mask, ease.invert_vertex_mask, ease.ease) == (True, False, -20)
    assert isinstance(smooth, SmoothDeformer)
    assert (smooth.smooth_center, smooth.smooth_side) == (50, 25)
    assert point.fap == 63 and table.fap == 6 and table.vertices == (50,)
    assert params.vertex_masks == {4: (1, 2, 3, 4, 5)}


def test_an_unchanged_file_saves_to_the_same_canonical_xml():
    params = parse_parameters(APPENDIX_C)
    assert c14n(serialise_parameters(params)) == c14n(APPENDIX_C)


def test_changes_are_merged_and_unknown_parts_survive():
    params = parse_parameters(APPENDIX_C)
    ease = params.deformers[0]
    assert isinstance(ease, EaseDeformer)
    changed = dataclasses.replace(
        params,
        deformers=(dataclasses.replace(ease, ease=40.0), *params.deformers[1:]),
        keep_syncs=(19, 20),
        feature_points={**params.feature_points, "9.15": (0.0, -0.03, 0.1)},
    )
    saved = serialise_parameters(changed)
    again = parse_parameters(saved)
    assert again.deformers[0] == dataclasses.replace(ease, ease=40.0)
    assert again.keep_syncs == (19, 20)
    assert again.feature_points["9.15"] == (0.0, -0.03, 0.1)
    text = saved.decode()
    for kept in (
        'colour="red"',
        "muscle-deformer",
        "x:extra",
        "the top middle lip",
        'x:note="pupil"',
        'version="2"',
    ):
        assert kept in text
    # untouched elements keep their text exactly
    assert 'smooth-center="50" smooth-side="25"' in text


def test_removed_settings_disappear_and_new_ones_are_appended():
    params = parse_parameters(APPENDIX_C)
    new = EaseDeformer(19, (0.0, -1.0, 0.0), 0.01)
    changed = dataclasses.replace(params, deformers=(params.deformers[1], new), vertex_masks={})
    again = parse_parameters(serialise_parameters(changed))
    assert again.deformers == (params.deformers[1], new)
    assert again.vertex_masks == {}
    assert b"muscle-deformer" in serialise_parameters(changed)


def test_the_test_head_parameters_round_trip(tmp_path: Path):
    head = build_test_head()
    mesh_path, param_path = save_face(head, tmp_path / "head")
    assert mesh_path.name == "head.npz" and param_path.name == "head.xml"
    first = param_path.read_bytes()
    loaded = load_face(param_path)
    assert loaded.params.deformers == head.params.deformers
    assert dict(loaded.params.feature_points) == dict(head.params.feature_points)
    assert dict(loaded.params.vertex_masks) == dict(head.params.vertex_masks)
    assert c14n(serialise_parameters(loaded.params)) == c14n(first)
    # file -> load -> save -> identical content
    save_face(loaded, tmp_path / "again.npz")
    assert c14n((tmp_path / "again.xml").read_bytes()) == c14n(first)


def test_a_saved_face_deforms_like_the_original(tmp_path: Path):
    head = build_test_head()
    save_face(head, tmp_path / "head")
    loaded = load_face(tmp_path / "head.npz")
    assert np.array_equal(loaded.vertices, head.vertices)
    assert np.array_equal(loaded.faces, head.faces)
    assert loaded.parts.keys() == head.parts.keys()
    vector = fap_vector({3: 300.0, 19: 400.0, 29: 100.0, 47: 200.0, 48: -900.0, 53: 150.0})
    assert np.array_equal(deform(loaded, vector), deform(head, vector))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (b"<faceeditor-parameters><fp-positions>", "well-formed"),
        (b"<parameters/>", "root"),
        (
            b"<faceeditor-parameters><deformers>\n<ease-deformer fap='4' x='0' y='-1' z='0'/>"
            b"</deformers></faceeditor-parameters>",
            "line 2.*size",
        ),
        (
            b"<faceeditor-parameters><deformers><deformer fap='4' x='a' y='0' z='0'/>"
            b"</deformers></faceeditor-parameters>",
            "not a number",
        ),
        (
            b"<faceeditor-parameters><vertex-masks><vertex-mask fap='4'>1 two</vertex-mask>"
            b"</vertex-masks></faceeditor-parameters>",
            "integers",
        ),
    ],
)
def test_bad_files_are_reported(text, message):
    with pytest.raises(FaceFileError, match=message):
        parse_parameters(text)


def test_entities_are_not_expanded():
    text = (
        b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
        b"<faceeditor-parameters><keep-syncs>&e;</keep-syncs></faceeditor-parameters>"
    )
    assert parse_parameters(text).keep_syncs == ()


def test_a_missing_face_file_is_reported(tmp_path: Path):
    with pytest.raises(FaceFileError):
        load_face(tmp_path / "nothing")


def test_a_one_element_name_array_is_read_as_the_name(tmp_path: Path):
    head = build_test_head()
    save_face(head, tmp_path / "head")
    with np.load(tmp_path / "head.npz") as data:
        arrays = {key: data[key] for key in data.files}
    arrays["name"] = np.array(["someone"])
    np.savez(tmp_path / "head.npz", **arrays)
    assert load_face(tmp_path / "head").name == "someone"


def test_the_default_face_parameter_file_round_trips():
    default = pytest.importorskip("realizer.face.default")
    path = default.default_face_path().with_suffix(".xml")
    if not path.exists():
        pytest.skip(f"no default face at {path}")
    original = path.read_bytes()
    assert c14n(serialise_parameters(parse_parameters(original))) == c14n(original)


def test_a_float16_facedef_mesh_round_trips_compactly():
    from realizer.face.facedef import FaceDefMesh
    from realizer.face.model import FaceParameters

    rows = tuple(((0.5, -0.25, 1.0), (0.125, 0.0, -2.0)) for _ in range(200))
    table = FaceDefMesh(19, (-1000.0, 0.0, 1000.0), tuple(range(200)), rows, encoding="float16")
    text = serialise_parameters(FaceParameters({}, deformers=(table,)))
    assert b"<displacement " not in text and b'encoding="float16"' in text
    assert len(text) < 5000  # 1,200 numbers and 200 indices in base64, not decimal text
    back = parse_parameters(text).deformers[0]
    assert back == table
    assert serialise_parameters(FaceParameters({}, deformers=(back,))) == text


def test_a_float16_facedef_mesh_refuses_values_float16_cannot_hold():
    from realizer.face.facedef import FaceDefMesh
    from realizer.face.model import FaceParameters

    table = FaceDefMesh(19, (-1000.0, 1000.0), (0,), (((0.1, 0.0, 0.0),),), encoding="float16")
    with pytest.raises(FaceFileError, match="float16"):
        serialise_parameters(FaceParameters({}, deformers=(table,)))


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("<vertices>AAAAAA==</vertices>", "needs <vertices> and <displacements>"),
        ("<vertices>AAAAAA==</vertices><displacements>AAA=</displacements>", "need"),
        ("<vertices>!!</vertices><displacements>AAA=</displacements>", "base64"),
    ],
)
def test_bad_float16_facedef_meshes_are_reported(body, message):
    text = (
        '<faceeditor-parameters><deformers><facedef-mesh fap="19" intervals="-1000 1000" '
        f'encoding="float16">{body}</facedef-mesh></deformers></faceeditor-parameters>'
    )
    with pytest.raises(FaceFileError, match=message):
        parse_parameters(text)
