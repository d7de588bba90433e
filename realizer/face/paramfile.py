"""The face parameter file (Paul 2010, §4.3.6, Appendix C) and the face files.

The XML of FaceEditor: under the root ``faceeditor-parameters`` the children
``fp-positions`` (``fp-position`` elements with the feature point and its
three coordinates), ``keep-syncs`` (space-separated FAP numbers),
``deformers`` and ``vertex-masks`` (``vertex-mask fap="n"`` holding vertex
indices), in that order. The DTD of Appendix C names three deformers:
``deformer`` (x y z fap), ``ease-deformer`` (x y z fap size scalex scaley
scalez use-vertex-mask invert-vertex-mask ease) and ``smooth-deformer`` (the
same with smooth-center and smooth-side instead of ease). The thesis truncates
the DTD before ``fp-position``'s attributes; we name them ``fp x y z``.
``x y z`` of a deformer is read as the face's 3D direction of the FAP.

Extensions (optional attributes and elements; a file without them is plain
Appendix C): ``part`` and ``fp`` on the deformers (which vertices, which
centre); ``cosine-deformer`` (raised cosine); ``transform-deformer``
(FaceDefTransform: ``parts type x y z scale pivot-x pivot-y pivot-z |
pivot-fp falloff``); ``dilate-deformer`` and ``roll-deformer`` (pupils,
tongue roll: ``part x y z scale`` and a pivot); ``facedef-mesh fap target
intervals`` with ``displacement vertex="i"`` children ("dx dy dz, dx dy dz"
per interval), or, with ``encoding="float16"``, two compact children:
``vertices`` (base64 little-endian int32) and ``displacements`` (base64
little-endian float16, vertices x intervals x 3; FAPU per FAP unit, where a
thousandth of the feature point's motion is precision enough). Units:
metres, and percent for smooth-center/-side.

Lossless: :func:`read_parameters` keeps the text it read in
``FaceParameters.source``; :func:`write_parameters` merges the current
values back into that document, touching only what changed, so unknown
elements, attributes, comments and formatting survive and an unchanged file
saves to the same canonical XML.

A face on disk is two files with one stem: ``NAME.npz`` (the mesh: arrays
``vertices`` (n, 3) float32 metres, ``faces`` (m, 3) int32, ``part:NAME``
int32 vertex indices, ``attr:NAME`` extra arrays, ``name``) and ``NAME.xml``
(the parameter file). :func:`load_face` and :func:`save_face` read and write
the pair.
"""

from __future__ import annotations

import base64
import binascii
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from realizer.face.errors import FaceFileError
from realizer.face.facedef import FaceDefMesh
from realizer.face.model import (
    CosineDeformer,
    DeformerSetting,
    DilateDeformer,
    EaseDeformer,
    Face,
    FaceParameters,
    InfluenceDeformer,
    PointDeformer,
    RollDeformer,
    SmoothDeformer,
    TransformDeformer,
)

ROOT = "faceeditor-parameters"
SECTIONS = ("fp-positions", "keep-syncs", "deformers", "vertex-masks")
#: Largest parameter file read, bytes (a mask of every vertex of a 100k mesh fits).
MAX_FILE_BYTES = 64 * 1024 * 1024

_TAGS: dict[type, str] = {
    PointDeformer: "deformer",
    EaseDeformer: "ease-deformer",
    SmoothDeformer: "smooth-deformer",
    CosineDeformer: "cosine-deformer",
    TransformDeformer: "transform-deformer",
    DilateDeformer: "dilate-deformer",
    RollDeformer: "roll-deformer",
    FaceDefMesh: "facedef-mesh",
}
DEFORMER_TAGS = frozenset(_TAGS.values())


def _parser() -> etree.XMLParser:
    # no entities, no network, no DTD loading: the file is data
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        huge_tree=False,
        remove_blank_text=False,
    )


def _fmt(value: float) -> str:
    number = float(value)
    return str(int(number)) if number.is_integer() and abs(number) < 1e15 else repr(number)


