"""A strict reader of BML 1.0 feedback: what a client of this realizer receives.

BML 1.0 ("Feedback") has four messages, each one element in the BML
namespace: ``predictionFeedback``, ``blockProgress``, ``syncPointProgress``
and ``warningFeedback``. :func:`parse_feedback` reads one and checks it the
way the reference parser of the BML community (saiba/OpenBMLParser's
``BMLFeedbackParser``) does, and stricter:

* the element and its attributes: required ones present (``id``,
  ``globalTime``, ``time``, ``type``), times finite numbers, ids of the
  documented shape (``block:sync``, ``block:behaviour:sync``), no attribute
  outside BML 1.0 unless it is in a namespace (custom attributes are legal
  BML); the BMLA ``status`` must be one of AsapRealizer's block statuses;
* a prediction: one or more ``<bml id globalStart? globalEnd?>`` with at
  least one of the two times, and behaviour elements that are each a valid
  BML 1.0 behaviour (``id="block:behaviour"``): it is read by this package's
  own BML parser inside a block of that id and must come out a behaviour,
  with no warning (required attributes kept, speech ``<text>`` with its
  ``<sync>`` markers), and each sync point it gives must carry a predicted
  time (a number), not a reference.

Complexity and limits: one hardened lxml parse (no DTD, no entities, no
network) of at most :attr:`FeedbackLimits.max_bytes`, then one BML parse per
predicted behaviour (at most :attr:`FeedbackLimits.max_behaviours`).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

from lxml import etree

from realizer.bml_parser.errors import BmlError, WarningType
from realizer.bml_parser.reader import Limits, parse_bml
from realizer.bml_parser.tree import Behaviour
from realizer.bml_parser.vocabulary import BML_NS, BMLA_NS

#: Block statuses of AsapRealizer's BMLA (BMLABlockStatus).
BMLA_STATUSES = frozenset(
    {"NONE", "IN_PREP", "PENDING", "LURKING", "IN_EXEC", "SUBSIDING", "DONE", "REVOKED",
     "INTERRUPTED", "FAILED"}
)  # fmt: skip


class FeedbackError(BmlError):
    """A feedback message that is not valid BML 1.0 feedback."""


@dataclass(frozen=True, slots=True)
class FeedbackLimits:
    max_bytes: int = 1024 * 1024
    max_behaviours: int = 20_000


@dataclass(frozen=True, slots=True)
class BlockProgress:
    block_id: str
    sync: str  # "start" or "end" (BMLA adds "relax")
    global_time: float
    character_id: str | None = None
    status: str | None = None  # bmla:status


@dataclass(frozen=True, slots=True)
class SyncPointProgress:
    block_id: str
    behaviour_id: str
    sync: str
    time: float  # seconds from the block's start
    global_time: float
    character_id: str | None = None


@dataclass(frozen=True, slots=True)
class WarningFeedback:
    id: str
    type: WarningType
    text: str
    character_id: str | None = None


@dataclass(frozen=True, slots=True)
class BlockPrediction:
    block_id: str
    global_start: float | None
    global_end: float | None


@dataclass(frozen=True, slots=True)
class BehaviourPrediction:
    block_id: str
    behaviour: Behaviour
    #: sync name -> predicted global time (seconds), canonical order
    times: dict[str, float]


@dataclass(frozen=True, slots=True)
class PredictionFeedback:
    blocks: tuple[BlockPrediction, ...]
    behaviours: tuple[BehaviourPrediction, ...]
    character_id: str | None = None


FeedbackMessage = BlockProgress | SyncPointProgress | WarningFeedback | PredictionFeedback

_PARSER = etree.XMLParser(
    resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False
)  # fmt: skip

_ALLOWED = {
    "blockProgress": {"id", "globalTime", "characterId"},
    "syncPointProgress": {"id", "time", "globalTime", "characterId"},
    "warningFeedback": {"id", "type", "characterId"},
    "predictionFeedback": {"characterId"},
}


def _fail(message: str, element: Any = None) -> FeedbackError:
    line = int(getattr(element, "sourceline", 0) or 0)
    return FeedbackError(message, line=line, source="<feedback>")


def _time(element: Any, name: str, required: bool = True) -> float | None:
    raw = element.get(name)
    if raw is None:
        if required:
            raise _fail(f"<{etree.QName(element).localname}> lacks {name!r}", element)
        return None
    try:
        value = float(raw)
    except ValueError:
        raise _fail(f"{name}={raw!r} is not a number", element) from None
    if not math.isfinite(value):
        raise _fail(f"{name}={raw!r} is not a finite number", element)
    return value


def _check_attributes(element: Any, allowed: set[str]) -> None:
    local = etree.QName(element).localname
    for name, value in element.attrib.items():
        if name[0] == "{":
            if name == f"{{{BMLA_NS}}}status" and value not in BMLA_STATUSES:
                raise _fail(f"bmla:status={value!r} is not a BMLA block status", element)
            continue  # a custom attribute in its own namespace is legal BML
        if name not in allowed:
            raise _fail(f"attribute {name!r} is not BML 1.0 feedback on <{local}>", element)


def _split_id(element: Any, parts: int) -> list[str]:
    raw = element.get("id")
    if not raw:
        raise _fail(f"<{etree.QName(element).localname}> lacks 'id'", element)
    pieces: list[str] = str(raw).split(":", parts - 1)
    if len(pieces) != parts or not all(pieces):
        shape = "block:behaviour:sync" if parts == 3 else "block:sync"
        raise _fail(f"id {raw!r} is not of the form {shape}", element)
    return pieces


def parse_feedback(
    data: str | bytes, *, limits: FeedbackLimits = FeedbackLimits()
) -> FeedbackMessage:
    """Read one feedback message; raise :class:`FeedbackError` if it is not valid."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    if len(raw) > limits.max_bytes:
        raise _fail(f"feedback of {len(raw)} bytes exceeds {limits.max_bytes}")
    if b"<!DOCTYPE" in raw:
        raise _fail("DOCTYPE declarations are not allowed in feedback")
    try:
        root = etree.fromstring(raw, _PARSER)
    except etree.XMLSyntaxError as exc:
        raise _fail(f"not well-formed XML: {exc.msg}") from None
    qname = etree.QName(root)
    if qname.namespace != BML_NS or qname.localname not in _ALLOWED:
        raise _fail(f"{root.tag!r} is not a BML 1.0 feedback element", root)
    local = qname.localname
    _check_attributes(root, _ALLOWED[local])
    character = root.get("characterId")
    if local == "blockProgress":
        block_id, sync = _split_id(root, 2)
        if sync not in ("start", "end", "relax"):
            raise _fail(f"blockProgress sync {sync!r} is not start or end", root)
        global_time = _time(root, "globalTime")
        assert global_time is not None
        if len(root):
            raise _fail("blockProgress has no content", root)
        status = root.get(f"{{{BMLA_NS}}}status")
        return BlockProgress(block_id, sync, global_time, character, status)
    if local == "syncPointProgress":
        block_id, behaviour_id, sync = _split_id(root, 3)
        time, global_time = _time(root, "time"), _time(root, "globalTime")
        assert time is not None and global_time is not None
        return SyncPointProgress(block_id, behaviour_id, sync, time, global_time, character)
    if local == "warningFeedback":
        ident = root.get("id")
        if not ident:
            raise _fail("<warningFeedback> lacks 'id'", root)
        kind = root.get("type")
        if kind not in set(WarningType):
            raise _fail(f"warning type {kind!r} is not a BML 1.0 warning type", root)
        return WarningFeedback(ident, WarningType(kind), root.text or "", character)
    return _prediction(root, character, limits)


