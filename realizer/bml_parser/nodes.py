"""The lossless XML layer under the BML tree.

Every node of a parsed document is one of these (or a typed subclass of
:class:`XmlElement` from :mod:`realizer.bml_parser.tree`). Together they keep
all that XML canonicalisation (C14N 2.0) looks at: element and attribute
names with their namespaces and prefixes, namespace declarations where they
were made, attribute order, text and tails, comments and processing
instructions. That is what makes ``serialise(parse(text))`` give the
document back (Paul 2010, section 3.2: "the BML document can be
reconstructed").

Nodes are immutable; ``line`` is not part of equality.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class Comment:
    """An XML comment, with the text that follows it (its tail)."""

    text: str
    tail: str = ""


@dataclass(frozen=True, slots=True)
class ProcessingInstruction:
    """An XML processing instruction ``<?target text?>``."""

    target: str
    text: str = ""
    tail: str = ""


@dataclass(frozen=True, slots=True)
class XmlElement:
    """An element as written: the base of every typed BML node.

    ``tag`` is a Clark name (``{namespace}local`` or ``local``); ``prefix`` is
    the prefix it was written with (``None`` for the default namespace);
    ``nsdecls`` are the namespace declarations made on this element, in
    order; ``attributes`` are ``(clark name, value)`` pairs in document order.
    """

    tag: str
    attributes: tuple[tuple[str, str], ...] = ()
    text: str = ""
    children: tuple[Node, ...] = ()
    tail: str = ""
    prefix: str | None = None
    nsdecls: tuple[tuple[str | None, str], ...] = ()
    line: int = field(default=0, compare=False)

    @property
    def namespace(self) -> str:
        """The element's namespace URI, or ``""``."""
        return self.tag[1 : self.tag.index("}")] if self.tag[0] == "{" else ""

    @property
    def local_name(self) -> str:
        return self.tag.rpartition("}")[2]

    def get(self, name: str, default: str | None = None) -> str | None:
        """The value of attribute ``name`` (a Clark name), or ``default``."""
        for key, value in self.attributes:
            if key == name:
                return value
        return default

    def elements(self) -> Iterator[XmlElement]:
        """The child elements, skipping comments and processing instructions."""
        for child in self.children:
            if isinstance(child, XmlElement):
                yield child

    def iter(self) -> Iterator[XmlElement]:
        """This element and all its descendant elements, in document order."""
        yield self
        for child in self.elements():
            yield from child.iter()


Node = XmlElement | Comment | ProcessingInstruction