def _bool(text: str, where: str) -> bool:
    lowered = text.strip().lower()
    if lowered in ("true", "1", "yes"):
        return True
    if lowered in ("false", "0", "no"):
        return False
    raise FaceFileError(f"{where}: {text!r} is not a boolean")


class _Reader:
    def __init__(self, element: Any) -> None:
        self.element = element
        self.where = f"line {element.sourceline}: <{element.tag}>"

    def text(self, name: str, default: str | None = None) -> str:
        value = self.element.get(name)
        if value is None:
            if default is None:
                raise FaceFileError(f"{self.where} needs the attribute {name!r}")
            return default
        return str(value)

    def optional(self, name: str) -> str | None:
        value = self.element.get(name)
        return None if value is None else str(value)

    def number(self, name: str, default: float | None = None) -> float:
        raw = self.element.get(name)
        if raw is None:
            if default is None:
                raise FaceFileError(f"{self.where} needs the attribute {name!r}")
            return default
        try:
            value = float(raw)
        except ValueError:
            raise FaceFileError(f"{self.where}: {name}={raw!r} is not a number") from None
        if not np.isfinite(value):
            raise FaceFileError(f"{self.where}: {name} must be finite")
        return value

    def integer(self, name: str) -> int:
        raw = self.text(name)
        try:
            return int(raw)
        except ValueError:
            raise FaceFileError(f"{self.where}: {name}={raw!r} is not an integer") from None

    def vec(self, prefix: str = "", default: tuple[float, float, float] | None = None) -> Any:
        names = [f"{prefix}{axis}" for axis in "xyz"]
        if default is not None and all(self.element.get(n) is None for n in names):
            return default
        return tuple(self.number(n) for n in names)

    def pivot(self) -> tuple[Any, str | None]:
        fp = self.optional("pivot-fp")
        if self.element.get("pivot-x") is None:
            return None, fp
        return self.vec("pivot-"), fp


def _read_deformer(element: Any) -> DeformerSetting:
    r = _Reader(element)
    tag = element.tag
    fap = r.integer("fap")
    if tag == "deformer":
        return PointDeformer(fap, r.vec(), r.text("part", "skin"), r.optional("fp"))
    if tag in ("ease-deformer", "smooth-deformer", "cosine-deformer"):
        common = dict(
            fap=fap,
            direction=r.vec(),
            size=r.number("size"),
            scale=(r.number("scalex", 1.0), r.number("scaley", 1.0), r.number("scalez", 1.0)),
            use_vertex_mask=_bool(r.text("use-vertex-mask", "false"), r.where),
            invert_vertex_mask=_bool(r.text("invert-vertex-mask", "false"), r.where),
            part=r.text("part", "skin"),
            feature_point=r.optional("fp"),
        )
        if tag == "ease-deformer":
            return EaseDeformer(**common, ease=r.number("ease", 0.0))
        if tag == "smooth-deformer":
            return SmoothDeformer(
                **common,
                smooth_center=r.number("smooth-center", 0.0),
                smooth_side=r.number("smooth-side", 0.0),
            )
        return CosineDeformer(**common)
    if tag == "transform-deformer":
        kind = r.text("type")
        if kind not in ("rotation", "translation"):
            raise FaceFileError(f"{r.where}: type must be rotation or translation")
        pivot, pivot_fp = r.pivot()
        return TransformDeformer(
            fap,
            tuple(r.text("parts").split()),
            "rotation" if kind == "rotation" else "translation",
            r.vec(),
            r.number("scale", 1.0),
            pivot,
            pivot_fp,
            r.number("falloff", 0.0),
        )
    if tag in ("dilate-deformer", "roll-deformer"):
        pivot, pivot_fp = r.pivot()
        cls = DilateDeformer if tag == "dilate-deformer" else RollDeformer
        return cls(
            fap,
            r.text("part", "tongue" if cls is RollDeformer else None),
            r.vec(default=(0.0, 0.0, 1.0)),
            r.number("scale", 1.0),
            pivot,
            pivot_fp,
        )
    if tag == "facedef-mesh":
        borders = tuple(float(x) for x in r.text("intervals").replace(",", " ").split())
        vertices: list[int] = []
        displacements: list[tuple[tuple[float, float, float], ...]] = []
        encoding = r.text("encoding", "text")
        if encoding == "float16":
            return _binary_facedef(element, r, fap, borders)
        for child in element:
            if not isinstance(child.tag, str) or child.tag != "displacement":
                continue
            cr = _Reader(child)
            numbers = [float(x) for x in (child.text or "").replace(",", " ").split()]
            if len(numbers) % 3:
                raise FaceFileError(f"{cr.where}: displacements come in threes")
            vertices.append(cr.integer("vertex"))
            displacements.append(
                tuple(
                    (numbers[i], numbers[i + 1], numbers[i + 2]) for i in range(0, len(numbers), 3)
                )
            )
        try:
            return FaceDefMesh(
                fap, borders, tuple(vertices), tuple(displacements), r.text("target", "Face")
            )
        except Exception as exc:
            raise FaceFileError(f"{r.where}: {exc}") from exc
    raise FaceFileError(f"{r.where}: not a deformer")  # pragma: no cover


