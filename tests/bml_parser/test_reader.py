"""The reader: the tree it builds for each part of BML, and its warnings."""

from __future__ import annotations

import pytest

from realizer.bml_parser import (
    BML_NS,
    REALIZER_NS,
    Behaviour,
    BmlSyntaxError,
    Comment,
    ProcessingInstruction,
    SyncRefError,
    WarningType,
    XmlElement,
    canonical,
    parse_bml,
    serialise,
)
from tests.conftest import EXAMPLES


def bml(body: str, attrs: str = 'id="b1"', extra_ns: str = "") -> str:
    return f'<bml xmlns="{BML_NS}" {extra_ns} {attrs}>{body}</bml>'


def only(text: str) -> Behaviour:
    (behaviour,) = parse_bml(text).block.behaviours
    return behaviour


def test_block_attributes_are_read_with_merge_as_default_composition() -> None:
    block = parse_bml(bml("", 'id="b1" characterId="Alice"')).block
    assert (block.id, block.character_id, block.composition) == ("b1", "Alice", "MERGE")
    block = parse_bml(bml("", 'id="b2" composition="append"')).block
    assert block.composition == "APPEND"


def test_block_without_id_is_rejected() -> None:
    with pytest.raises(BmlSyntaxError, match="no id"):
        parse_bml(f'<bml xmlns="{BML_NS}"/>')


def test_unknown_composition_is_rejected_with_its_column() -> None:
    with pytest.raises(BmlSyntaxError) as caught:
        parse_bml(bml("", 'id="b" composition="MIX"'))
    assert "MIX" in caught.value.message
    assert caught.value.column == bml("", 'id="b" composition="MIX"').index("composition=") + 1


def test_root_must_be_bml() -> None:
    with pytest.raises(BmlSyntaxError, match="root element"):
        parse_bml(f'<block xmlns="{BML_NS}" id="b"/>')


@pytest.mark.parametrize(
    ("element", "syncs"),
    [
        ('<faceLexeme id="x" lexeme="RAISE_BROWS"/>', ("start", "attackPeak", "relax", "end")),
        ('<faceShift id="x" lexeme="RAISE_BROWS"/>', ("start", "end")),
        ('<gaze id="x" target="t"/>', ("start", "ready", "relax", "end")),
        ('<gazeShift id="x" target="t"/>', ("start", "end")),
        (
            '<gesture id="x" lexeme="BEAT"/>',
            ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end"),
        ),
        (
            '<pointing id="x" target="t"/>',
            ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end"),
        ),
        (
            '<head id="x" lexeme="NOD"/>',
            ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end"),
        ),
        (
            '<headDirectionShift id="x" target="t"/>',
            ("start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end"),
        ),
        ('<locomotion id="x" target="t"/>', ("start", "ready", "relax", "end")),
        ('<posture id="x"><stance type="SITTING"/></posture>', ("start", "ready", "relax", "end")),
        ('<postureShift id="x"><stance type="SITTING"/></postureShift>', ("start", "end")),
        ('<speech id="x"><text>hi</text></speech>', ("start", "end")),
        ('<wait id="x"/>', ("start", "end")),
    ],
)
def test_every_core_behaviour_has_its_sync_points_in_canonical_order(
    element: str, syncs: tuple[str, ...]
) -> None:
    behaviour = only(bml(element))
    assert behaviour.syncs == syncs
    assert behaviour.type == element[1:].split()[0].rstrip(">")


def test_head_repetitions_add_numbered_strokes() -> None:
    behaviour = only(bml('<head id="n" lexeme="NOD" repetition="3"/>'))
    assert behaviour.syncs == (
        "start", "ready", "strokeStart", "stroke", "stroke:2", "stroke:3", "strokeEnd", "relax",
        "end",
    )  # fmt: skip


