"""Parse-and-serialise throughput of the BML parser against bare lxml.

For the conformance corpus plus the examples, and for one block of 5,000
behaviours, this times ``serialise(parse_bml(doc))`` and, as the baseline,
``lxml.etree.tostring(lxml.etree.fromstring(doc))`` with the same hardened
parser settings; it prints documents per second, MB/s and the ratio of our
throughput to lxml's (goal: at least 1/3).

It also prints a floor: lxml's parse plus a Python loop that merely touches
every element's tag, attributes, text, tail and line, which any pure-Python
tree built from lxml must pay; its ratio bounds what the parser can reach.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from lxml import etree

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import best_of, figure

from realizer.bml_parser import BML_NS, parse_bml, serialise
from realizer.bml_parser.reader import _BYTES_PARSER

ROOT = Path(__file__).resolve().parents[1]


def corpus() -> list[bytes]:
    paths = sorted((ROOT / "examples" / "bml").glob("*.xml"))
    # more BML from elsewhere (for example a conformance corpus): a folder of
    # .xml files named by REALIZER_BML_CORPUS
    extra = os.environ.get("REALIZER_BML_CORPUS")
    if extra and Path(extra).is_dir():
        paths += sorted(Path(extra).glob("*.xml"))
    documents = []
    for path in paths:
        data = path.read_bytes()
        try:
            parse_bml(data)
        except Exception:
            continue  # the deliberately broken ones
        documents.append(data)
    return documents


def big_block(behaviours: int) -> bytes:
    lines = [f'<bml xmlns="{BML_NS}" id="big">']
    for i in range(behaviours):
        kind = i % 4
        if kind == 0:
            lines.append(f'  <head id="h{i}" lexeme="NOD" start="{i * 0.1:.1f}"/>')
        elif kind == 1:
            lines.append(f'  <gesture id="g{i}" lexeme="BEAT" stroke="h{i - 1}:stroke+0.2"/>')
        elif kind == 2:
            lines.append(
                f'  <faceLexeme id="f{i}" lexeme="RAISE_BROWS" amount="0.5" '
                f'start="g{i - 1}:start" end="g{i - 1}:end+1"/>'
            )
        else:
            lines.append(
                f'  <speech id="s{i}" start="f{i - 1}:relax"><text>Hello <sync id="a"/>'
                "there, world.</text></speech>"
            )
    lines.append("</bml>")
    return "\n".join(lines).encode()


def measure(name: str, documents: list[bytes], repeats: int) -> None:
    size = sum(len(d) for d in documents)

    def ours() -> None:
        for document in documents:
            serialise(parse_bml(document).block)

    def bare() -> None:
        for document in documents:
            etree.tostring(etree.fromstring(document, _BYTES_PARSER))

    def floor() -> None:
        for document in documents:
            for el in etree.fromstring(document, _BYTES_PARSER).iter():
                (el.tag, tuple(el.attrib.items()), el.text, el.tail, el.sourceline)

    t_ours = best_of(ours, repeats=repeats)
    t_lxml = best_of(bare, repeats=repeats)
    t_floor = best_of(floor, repeats=repeats)
    print(
        f"{name}: {len(documents)} documents, {size / 1e3:.1f} kB\n"
        f"  realizer parse+serialise: {t_ours * 1e3:8.2f} ms  "
        f"({len(documents) / t_ours:9.0f} docs/s, {size / t_ours / 1e6:6.2f} MB/s)\n"
        f"  lxml parse+tostring:      {t_lxml * 1e3:8.2f} ms  "
        f"({len(documents) / t_lxml:9.0f} docs/s, {size / t_lxml / 1e6:6.2f} MB/s)\n"
        f"  floor (lxml parse + touching every element from Python): {t_floor * 1e3:.2f} ms"
    )
    figure(f"{name}: realizer parse+serialise", len(documents) / t_ours, "docs/s")
    figure(f"{name}: lxml parse+tostring", len(documents) / t_lxml, "docs/s")
    figure(f"{name}: ratio realizer/lxml", t_lxml / t_ours, "x", goal=1 / 3, higher_is_better=True)
    figure(f"{name}: ratio floor/lxml", t_lxml / t_floor, "x")


def run(quick: bool = False) -> None:
    repeats = 3 if quick else 7
    measure("corpus + examples", corpus(), repeats)
    measure("one block of 5,000 behaviours", [big_block(5000)], repeats)


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
