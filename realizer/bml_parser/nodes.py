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

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar


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


_T = TypeVar("_T")


def builder(cls: type[_T], *, every_field: bool = False) -> Callable[..., _T]:
    """A constructor of the frozen dataclass ``cls`` that takes every field
    positionally, in declared order.

    It builds the same object as ``cls(...)`` at a fraction of the cost: a
    frozen dataclass's ``__init__`` calls ``object.__setattr__`` once per
    field (17 for a behaviour), which the parser pays for every node of
    every block. Here the object is made as an instance of a private
    subclass that adds no slots and keeps Python's own attribute setting, so
    each field is one plain slot store; then it becomes a ``cls`` (the same
    memory layout, so ``__class__`` may be assigned). Only for classes whose
    fields are all constructor arguments (or with ``every_field``, which
    takes the others too, in declared order) and that have no
    ``__post_init__`` (checked here).
    """
    fields = dataclasses.fields(cls)  # type: ignore[arg-type]
    if not (every_field or all(f.init for f in fields)) or hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__} has fields outside __init__ or a __post_init__")
    # __setattr__ and __delattr__ share one type slot: both must be object's
    # for the interpreter to store into slots directly.
    twin = type(
        f"_Building{cls.__name__}",
        (cls,),
        {
            "__slots__": (),
            "__setattr__": object.__setattr__,
            "__delattr__": object.__delattr__,
        },
    )
    namespace: dict[str, Any] = {"_new": object.__new__, "_cls": cls, "_twin": twin}
    arguments = ", ".join(f"a{index}" for index in range(len(fields)))
    body = "".join(f"    o.{f.name} = a{index}\n" for index, f in enumerate(fields))
    source = f"def make({arguments}):\n    o = _new(_twin)\n{body}    o.__class__ = _cls\n"
    exec(source + "    return o\n", namespace)
    make: Callable[..., _T] = namespace["make"]
    make.__doc__ = f"{cls.__name__}(...) with every field positional, built slot by slot."
    return make