def test_speech_text_keeps_runs_and_sync_markers_in_order() -> None:
    behaviour = only(
        bml('<speech id="s"><text>Hello <sync id="a"/>dear <sync id="b"/>world.</text></speech>')
    )
    assert behaviour.speech is not None
    runs = [r if isinstance(r, str) else f"<{r.id}>" for r in behaviour.speech.runs]
    assert runs == ["Hello ", "<a>", "dear ", "<b>", "world."]
    assert behaviour.speech.plain == "Hello dear world."
    assert behaviour.syncs == ("start", "a", "b", "end")


def test_speech_sync_ids_must_be_unique() -> None:
    with pytest.raises(BmlSyntaxError, match="twice"):
        parse_bml(bml('<speech id="s"><text>a<sync id="x"/>b<sync id="x"/></text></speech>'))


def test_duplicate_behaviour_ids_are_rejected_at_the_second() -> None:
    text = bml('<head id="n" lexeme="NOD"/>\n<head id="n" lexeme="SHAKE"/>')
    with pytest.raises(BmlSyntaxError, match="twice") as caught:
        parse_bml(text)
    assert caught.value.line == 2


def test_sync_attributes_are_parsed_and_keep_their_raw_text() -> None:
    behaviour = only(bml('<head id="n" lexeme="NOD" start=" 1 " stroke="g1:stroke + 0.5"/>'))
    refs = dict(behaviour.sync_refs)
    assert refs["start"].offset == 1.0 and refs["start"].is_time
    assert (refs["stroke"].behaviour, refs["stroke"].offset) == ("g1", 0.5)
    assert refs["stroke"].raw == "g1:stroke + 0.5"


def test_malformed_sync_attribute_is_rejected_with_line_and_column() -> None:
    text = bml('\n  <head id="n" lexeme="NOD" start="n2::start"/>')
    with pytest.raises(SyncRefError) as caught:
        parse_bml(text, source="doc.xml")
    column = text.splitlines()[1].index("start=") + 1
    assert (caught.value.line, caught.value.column) == (2, column)
    assert str(caught.value).startswith(f"doc.xml:2:{column}: error:")


def test_description_alternatives_are_kept_with_priority_and_type() -> None:
    behaviour = only(
        bml(
            '<gesture id="g" lexeme="BEAT"><description priority="2" type="application/x-murml">'
            "<murml/></description></gesture>"
        )
    )
    (description,) = behaviour.descriptions
    assert (description.priority, description.type) == (2, "application/x-murml")


def test_behaviour_missing_a_required_attribute_is_dropped_with_a_warning() -> None:
    result = parse_bml(bml('<head id="n"/><head id="m" lexeme="NOD"/>'))
    assert [b.id for b in result.block.behaviours] == ["m"]
    (warning,) = result.warnings
    assert warning.type is WarningType.CANNOT_CREATE_BEHAVIOR
    assert warning.id == "b1:n" and "lexeme" in warning.message


def test_non_numeric_amount_makes_a_behaviour_uncreatable() -> None:
    result = parse_bml(bml('<faceLexeme id="f" lexeme="RAISE_BROWS" amount="lots"/>'))
    assert result.block.behaviours == ()
    assert result.warnings[0].type is WarningType.CANNOT_CREATE_BEHAVIOR


def test_unknown_behaviour_in_foreign_namespace_is_kept_but_warned_about() -> None:
    text = bml(
        '<x:dance id="d" start="0"/><head id="n" lexeme="NOD"/>', extra_ns='xmlns:x="urn:other"'
    )
    result = parse_bml(text)
    assert [b.id for b in result.block.behaviours] == ["n"]
    assert [w.type for w in result.warnings] == [WarningType.CUSTOM_BEHAVIOUR_NOT_SUPPORTED]
    assert canonical(serialise(result.block)) == canonical(text)


def test_unknown_element_in_bml_namespace_is_warned_about() -> None:
    result = parse_bml(bml('<haed id="n" lexeme="NOD"/>'))
    assert [w.type for w in result.warnings] == [WarningType.BEHAVIOR_TYPE_NOT_SUPPORTED]


