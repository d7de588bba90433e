"""Serialise a BML tree back to XML text.

The writer works from the lossless fields of
:class:`~realizer.bml_parser.nodes.XmlElement`, so a parsed document comes
back equal under XML canonicalisation (C14N 2.0): the same elements,
prefixes, namespace declarations, attributes in the same order, text,
comments and processing instructions. It writes strings directly rather than
building an lxml tree, which keeps it fast.

Elements built by hand need not declare their namespaces: the writer
declares any namespace that is not in scope where it is used.

A block the parser made and nobody changed keeps the text it was read from
(``Block.source``); :func:`serialise` returns that text instead of writing
the tree again, the way an editor saves an unmodified file unchanged.
"""

from __future__ import annotations

import re
from typing import Final

from realizer.bml_parser.nodes import Comment, Node, ProcessingInstruction, XmlElement
from realizer.bml_parser.tree import Block

XML_NS: Final = "http://www.w3.org/XML/1998/namespace"

_TEXT_ESCAPES: Final = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;", "\r": "&#13;"})
_ATTR_ESCAPES: Final = str.maketrans(
    {"&": "&amp;", "<": "&lt;", '"': "&quot;", "\t": "&#9;", "\n": "&#10;", "\r": "&#13;"}
)
# Most values need no escaping; finding that out is cheaper than translating.
_TEXT_SPECIAL: Final = re.compile("[&<>\r]").search
_ATTR_SPECIAL: Final = re.compile('[&<"\t\n\r]').search


def _text(value: str) -> str:
    return value.translate(_TEXT_ESCAPES) if _TEXT_SPECIAL(value) else value


def _attr(value: str) -> str:
    return value.translate(_ATTR_ESCAPES) if _ATTR_SPECIAL(value) else value


def _split(clark: str) -> tuple[str, str]:
    if clark[0] == "{":
        namespace, _, local = clark[1:].partition("}")
        return namespace, local
    return "", clark


class _Writer:
    def __init__(self) -> None:
        self.out: list[str] = []
        self.counter = 0

    def node(self, node: Node, scope: dict[str | None, str]) -> None:
        out = self.out
        if isinstance(node, XmlElement):
            self.element(node, scope)
        elif isinstance(node, Comment):
            out.append(f"<!--{node.text}-->")
        else:
            assert isinstance(node, ProcessingInstruction)
            out.append(f"<?{node.target} {node.text}?>" if node.text else f"<?{node.target}?>")
        if node.tail:
            out.append(_text(node.tail))

    def fresh_prefix(self, scope: dict[str | None, str]) -> str:
        while True:
            prefix = f"ns{self.counter}"
            self.counter += 1
            if prefix not in scope:
                return prefix

    def element(self, element: XmlElement, outer: dict[str | None, str]) -> None:
        out = self.out
        scope = outer
        decls: list[tuple[str | None, str]] = list(element.nsdecls)
        if decls:
            scope = dict(outer)
            scope.update(decls)
        namespace, local = _split(element.tag)
        prefix = element.prefix
        if namespace:
            if scope.get(prefix) != namespace:
                # Built by hand, or a prefix that no longer fits: declare one.
                prefix = (
                    None
                    if prefix is None and None not in scope
                    else (prefix or self.fresh_prefix(scope))
                )
                decls.append((prefix, namespace))
                scope = {**scope, prefix: namespace}
        elif scope.get(None):
            prefix = None
            decls.append((None, ""))
            scope = {**scope, None: ""}
        qname = f"{prefix}:{local}" if prefix and namespace else local
        parts = [f"<{qname}"]
        for declared_prefix, uri in decls:
            name = f"xmlns:{declared_prefix}" if declared_prefix else "xmlns"
            parts.append(f' {name}="{_attr(uri)}"')
        for key, value in element.attributes:
            if key[0] == "{":
                attr_ns, attr_local = _split(key)
                if attr_ns == XML_NS:
                    attr_prefix: str | None = "xml"
                else:
                    attr_prefix = next(
                        (p for p, u in scope.items() if u == attr_ns and p is not None), None
                    )
                    if attr_prefix is None:
                        attr_prefix = self.fresh_prefix(scope)
                        scope = {**scope, attr_prefix: attr_ns}
                        parts.append(f' xmlns:{attr_prefix}="{_attr(attr_ns)}"')
                key = f"{attr_prefix}:{attr_local}"
            parts.append(f' {key}="{_attr(value)}"')
        if not element.text and not element.children:
            parts.append("/>")
            out.append("".join(parts))
            return
        parts.append(">")
        out.append("".join(parts))
        if element.text:
            out.append(_text(element.text))
        for child in element.children:
            self.node(child, scope)
        out.append(f"</{qname}>")


def serialise(node: Block | XmlElement, *, from_source: bool = True) -> str:
    """The XML text of a block (with its prolog and epilog) or of any element.

    A block as the parser made it comes back as the text it was read from
    (``Block.source``: byte for byte, less the XML declaration), which costs
    nothing; any other block or element, or any node with ``from_source``
    false, is written from its fields (equal to the source under C14N 2.0).
    """
    if from_source and isinstance(node, Block) and node.source:
        return node.source
    writer = _Writer()
    if isinstance(node, Block):
        for item in node.prolog:
            writer.node(item, {})
            writer.out.append("\n")
        writer.element(node, {})
        for item in node.epilog:
            writer.out.append("\n")
            writer.node(item, {})
    else:
        writer.element(node, {})
    return "".join(writer.out)


def canonical(text: str | bytes) -> str:
    """C14N 2.0 form (with comments) of an XML document, for comparisons."""
    from xml.etree.ElementTree import canonicalize

    return canonicalize(text if isinstance(text, str) else text.decode("utf-8"), with_comments=True)