def _binary_facedef(element: Any, r: Any, fap: int, borders: tuple[float, ...]) -> FaceDefMesh:
    """A FaceDefMesh stored compactly: ``<vertices>`` holds the vertex
    indices as base64 little-endian int32, ``<displacements>`` the
    displacements as base64 little-endian float16, (vertices, intervals, 3)."""
    texts: dict[str, str] = {}
    for child in element:
        if isinstance(child.tag, str) and child.tag in ("vertices", "displacements"):
            texts[child.tag] = "".join((child.text or "").split())
    if set(texts) != {"vertices", "displacements"}:
        raise FaceFileError(
            f"{r.where}: a float16 facedef-mesh needs <vertices> and <displacements>"
        )
    try:
        index = np.frombuffer(base64.b64decode(texts["vertices"], validate=True), dtype="<i4")
        values = np.frombuffer(base64.b64decode(texts["displacements"], validate=True), dtype="<f2")
    except (ValueError, binascii.Error) as exc:
        raise FaceFileError(f"{r.where}: bad base64 or array size: {exc}") from None
    intervals = max(len(borders) - 1, 1)
    if values.size != index.size * intervals * 3:
        raise FaceFileError(
            f"{r.where}: {index.size} vertices x {intervals} intervals need "
            f"{index.size * intervals * 3} displacements, not {values.size}"
        )
    if not np.all(np.isfinite(values)) or (index.size and index.min() < 0):
        raise FaceFileError(f"{r.where}: displacements must be finite, vertices >= 0")
    rows = values.astype(np.float64).reshape(index.size, intervals, 3).tolist()
    try:
        return FaceDefMesh(
            fap,
            borders,
            tuple(int(i) for i in index),
            tuple(tuple((d[0], d[1], d[2]) for d in row) for row in rows),
            r.text("target", "Face"),
            "float16",
        )
    except Exception as exc:
        raise FaceFileError(f"{r.where}: {exc}") from exc