def test_custom_attributes_are_warned_about_and_kept() -> None:
    text = bml('<head id="n" lexeme="NOD" x:speed="2" strat="1"/>', extra_ns='xmlns:x="urn:other"')
    result = parse_bml(text)
    assert [w.type for w in result.warnings] == [WarningType.CUSTOM_ATTRIBUTE_NOT_SUPPORTED] * 2
    assert "strat" in result.warnings[1].message
    assert canonical(serialise(result.block)) == canonical(text)


def test_constraints_read_synchronize_before_and_after() -> None:
    block = parse_bml(
        bml(
            '<head id="a" lexeme="NOD"/><head id="b" lexeme="NOD"/>'
            '<constraint id="c"><synchronize ref="a:stroke"><sync ref="b:stroke+1"/></synchronize>'
            '<before ref="a:end"><sync ref="b:start"/></before>'
            '<after ref="b:end"><sync ref="a:relax"/></after></constraint>'
        )
    ).block
    (constraint,) = block.constraints
    kinds = [(r.kind, r.ref.raw if r.ref else None, [s.raw for s in r.syncs]) for r in
             constraint.relations]  # fmt: skip
    assert kinds == [
        ("synchronize", "a:stroke", ["b:stroke+1"]),
        ("before", "a:end", ["b:start"]),
        ("after", "b:end", ["a:relax"]),
    ]


def test_before_without_ref_is_rejected() -> None:
    with pytest.raises(BmlSyntaxError, match="needs a ref"):
        parse_bml(bml('<constraint><before><sync ref="a:start"/></before></constraint>'))


def test_draft_face_facs_parses_as_face_facs_and_serialises_as_written() -> None:
    text = (
        '<bml xmlns="http://www.mindmakers.org/projects/BML" id="d">'
        '<face id="f" type="FACS" au="12" side="LEFT" amount="0.5" stroke_start="0"/>'
        '<head id="h" type="NOD" repeats="2" start="f:attack_peak"/></bml>'
    )
    result = parse_bml(text)
    face, head = result.block.behaviours
    assert (face.type, dict(face.params)) == ("faceFacs", {"au": "12", "side": "LEFT",
                                                            "amount": "0.5"})  # fmt: skip
    assert face.dialect == "draft" and result.block.dialect == "draft"
    assert (head.type, head.lexeme, head.param("repetition")) == ("head", "NOD", "2")
    assert head.syncs.count("stroke:2") == 1
    assert dict(head.sync_refs)["start"].sync == "attackPeak"
    assert serialise(result.block) == text


def test_draft_without_namespace_is_read_as_draft() -> None:
    block = parse_bml('<bml id="d"><face id="f" type="EYEBROW" amount="1"/></bml>').block
    (face,) = block.behaviours
    assert (face.type, face.lexeme, block.dialect) == ("faceLexeme", "EYEBROW", "draft")


def test_core_extension_face_facs() -> None:
    behaviour = only(
        bml(
            '<ext:faceFacs id="f" au="1" side="RIGHT" amount="0.3"/>',
            extra_ns='xmlns:ext="http://www.bml-initiative.org/bml/coreextensions-1.0"',
        )
    )
    assert (behaviour.type, behaviour.dialect, behaviour.number("au", 0)) == ("faceFacs", "ext", 1)


@pytest.mark.parametrize(
    ("element", "kind", "param"),
    [
        ('<rf:fap id="x" values="3=400 31:-200"/>', "fap", ("values", "3=400 31:-200")),
        ('<rf:emotion id="x" word="afraid"/>', "emotion", ("word", "afraid")),
        ('<rf:emotion id="x" angle="70" activation="4.9"/>', "emotion", ("angle", "70")),
        ('<rf:viseme id="x" viseme1="3" viseme2="10" blend="20"/>', "viseme", ("blend", "20")),
        ('<rf:expression id="x" expression1="joy" intensity1="40"/>', "expression",
         ("expression1", "joy")),
    ],
)  # fmt: skip
def test_face_extension_behaviours_parse_with_face_syncs(
    element: str, kind: str, param: tuple[str, str]
) -> None:
    text = bml(element.replace('"/>', '" start="0" attackPeak="1"/>', 1),
               extra_ns=f'xmlns:rf="{REALIZER_NS}"')  # fmt: skip
    behaviour = only(text)
    assert behaviour.type == kind and behaviour.dialect == "realizer"
    assert behaviour.syncs == ("start", "attackPeak", "relax", "end")
    assert behaviour.param(param[0]) == param[1]
    assert canonical(serialise(parse_bml(text).block)) == canonical(text)