def _prediction(root: Any, character: str | None, limits: FeedbackLimits) -> PredictionFeedback:
    blocks: list[BlockPrediction] = []
    behaviours: list[BehaviourPrediction] = []
    for child in root:
        if not isinstance(child.tag, str):
            continue  # comments
        qname = etree.QName(child)
        if qname.namespace == BML_NS and qname.localname == "bml":
            _check_attributes(child, {"id", "globalStart", "globalEnd"})
            block_id = child.get("id")
            if not block_id:
                raise _fail("<bml> in a prediction lacks 'id'", child)
            start, end = _time(child, "globalStart", False), _time(child, "globalEnd", False)
            if start is None and end is None:
                raise _fail("<bml> in a prediction gives neither globalStart nor globalEnd", child)
            blocks.append(BlockPrediction(block_id, start, end))
            continue
        if len(behaviours) >= limits.max_behaviours:
            raise _fail(f"more than {limits.max_behaviours} predicted behaviours", child)
        behaviours.append(_predicted_behaviour(child))
    if not blocks and not behaviours:
        raise _fail("an empty predictionFeedback", root)
    return PredictionFeedback(tuple(blocks), tuple(behaviours), character)


def _predicted_behaviour(element: Any) -> BehaviourPrediction:
    block_id, behaviour_id = _split_id(element, 2)
    local = etree.QName(element).localname
    for child in element:
        if isinstance(child.tag, str) and etree.QName(child).namespace in (BML_NS, None):
            name = etree.QName(child).localname
            if name not in ("text", "description") or (name == "text" and local != "speech"):
                # OpenBMLParser throws here: a speech's <sync> belongs in its <text>
                raise _fail(f"<{name}> is not allowed directly in <{local}>", child)
    wrapper = etree.Element(f"{{{BML_NS}}}bml", nsmap={None: BML_NS})  # type: ignore[dict-item]
    wrapper.set("id", block_id)
    inner = copy.deepcopy(element)
    inner.set("id", behaviour_id)
    wrapper.append(inner)
    try:
        result = parse_bml(etree.tostring(wrapper), source="<prediction>", limits=Limits())
    except BmlError as exc:
        raise _fail(f"predicted <{local}> {behaviour_id!r}: {exc.message}", element) from None
    if result.warnings:
        raise _fail(f"predicted <{local}> {behaviour_id!r}: {result.warnings[0].message}", element)
    [behaviour] = result.block.behaviours or (None,)
    if behaviour is None:
        raise _fail(f"predicted <{local}> {behaviour_id!r} is not a BML 1.0 behaviour", element)
    times: dict[str, float] = {}
    refs = list(behaviour.sync_refs)
    if behaviour.speech is not None:
        refs += [(r.id, r.ref) for r in behaviour.speech.runs
                 if not isinstance(r, str) and r.ref is not None]  # fmt: skip
    for sync, ref in refs:
        if not ref.is_time:
            raise _fail(
                f"predicted {behaviour_id}:{sync} is a reference ({ref.raw!r}), not a time",
                element,
            )
        times[sync] = ref.offset
    ordered = {s: times[s] for s in behaviour.syncs if s in times}
    return BehaviourPrediction(block_id, behaviour, ordered)