def _deformer_attributes(setting: DeformerSetting) -> dict[str, str]:
    """The attributes a setting writes (optional ones only when not default)."""
    attrs: dict[str, str] = {"fap": str(setting.fap)}

    def vec(values: Any, prefix: str = "") -> None:
        for axis, value in zip("xyz", values, strict=True):
            attrs[f"{prefix}{axis}"] = _fmt(value)

    if isinstance(setting, PointDeformer):
        vec(setting.direction)
        if setting.part != "skin":
            attrs["part"] = setting.part
        if setting.feature_point:
            attrs["fp"] = setting.feature_point
    elif isinstance(setting, InfluenceDeformer):
        vec(setting.direction)
        attrs["size"] = _fmt(setting.size)
        for axis, value in zip("xyz", setting.scale, strict=True):
            attrs[f"scale{axis}"] = _fmt(value)
        attrs["use-vertex-mask"] = "true" if setting.use_vertex_mask else "false"
        attrs["invert-vertex-mask"] = "true" if setting.invert_vertex_mask else "false"
        if isinstance(setting, EaseDeformer):
            attrs["ease"] = _fmt(setting.ease)
        if isinstance(setting, SmoothDeformer):
            attrs["smooth-center"] = _fmt(setting.smooth_center)
            attrs["smooth-side"] = _fmt(setting.smooth_side)
        if setting.part != "skin":
            attrs["part"] = setting.part
        if setting.feature_point:
            attrs["fp"] = setting.feature_point
    elif isinstance(setting, TransformDeformer | DilateDeformer | RollDeformer):
        if isinstance(setting, TransformDeformer):
            attrs["parts"] = " ".join(setting.parts)
            attrs["type"] = setting.kind
        else:
            attrs["part"] = setting.part
        vec(setting.axis)
        attrs["scale"] = _fmt(setting.scale)
        if setting.pivot is not None:
            vec(setting.pivot, "pivot-")
        if setting.pivot_fp:
            attrs["pivot-fp"] = setting.pivot_fp
        if isinstance(setting, TransformDeformer) and setting.falloff:
            attrs["falloff"] = _fmt(setting.falloff)
    elif isinstance(setting, FaceDefMesh):
        attrs["target"] = setting.target
        attrs["intervals"] = " ".join(_fmt(b) for b in setting.intervals)
        if setting.encoding != "text":
            attrs["encoding"] = setting.encoding
    return attrs


_OPTIONAL_ATTRIBUTES = (
    "part", "fp", "pivot-x", "pivot-y", "pivot-z", "pivot-fp", "falloff", "encoding",
)  # fmt: skip


def _fill_deformer(element: Any, setting: DeformerSetting) -> None:
    attrs = _deformer_attributes(setting)
    for name in _OPTIONAL_ATTRIBUTES:
        if name not in attrs and name in element.attrib:
            del element.attrib[name]
    for name, value in attrs.items():
        element.set(name, value)
    if isinstance(setting, FaceDefMesh):
        for child in list(element):
            if isinstance(child.tag, str) and child.tag in (
                "displacement", "vertices", "displacements",
            ):  # fmt: skip
                element.remove(child)
        if setting.encoding == "float16":
            table = np.asarray(setting.displacements, dtype=np.float64)
            packed = table.astype("<f2")
            if not np.array_equal(packed.astype(np.float64), table):
                raise FaceFileError(
                    f"FaceDefMesh of FAP {setting.fap}: float16 encoding needs float16 values"
                )
            index = np.asarray(setting.vertices, dtype="<i4")
            child = etree.SubElement(element, "vertices")
            child.text = base64.b64encode(index.tobytes()).decode("ascii")
            child = etree.SubElement(element, "displacements")
            child.text = base64.b64encode(packed.tobytes()).decode("ascii")
            return
        for vertex, rows in zip(setting.vertices, setting.displacements, strict=True):
            child = etree.SubElement(element, "displacement", vertex=str(vertex))
            child.text = ", ".join(" ".join(_fmt(c) for c in row) for row in rows)


# -- reading ----------------------------------------------------------------------------