@pytest.mark.parametrize(
    "element",
    [
        '<rf:fap id="x" values="99=1"/>',
        '<rf:fap id="x" values="3"/>',
        '<rf:emotion id="x" angle="70"/>',
        '<rf:viseme id="x"/>',
    ],
)
def test_invalid_face_extension_behaviour_is_dropped_with_a_warning(element: str) -> None:
    result = parse_bml(bml(element, extra_ns=f'xmlns:rf="{REALIZER_NS}"'))
    assert result.block.behaviours == ()
    assert result.warnings[0].type is WarningType.CANNOT_CREATE_BEHAVIOR


def test_comments_and_processing_instructions_survive_inside_and_around() -> None:
    text = (
        "<?xml-stylesheet href='a.xsl'?><!-- before -->"
        f'<bml xmlns="{BML_NS}" id="b"><!-- inside --><?pi data?>'
        '<head id="n" lexeme="NOD"><!-- in a behaviour --></head></bml><!-- after -->'
    )
    block = parse_bml(text).block
    assert [type(n) for n in block.prolog] == [ProcessingInstruction, Comment]
    assert [type(n) for n in block.epilog] == [Comment]
    assert canonical(serialise(block)) == canonical(text)


def test_unknown_children_and_nested_namespaces_round_trip() -> None:
    text = (
        f'<bml xmlns="{BML_NS}" xmlns:a="urn:a" id="b" a:flag="1">'
        '<posture id="p"><stance type="STANDING"/><pose part="ARMS" lexeme="CROSSED"/></posture>'
        '<a:x xmlns:b="urn:b" b:y="2"><b:z>text &amp; more</b:z></a:x>'
        '<speech id="s"><text>a &lt; b <sync id="m"/> "quoted"</text></speech></bml>'
    )
    assert canonical(serialise(parse_bml(text).block)) == canonical(text)


def test_hand_built_elements_get_namespace_declarations() -> None:
    element = XmlElement(tag="{urn:x}thing", attributes=(("{urn:y}attr", "v"),))
    text = serialise(element)
    assert "urn:x" in text and "urn:y" in text
    reparsed = canonical(text)
    assert 'attr="v"' in reparsed


def test_str_and_bytes_input_parse_the_same_even_with_an_encoding_declaration() -> None:
    text = f'<?xml version="1.0" encoding="ISO-8859-1"?><bml xmlns="{BML_NS}" id="b"/>'
    assert parse_bml(text).block.id == "b"
    assert parse_bml(text.encode("latin-1")).block.id == "b"


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.xml")), ids=lambda p: p.name)
def test_every_example_parses_without_warnings_and_round_trips(path) -> None:  # type: ignore[no-untyped-def]
    data = path.read_bytes()
    result = parse_bml(data, source=path.name)
    assert result.warnings == ()
    assert result.block.behaviours
    assert canonical(serialise(result.block)) == canonical(data)


def test_there_are_at_least_a_dozen_examples_each_saying_what_it_shows() -> None:
    paths = sorted(EXAMPLES.glob("*.xml"))
    assert len(paths) >= 12
    for path in paths:
        assert parse_bml(path.read_bytes()).block.prolog, f"{path.name} has no comment"


def test_bml_1_0_without_its_namespace_is_explained_with_the_fix() -> None:
    result = parse_bml('<bml id="x"><faceLexeme id="a" lexeme="RAISE_BROWS"/></bml>')
    [warning] = result.warnings
    assert "declares no namespace" in warning.message and "draft of 2008" in warning.message
    assert 'add xmlns="http://www.bml-initiative.org/bml/bml-1.0" to <bml>' in warning.message
