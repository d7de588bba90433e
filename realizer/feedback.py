"""BML 1.0 feedback messages as XML (namespace http://www.bml-initiative.org/bml/bml-1.0).

The realizer tells the submitter what happens to each block (BML 1.0,
"Feedback"; element and attribute names as the reference parser
saiba/OpenBMLParser reads and writes them):

* ``predictionFeedback``: a ``<bml id globalStart globalEnd/>`` for the
  block, then every scheduled behaviour as a valid BML 1.0 behaviour
  element: its own element name (in its own namespace: ``faceFacs`` in the
  core extensions), ``id="block:behaviour"``, its required and understood
  attributes under their BML 1.0 names (a draft ``<head type="NOD">`` is
  predicted as ``<head lexeme="NOD">``), and each sync point's predicted
  global time as the value of its sync attribute; a speech keeps its
  ``<text>`` with the ``<sync id>`` markers in text order, each marker's
  predicted time in its ``ref``;
* ``blockProgress``: ``id="block:start"`` and ``id="block:end"`` with a
  ``globalTime``. The BML 1.0 element has no status attribute; the block's
  status is given the way AsapRealizer's BMLA extension defines it, as
  ``bmla:status`` in the namespace ``http://www.asap-project.org/bmla``:
  ``IN_EXEC`` at the start, ``DONE`` at a normal end, ``INTERRUPTED`` for a
  block stopped while running, ``REVOKED`` for one stopped before it began;
* ``syncPointProgress``: ``id="block:behaviour:sync"`` with the block-relative
  ``time`` and the ``globalTime`` at which time passed the sync point;
* ``warningFeedback``: ``id`` and ``type`` (a BML 1.0 warning type) with the
  message as text.

Times are seconds, written with microsecond precision. Every message is
well-formed XML 1.0 whatever a peer sent: ids, types and messages that did
not come through the parser (an interrupt's block id, a refused character
id) have each character XML 1.0 cannot carry (C0 controls other than tab,
newline and carriage return; U+FFFE, U+FFFF; lone surrogates) replaced by
U+FFFD, the replacement character.
:func:`realizer.bml_parser.feedback.parse_feedback` reads every message back
strictly.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from xml.sax.saxutils import escape, quoteattr

from realizer.bml_parser import BML_NS, Behaviour, TextSync
from realizer.bml_parser.vocabulary import BMLA_NS, prediction_element

_XMLNS = f"xmlns={quoteattr(BML_NS)}"
_BMLA = f"xmlns:bmla={quoteattr(BMLA_NS)}"

# One character class: linear, no backtracking.
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def xml_safe(text: str) -> str:
    """``text`` with each character XML 1.0 cannot carry replaced by U+FFFD."""
    return _NOT_XML.sub("\ufffd", text)


#: BMLA block statuses this realizer reports (AsapRealizer's BMLABlockStatus).
BLOCK_STATUSES = ("IN_EXEC", "DONE", "INTERRUPTED", "REVOKED", "FAILED")


@dataclass(frozen=True, slots=True)
class Feedback:
    """One feedback message: ``kind`` is prediction, blockProgress,
    syncPointProgress or warning; ``time`` the global time (seconds) it is
    about; ``xml`` the BML 1.0 element."""

    kind: str
    block_id: str
    time: float
    xml: str


def _t(seconds: float) -> str:
    return f"{seconds + 0.0:.6f}".rstrip("0").rstrip(".") if seconds == seconds else "nan"


def _character(character_id: str | None) -> str:
    return f" characterId={quoteattr(xml_safe(character_id))}" if character_id else ""


def block_progress(
    block_id: str, which: str, global_time: float, character_id: str | None, status: str = ""
) -> Feedback:
    """``status``: one of :data:`BLOCK_STATUSES` (written as ``bmla:status``), or ``""``."""
    if status and status not in BLOCK_STATUSES:
        raise ValueError(f"unknown block status {status!r}")
    extra = f" {_BMLA} bmla:status={quoteattr(status)}" if status else ""
    xml = (
        f"<blockProgress {_XMLNS}{extra} id={quoteattr(xml_safe(f'{block_id}:{which}'))} "
        f'globalTime="{_t(global_time)}"{_character(character_id)}/>'
    )
    return Feedback("blockProgress", block_id, global_time, xml)


def sync_point_progress(
    block_id: str,
    behaviour_id: str,
    sync: str,
    time: float,
    global_time: float,
    character_id: str | None,
) -> Feedback:
    xml = (
        f"<syncPointProgress {_XMLNS} id={quoteattr(f'{block_id}:{behaviour_id}:{sync}')} "
        f'time="{_t(time)}" globalTime="{_t(global_time)}"{_character(character_id)}/>'
    )
    return Feedback("syncPointProgress", block_id, global_time, xml)


def warning(
    block_id: str, target: str, warning_type: str, message: str, time: float,
    character_id: str | None,
) -> Feedback:  # fmt: skip
    xml = (
        f"<warningFeedback {_XMLNS} id={quoteattr(xml_safe(target or block_id))} "
        f"type={quoteattr(xml_safe(warning_type))}{_character(character_id)}>"
        f"{escape(xml_safe(message))}"
        "</warningFeedback>"
    )
    return Feedback("warning", block_id, time, xml)


@cache
def _prefix(namespace: str) -> str:
    if namespace == BMLA_NS:
        return "bmla"
    return {BML_NS: ""}.get(namespace, "ext" if "coreextensions" in namespace else "rf")


def _behaviour_element(block_id: str, behaviour: Behaviour, times: Mapping[str, float]) -> str:
    element = prediction_element(behaviour.type)
    if element is None:  # no BML 1.0 element for it: nothing valid to predict
        return ""
    namespace, name, attributes, sync_names = element
    prefix = _prefix(namespace)
    tag = f"{prefix}:{name}" if prefix else name
    decl = f" xmlns:{prefix}={quoteattr(namespace)}" if prefix else ""
    parts = [f"<{tag}{decl} id={quoteattr(f'{block_id}:{behaviour.id}')}"]
    for key, value in behaviour.params:
        if key in attributes:
            parts.append(f" {key}={quoteattr(value)}")
    markers = set(behaviour.speech.sync_ids) if behaviour.speech is not None else set()
    for sync in behaviour.syncs:
        # stroke:2.. of a repeated head, and the draft's extra sync points
        # (a draft gaze's stroke), have no attribute on the BML 1.0 element;
        # their times come with the syncPointProgress.
        if sync in times and sync not in markers and sync in sync_names:
            parts.append(f' {sync}="{_t(times[sync])}"')
    if behaviour.type == "parameterValueChange":  # BMLA: its trajectory is a child
        ramp = "".join(
            f" {key}={quoteattr(value)}"
            for key, value in behaviour.params
            if key in ("initialValue", "targetValue")
        )
        kind = quoteattr(behaviour.param("trajectory") or "linear")
        parts.append(f"><{prefix}:trajectory type={kind}{ramp}/></{tag}>")
        return "".join(parts)
    if behaviour.speech is None:
        parts.append("/>")
        return "".join(parts)
    parts.append("><text>")
    for run in behaviour.speech.runs:
        if isinstance(run, TextSync):
            at = times.get(run.id)
            ref = f' ref="{_t(at)}"' if at is not None else ""
            parts.append(f"<sync id={quoteattr(run.id)}{ref}/>")
        else:
            parts.append(escape(run))
    parts.append(f"</text></{tag}>")
    return "".join(parts)


def prediction(
    block_id: str,
    start: float,
    end: float,
    behaviours: Sequence[tuple[Behaviour, Mapping[str, float]]],
    time: float,
    character_id: str | None,
    status: str = "",
) -> Feedback:
    """``behaviours``: each scheduled behaviour with its sync name -> global time;
    ``status``: a BMLA block status for the ``<bml>`` (``PENDING`` for a
    preplanned block), or ``""``."""
    extra = f" {_BMLA} bmla:status={quoteattr(status)}" if status else ""
    parts = [
        f"<predictionFeedback {_XMLNS}{_character(character_id)}>",
        f'<bml id={quoteattr(block_id)}{extra} globalStart="{_t(start)}" globalEnd="{_t(end)}"/>',
    ]
    parts.extend(_behaviour_element(block_id, b, times) for b, times in behaviours)
    parts.append("</predictionFeedback>")
    return Feedback("prediction", block_id, time, "".join(parts))