def parse_parameters(data: bytes | str) -> FaceParameters:
    """Read a face parameter file's text into :class:`FaceParameters`.

    Raises :class:`FaceFileError` (with the line) for malformed XML, a wrong
    root or a bad value. Unknown elements and attributes are ignored here
    and kept in ``source``.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    if len(raw) > MAX_FILE_BYTES:
        raise FaceFileError(f"a face parameter file is at most {MAX_FILE_BYTES} bytes")
    try:
        root = etree.fromstring(raw, _parser())
    except etree.XMLSyntaxError as exc:
        raise FaceFileError(f"not well-formed XML: {exc}") from None
    if root.tag != ROOT:
        raise FaceFileError(f"the root element must be <{ROOT}>, not <{root.tag}>")
    points: dict[str, tuple[float, float, float]] = {}
    keep: tuple[int, ...] = ()
    deformers: list[DeformerSetting] = []
    masks: dict[int, tuple[int, ...]] = {}
    for section in root:
        if not isinstance(section.tag, str):
            continue
        if section.tag == "fp-positions":
            for element in _known(section, "fp-position"):
                r = _Reader(element)
                points[_fp_name(element)] = r.vec()
        elif section.tag == "keep-syncs":
            keep = _integers(section.text or "", f"line {section.sourceline}: <keep-syncs>")
        elif section.tag == "deformers":
            deformers.extend(
                _read_deformer(e)
                for e in section
                if isinstance(e.tag, str) and e.tag in DEFORMER_TAGS
            )
        elif section.tag == "vertex-masks":
            for element in _known(section, "vertex-mask"):
                r = _Reader(element)
                masks[r.integer("fap")] = _integers(element.text or "", r.where)
    return FaceParameters(points, keep, tuple(deformers), masks, raw)


def read_parameters(path: str | Path) -> FaceParameters:
    """Read a face parameter file from disk (see :func:`parse_parameters`)."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise FaceFileError(f"{path}: error: no such file") from None
    except OSError as exc:
        raise FaceFileError(f"{path}: error: cannot read it: {exc.strerror}") from None
    return parse_parameters(data)


def _known(section: Any, tag: str) -> list[Any]:
    return [e for e in section if isinstance(e.tag, str) and e.tag == tag]


def _fp_name(element: Any) -> str:
    for name in ("fp", "id", "name"):
        value = element.get(name)
        if value is not None:
            return str(value)
    raise FaceFileError(f"line {element.sourceline}: <fp-position> needs the attribute 'fp'")


def _integers(text: str, where: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in re.split(r"[\s,]+", text.strip()) if x)
    except ValueError:
        raise FaceFileError(f"{where}: expected integers") from None


# -- writing ----------------------------------------------------------------------------


def serialise_parameters(params: FaceParameters) -> bytes:
    """The parameter file's bytes: ``params.source`` with the values merged in.

    Elements whose values did not change are left exactly as they were;
    changed ones get new attribute values (unknown attributes stay);
    settings that are gone are removed and new ones appended. Without a
    source, a fresh, indented document is written.
    """
    fresh = params.source is None
    if params.source is not None:
        root = etree.fromstring(params.source, _parser())
    else:
        root = etree.Element(ROOT)
    sections = {}
    for name in SECTIONS:
        found = _known(root, name)
        sections[name] = found[0] if found else etree.SubElement(root, name)

    _merge_points(sections["fp-positions"], params)
    keep = sections["keep-syncs"]
    if _integers(keep.text or "", "keep-syncs") != tuple(params.keep_syncs):
        keep.text = " ".join(str(n) for n in params.keep_syncs)
    _merge_deformers(sections["deformers"], params)
    _merge_masks(sections["vertex-masks"], params)
    if fresh:
        etree.indent(root, space="  ")
    body: bytes = etree.tostring(root, encoding="utf-8", xml_declaration=True)
    return body + (b"" if body.endswith(b"\n") else b"\n")


def _replace_or_append(
    section: Any,
    existing: list[Any],
    wanted: list[Any],
    equal: Callable[[Any, Any], bool],
    tag_of: Callable[[Any], str],
    fill: Callable[[Any, Any], None],
) -> None:
    for index, value in enumerate(wanted):
        if index < len(existing):
            element = existing[index]
            if element.tag == tag_of(value) and equal(element, value):
                continue
            if element.tag != tag_of(value):
                replacement = etree.Element(tag_of(value))
                replacement.tail = element.tail
                section.replace(element, replacement)
                element = replacement
            fill(element, value)
        else:
            element = etree.SubElement(section, tag_of(value))
            fill(element, value)
    for element in existing[len(wanted) :]:
        section.remove(element)


