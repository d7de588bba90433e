"""The behaviour vocabulary, loaded from ``data/vocabulary.toml``.

Which elements are behaviours in which namespace, the behaviour type each
becomes, its sync points in canonical order and its attributes. Sources are
named in the data file.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

BML_NS = "http://www.bml-initiative.org/bml/bml-1.0"
EXT_NS = "http://www.bml-initiative.org/bml/coreextensions-1.0"
DRAFT_NS = "http://www.mindmakers.org/projects/BML"
REALIZER_NS = "urn:realizer:bml:face-1.0"
#: AsapRealizer's BMLA extension (realizer control: block attributes,
#: activate, interrupt, parameter value changes, feedback status).
BMLA_NS = "http://www.asap-project.org/bmla"

#: Dialect of each namespace the parser understands. ``""`` (no namespace) is
#: read as the draft, which was often written without one.
DIALECTS: dict[str, str] = {
    BML_NS: "bml",
    EXT_NS: "ext",
    DRAFT_NS: "draft",
    REALIZER_NS: "realizer",
    BMLA_NS: "bmla",
    "": "draft",
}

#: Sync points every behaviour type has, in canonical order (BML 1.0).
CANONICAL_SYNCS: tuple[str, ...] = (
    "start",
    "ready",
    "strokeStart",
    "stroke",
    "strokeEnd",
    "relax",
    "end",
)


@dataclass(frozen=True, slots=True)
class BehaviourSpec:
    """What the parser knows about one behaviour element."""

    dialect: str
    element: str
    type: str
    syncs: tuple[str, ...]
    required: tuple[str, ...]
    numeric: tuple[str, ...]
    attributes: frozenset[str]
    #: attribute name -> BML 1.0 sync name, draft spellings included
    sync_attributes: dict[str, str]
    #: (draft name, BML 1.0 name) pairs for sync references, () outside the draft
    sync_aliases: tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class DraftMapping:
    """How the draft's attributes become BML 1.0's (``[draft]`` of the data file)."""

    attributes: dict[str, str]  # draft attribute -> BML 1.0 attribute
    modalities: dict[str, str]  # gaze modality -> BML 1.0 influence
    hands: dict[str, str]  # gesture hand -> BML 1.0 mode


@dataclass(frozen=True, slots=True)
class Vocabulary:
    specs: dict[tuple[str, str], BehaviourSpec]  # (namespace, element) -> spec
    namespaces: dict[str, str]  # dialect -> namespace
    draft_sync_names: dict[str, str]
    all_sync_names: frozenset[str]  # every sync attribute name of any dialect
    draft: DraftMapping

    def spec(self, namespace: str, element: str) -> BehaviourSpec | None:
        return self.specs.get((namespace, element))


@cache
def vocabulary() -> Vocabulary:
    """The vocabulary (loaded once)."""
    raw: dict[str, Any] = tomllib.loads(
        resources.files("realizer.bml_parser").joinpath("data/vocabulary.toml").read_text("utf-8")
    )
    namespaces: dict[str, str] = raw["namespaces"]
    sync_sets: dict[str, list[str]] = raw["syncs"]
    specs: dict[tuple[str, str], BehaviourSpec] = {}
    draft_names: dict[str, str] = raw["draft_sync_names"]
    for dialect, elements in raw["behaviours"].items():
        for element, entry in elements.items():
            syncs = sync_sets[entry["syncs"]]
            sync_attributes = {name: name for name in syncs}
            aliases: tuple[tuple[str, str], ...] = ()
            if dialect == "draft":
                aliases = tuple(draft_names.items())
                sync_attributes.update((a, b) for a, b in aliases if b in syncs)
            spec = BehaviourSpec(
                dialect=dialect,
                element=element,
                type=entry["type"],
                syncs=tuple(sync_sets[entry["syncs"]]),
                required=tuple(entry["required"]),
                numeric=tuple(entry["numeric"]),
                attributes=frozenset(entry["attributes"]),
                sync_attributes=sync_attributes,
                sync_aliases=aliases,
            )
            specs[(namespaces[dialect], element)] = spec
            if dialect == "draft":
                specs[("", element)] = spec
    all_syncs = frozenset(CANONICAL_SYNCS) | frozenset(draft_names) | {"attackPeak"}
    mapping = raw["draft"]
    draft = DraftMapping(mapping["attributes"], mapping["modality"], mapping["hand"])
    return Vocabulary(specs, namespaces, draft_names, all_syncs, draft)


@cache
def prediction_element(
    behaviour_type: str,
) -> tuple[str, str, frozenset[str], tuple[str, ...]] | None:
    """(namespace, element name, attributes, sync attribute names) of the
    element that writes a behaviour of ``behaviour_type`` in feedback: its
    BML 1.0 (or core extension, or this realizer's extension) element,
    whatever dialect the block was written in. None for a type with no such
    element."""
    for spec in vocabulary().specs.values():
        if spec.type == behaviour_type and spec.dialect != "draft":
            namespace = vocabulary().namespaces[spec.dialect]
            return namespace, spec.element, spec.attributes, spec.syncs
    return None
