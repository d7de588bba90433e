"""BML 1.0 feedback messages as XML (namespace http://www.bml-initiative.org/bml/bml-1.0).

The realizer tells the submitter what happens to each block (BML 1.0,
"Feedback"; element and attribute names as the reference parser
saiba/OpenBMLParser writes them):

* ``predictionFeedback``: the planned global times of the block and of every
  sync point of every behaviour, once the block is scheduled;
* ``blockProgress``: ``id="block:start"`` and ``id="block:end"`` with a
  ``globalTime``; an interrupted block ends with ``status="INTERRUPTED"``;
* ``syncPointProgress``: ``id="block:behaviour:sync"`` with the block-relative
  ``time`` and the ``globalTime`` at which time passed the sync point;
* ``warningFeedback``: ``id`` and ``type`` (a BML 1.0 warning type) with the
  message as text.

Times are seconds, written with microsecond precision.
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.sax.saxutils import escape, quoteattr

from realizer.bml_parser import BML_NS

_XMLNS = f"xmlns={quoteattr(BML_NS)}"


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
    return f" characterId={quoteattr(character_id)}" if character_id else ""


def block_progress(
    block_id: str, which: str, global_time: float, character_id: str | None, status: str = ""
) -> Feedback:
    extra = f" status={quoteattr(status)}" if status else ""
    xml = (
        f"<blockProgress {_XMLNS} id={quoteattr(f'{block_id}:{which}')} "
        f'globalTime="{_t(global_time)}"{_character(character_id)}{extra}/>'
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
        f"<warningFeedback {_XMLNS} id={quoteattr(target or block_id)} "
        f"type={quoteattr(warning_type)}{_character(character_id)}>{escape(message)}"
        "</warningFeedback>"
    )
    return Feedback("warning", block_id, time, xml)


#: Sync names that can be written as attributes of a behaviour element.
_ATTRIBUTE_SYNCS = frozenset(
    {"start", "ready", "strokeStart", "stroke", "strokeEnd", "relax", "end", "attackPeak"}
)


def prediction(
    block_id: str,
    start: float,
    end: float,
    behaviours: list[tuple[str, str, dict[str, float]]],
    time: float,
    character_id: str | None,
) -> Feedback:
    """``behaviours``: (element name, id, sync name -> global time)."""
    parts = [
        f"<predictionFeedback {_XMLNS}{_character(character_id)}>",
        f'<bml id={quoteattr(block_id)} globalStart="{_t(start)}" globalEnd="{_t(end)}"/>',
    ]
    for element, behaviour_id, times in behaviours:
        attrs = "".join(
            f' {name}="{_t(value)}"' for name, value in times.items() if name in _ATTRIBUTE_SYNCS
        )
        others = "".join(
            f'<sync id={quoteattr(name)} globalTime="{_t(value)}"/>'
            for name, value in times.items()
            if name not in _ATTRIBUTE_SYNCS
        )
        tag = f"<{element} id={quoteattr(behaviour_id)}{attrs}"
        parts.append(f"{tag}>{others}</{element}>" if others else f"{tag}/>")
    parts.append("</predictionFeedback>")
    return Feedback("prediction", block_id, time, "".join(parts))