def _merge_points(section: Any, params: FaceParameters) -> None:
    existing = {_fp_name(e): e for e in _known(section, "fp-position")}
    for name, element in existing.items():
        if name not in params.feature_points:
            section.remove(element)
    for name, position in params.feature_points.items():
        element = existing.get(name)
        if element is None:
            element = etree.SubElement(section, "fp-position", fp=name)
        elif _Reader(element).vec() == tuple(float(c) for c in position):
            continue
        for axis, value in zip("xyz", position, strict=True):
            element.set(axis, _fmt(value))


def _merge_deformers(section: Any, params: FaceParameters) -> None:
    existing = [e for e in section if isinstance(e.tag, str) and e.tag in DEFORMER_TAGS]
    _replace_or_append(
        section,
        existing,
        list(params.deformers),
        equal=lambda element, setting: _read_deformer(element) == setting,
        tag_of=lambda setting: _TAGS[type(setting)],
        fill=_fill_deformer,
    )


def _merge_masks(section: Any, params: FaceParameters) -> None:
    existing: dict[int, Any] = {}
    for element in _known(section, "vertex-mask"):
        existing[_Reader(element).integer("fap")] = element
    for fap_number, element in existing.items():
        if fap_number not in params.vertex_masks:
            section.remove(element)
    for fap_number, mask in params.vertex_masks.items():
        element = existing.get(fap_number)
        if element is None:
            element = etree.SubElement(section, "vertex-mask", fap=str(fap_number))
        elif _integers(element.text or "", "vertex-mask") == tuple(mask):
            continue
        element.text = " ".join(str(i) for i in mask)


def write_parameters(params: FaceParameters, path: str | Path) -> None:
    """Write the parameter file (see :func:`serialise_parameters`)."""
    Path(path).write_bytes(serialise_parameters(params))


# -- faces on disk ----------------------------------------------------------------------


def _pair(path: str | Path) -> tuple[Path, Path]:
    base = Path(path)
    if base.suffix in (".npz", ".xml"):
        base = base.with_suffix("")
    return base.with_name(base.name + ".npz"), base.with_name(base.name + ".xml")


def save_face(face: Face, path: str | Path) -> tuple[Path, Path]:
    """Write ``STEM.npz`` (mesh) and ``STEM.xml`` (parameters); returns both paths.

    ``path`` may name either file or the stem.
    """
    mesh_path, param_path = _pair(path)
    arrays: dict[str, np.ndarray] = {
        "vertices": np.asarray(face.vertices, dtype=np.float32),
        "faces": np.asarray(face.faces, dtype=np.int32),
        "name": np.array(face.name),
    }
    for name, indices in face.parts.items():
        arrays[f"part:{name}"] = np.asarray(indices, dtype=np.int32)
    for name, array in face.attributes.items():
        arrays[f"attr:{name}"] = np.asarray(array)
    with open(mesh_path, "wb") as handle:
        np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]
    write_parameters(face.params, param_path)
    return mesh_path, param_path


def load_face(path: str | Path) -> Face:
    """Read a face from ``STEM.npz`` and ``STEM.xml`` (``path``: either, or the stem).

    Raises :class:`FaceFileError` when a file is missing or malformed.
    """
    mesh_path, param_path = _pair(path)
    params = read_parameters(param_path)
    try:
        with np.load(mesh_path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except (OSError, ValueError) as exc:
        raise FaceFileError(f"cannot read the face mesh {mesh_path}: {exc}") from None
    for key in ("vertices", "faces"):
        if key not in arrays:
            raise FaceFileError(f"{mesh_path} has no array {key!r}")
    parts = {k[5:]: v for k, v in arrays.items() if k.startswith("part:")}
    attributes = {k[5:]: v for k, v in arrays.items() if k.startswith("attr:")}
    name = mesh_path.stem
    if "name" in arrays and arrays["name"].size:
        # a 0-d string array (save_face) or a one-element one (other writers)
        name = str(arrays["name"].reshape(-1)[0])
    return Face(arrays["vertices"], arrays["faces"], parts, params, name, attributes)
