"""Recursive-descent BML reader over a hardened lxml element tree.

Paul 2010, chapter 3 describes the parser this one grows from: a recursive
descent whose object tree reconstructs the document. Here lxml builds the
element tree (fast, with line numbers) under strict settings, and one
function per grammar rule turns elements into the typed, immutable nodes of
:mod:`realizer.bml_parser.tree`:

    block       := <bml> (behaviour | required | constraint | other)*
    required    := <required> (behaviour | constraint | other)*
    constraint  := <constraint> (synchronize | before | after | other)*
    relation    := <synchronize|before|after ref?> <sync ref>*
    behaviour   := <type id sync-attrs...> (description | text | other)*
    text        := <text> (words | <sync id>)*

Safety: no DTD is loaded, no entity is expanded, nothing is fetched from the
network, a document larger than :attr:`Limits.max_bytes` is refused before
parsing, and any DOCTYPE is refused (entity declarations are how the
"billion laughs" and external-entity attacks work).

Complexity and limits (the document is peer input): reading is linear in
the document's size. The DOCTYPE pre-check is a scanner that never looks
back; sync references are parsed in linear time
(:mod:`realizer.bml_parser.syncref`); the regular expressions left here
are deterministic (no two neighbouring parts can match the same
character). Whatever multiplies work has a named limit in :class:`Limits`:
behaviours per block, nesting depth, attributes per element, sync
references per speech text or constraint relation, strokes of a
repetition, the magnitude of numbers (times and offsets: one hour), the
text of a speech, and warnings per block (repeats collapse into one counted
warning). Columns of warnings are found with a per-line cursor, so all
lookups of one parse are linear too. A block over a limit is refused with a
:class:`~realizer.bml_parser.errors.BmlSecurityError`; a behaviour whose
attribute is out of range is not created, with a warning.
"""

from __future__ import annotations

import gc
import itertools
import re
from typing import Any, Final

from lxml import etree

from realizer.bml_parser.errors import (
    BmlError,
    BmlSecurityError,
    BmlSyntaxError,
    BmlWarning,
    SyncRefError,
    WarningType,
)
from realizer.bml_parser.nodes import Comment, Node, ProcessingInstruction, XmlElement, builder

# the result and the limits are plain Python classes (pickled between the
# service's processes), defined outside this module, which may be compiled
from realizer.bml_parser.result import DEFAULT_LIMITS as DEFAULT_LIMITS
from realizer.bml_parser.result import Limits as Limits
from realizer.bml_parser.result import ParseResult as ParseResult
from realizer.bml_parser.syncref import SyncRef, fast_sync_ref, parse_sync_ref
from realizer.bml_parser.tree import (
    NO_CONTROL,
    Behaviour,
    Block,
    BlockControl,
    Constraint,
    Description,
    Relation,
    Required,
    SpeechText,
    TextSync,
)
from realizer.bml_parser.vocabulary import (
    BML_NS,
    BMLA_NS,
    DIALECTS,
    DRAFT_NS,
    BehaviourSpec,
    vocabulary,
)

COMPOSITIONS: Final = ("MERGE", "APPEND", "REPLACE")
_BMLA_PREFIX: Final = "{" + BMLA_NS + "}"
_RELATION_KINDS: Final = ("synchronize", "before", "after")
_CHECKED_TYPES: Final = frozenset({"fap", "emotion", "head"})
# Clark-name prefixes ("{ns" before the "}") of the namespaces whose
# <description> and <text> children the grammar reads.
_CORE_PREFIXES: Final = frozenset({"{" + BML_NS, "{" + DRAFT_NS, ""})
# A FAP value of a <fap values="3=120 19:-80"> pair: deterministic (the sign,
# the digits, the point and the exponent each start with a character the
# part before cannot match), so matching is linear in the pair's length.
_FAP_NUMBER_RE: Final = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: Warnings of one type about one target listed one by one; the rest are counted.
_REPEATS_LISTED: Final = 4
#: Beyond this many characters a line's column is not looked for (0: unknown).
_COLUMN_WINDOW: Final = 1 << 16


#: The XML namespace's language attribute (BML 1.0 speech language).
_XML_LANG: Final = "{http://www.w3.org/XML/1998/namespace}lang"


def _make_parser(encoding: str | None) -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_comments=False,
        remove_pis=False,
        strip_cdata=True,
        encoding=encoding,
    )


_BYTES_PARSER: Final = _make_parser(None)
_TEXT_PARSER: Final = _make_parser("utf-8")  # str input is encoded as UTF-8 whatever it declares


def _number_within(text: str, limit: float) -> bool:
    """True when ``text`` is a number of magnitude at most ``limit``."""
    try:
        return abs(float(text)) <= limit  # False for inf and nan too
    except ValueError:
        return False


def _fap_pair_ok(pair: str, limit: float) -> bool:
    """True for ``N=value`` or ``N:value`` with N from 1 to 68 and a bounded value.

    ``pair`` holds no whitespace (the caller split on it); linear in its length.
    """
    separator = min((at for at in (pair.find("="), pair.find(":")) if at >= 0), default=-1)
    if separator <= 0:
        return False
    number, value = pair[:separator], pair[separator + 1 :]
    if not (number.isascii() and number.isdigit() and len(number) <= 4):
        return False
    if not 1 <= int(number) <= 68 or _FAP_NUMBER_RE.fullmatch(value) is None:
        return False
    return abs(float(value)) <= limit


class _Reader:
    """One parse: the source for error positions, and the warnings so far."""

    __slots__ = (
        "_cursor",
        "_line_starts",
        "_suppressed",
        "_text",
        "_warned",
        "block_id",
        "block_lang",
        "count_attributes",
        "data",
        "dropped",
        "flat_namespaces",
        "ids",
        "limits",
        "source",
        "vocab",
        "warnings",
    )

    def __init__(self, data: bytes, source: str, limits: Limits) -> None:
        self.data = data
        self.source = source
        self.limits = limits
        self.vocab = vocabulary()
        self.warnings: list[BmlWarning] = []
        # (type, target) -> [index in warnings, how many times reported]
        self._warned: dict[tuple[WarningType, str], list[int]] = {}
        self._suppressed = 0
        self.dropped: set[str] = set()
        self.ids: set[str] = set()
        self.block_id = ""
        self.block_lang: str | None = None  # the block's xml:lang
        # Every attribute has its "=" in the source (entities and DTD
        # defaults are refused): with no more of them in the whole document
        # than one element may hold, no element needs counting.
        self.count_attributes = data.count(b"=") > limits.max_attributes
        self._text: str | None = None  # the decoded source, once a column is asked for
        self._line_starts: list[int] = []
        self._cursor: dict[int, int] = {}  # line -> where its next search starts
        self.flat_namespaces = False

    # -- positions and reports -------------------------------------------

    def column(self, line: int, needle: str) -> int:
        """The 1-based column of ``needle`` on ``line`` (0 when not found).

        Elements and attributes are reported in document order, so each
        line's search starts where its last one matched (falling back to the
        line's start), and looks at most :data:`_COLUMN_WINDOW` characters
        ahead: with the bound on warnings per block, all lookups of one
        parse cost time linear in the document's size.
        """
        if line <= 0:
            return 0
        if self._text is None:
            # line ends as libxml2 counts them (CR LF, CR, LF), made one
            # character each, so columns are the same; all in C, linear
            text = self.data.decode("utf-8", "replace").replace("\r\n", "\n").replace("\r", "\n")
            self._text = text
            lengths = map(len, text.split("\n"))
            self._line_starts = list(itertools.accumulate(map((1).__add__, lengths), initial=0))
        if line >= len(self._line_starts):
            return 0
        line_start = self._line_starts[line - 1]
        line_end = self._line_starts[line]
        begin = self._cursor.get(line, line_start)
        found = self._text.find(needle, begin, min(line_end, begin + _COLUMN_WINDOW))
        if found < 0 and begin > line_start:
            found = self._text.find(needle, line_start, min(line_end, begin + _COLUMN_WINDOW))
        if found < 0:
            return 0
        self._cursor[line] = found + 1
        return found - line_start + 1

    def error(
        self,
        cls: type[BmlError],
        message: str,
        element: Any,
        needle: str = "<",
        warning_type: WarningType = WarningType.PARSING_FAILURE,
    ) -> BmlError:
        line = int(getattr(element, "sourceline", 0) or 0)
        return cls(
            message,
            line=line,
            column=self.column(line, needle),
            source=self.source,
            warning_type=warning_type,
        )

    def warn(
        self, kind: WarningType, message: str, element: Any, target: str = "", needle: str = "<"
    ) -> None:
        """Report a warning; repeats of one type about one target are counted.

        The first :data:`_REPEATS_LISTED` warnings of one type about one
        target are listed, the last of them counts the rest; at most
        ``limits.max_warnings`` are kept per block (those over it are
        counted in :meth:`final_warnings`). So one block cannot flood its
        listeners, nor cost a column lookup per attribute.
        """
        key = (kind, target)
        seen = self._warned.get(key)
        if seen is not None and seen[1] >= _REPEATS_LISTED:
            seen[1] += 1
            return
        if len(self.warnings) >= self.limits.max_warnings:
            self._suppressed += 1
            return
        line = int(getattr(element, "sourceline", 0) or 0)
        if seen is None:
            self._warned[key] = [len(self.warnings), 1]
        else:
            seen[0] = len(self.warnings)
            seen[1] += 1
        self.warnings.append(
            BmlWarning(
                kind,
                message,
                id=f"{self.block_id}:{target}" if target else self.block_id,
                line=line,
                column=self.column(line, needle),
            )
        )

    def final_warnings(self) -> tuple[BmlWarning, ...]:
        """The warnings with their repeat counts, and a count of those over the limit."""
        warnings = list(self.warnings)
        for index, count in self._warned.values():
            if count > _REPEATS_LISTED:
                first = warnings[index]
                more = count - _REPEATS_LISTED
                warnings[index] = BmlWarning(
                    first.type,
                    f"{first.message} (and {more} more like it)",
                    first.id,
                    first.line,
                    first.column,
                )
        if self._suppressed:
            warnings.append(
                BmlWarning(
                    WarningType.PARSING_FAILURE,
                    f"{self._suppressed} more warnings about block {self.block_id!r} are not "
                    f"listed (limit of {self.limits.max_warnings} warnings per block)",
                    id=self.block_id,
                )
            )
        return tuple(warnings)

    def sync_ref(self, raw: str, element: Any, attribute: str, aliases: Any = ()) -> SyncRef:
        try:
            return parse_sync_ref(raw, sync_aliases=aliases)
        except SyncRefError as exc:
            raise self.error(SyncRefError, exc.message, element, f'{attribute}="') from None

    # -- the XML layer -----------------------------------------------------

    def common(
        self,
        el: Any,
        parent_nsmap: dict[str | None, str],
        attributes: tuple[tuple[str, str], ...] | None = None,
    ) -> tuple[list[Any], dict[str | None, str]]:
        """The lossless fields every element keeps, in :class:`XmlElement`'s
        order (``children``, index 3, is filled by the caller), and the
        namespaces in scope inside it. ``attributes``: the element's, when
        the caller has listed them already (after :meth:`check_attributes`)."""
        if attributes is None:
            if self.count_attributes:
                self.check_attributes(el)
            attributes = tuple(el.items())
        if self.flat_namespaces and parent_nsmap:
            nsmap = parent_nsmap
            decls: tuple[tuple[str | None, str], ...] = ()
        else:
            nsmap = el.nsmap
            decls = (
                tuple([(p, uri) for p, uri in nsmap.items() if parent_nsmap.get(p) != uri])
                if parent_nsmap
                else tuple(nsmap.items())
            )
        return [
            el.tag,
            attributes,
            el.text or "",
            (),
            el.tail or "",
            el.prefix,
            decls,
            el.sourceline or 0,
        ], nsmap

    def check_attributes(self, el: Any) -> None:
        """Refuse an element with more than ``limits.max_attributes`` attributes.

        Counted before they are listed: lxml lists an element's attributes
        (``items()``) in time quadratic in their number.
        """
        count = len(el.attrib)
        if count > self.limits.max_attributes:
            raise self.error(
                BmlSecurityError,
                f"<{_split_tag(el.tag)[1]}> has {count} attributes; the limit is "
                f"{self.limits.max_attributes} per element",
                el,
            )

    def other(self, node: Any, nsmap: dict[str | None, str], depth: int) -> Node:
        """Any node kept as written: comments, PIs and elements the grammar does not name."""
        if node.tag.__class__ is not str:
            if isinstance(node, etree._Comment):
                return _new_comment(node.text or "", node.tail or "")
            if isinstance(node, etree._ProcessingInstruction):
                return _new_pi(str(node.target), node.text or "", node.tail or "")
            raise self.error(BmlSecurityError, "entity references are not allowed in BML", node)
        if depth > self.limits.max_depth:
            raise self.error(
                BmlSecurityError, f"elements nested deeper than {self.limits.max_depth}", node
            )
        fields, inner = self.common(node, nsmap)
        if len(node):
            fields[3] = tuple([self.other(child, inner, depth + 1) for child in node])
        return _new_element(*fields)

    # -- the grammar ---------------------------------------------------------

    def block(self, root: Any) -> Block:
        namespace, local = _split_tag(root.tag)
        if (
            local != "bml"
            or namespace not in DIALECTS
            or (DIALECTS[namespace] not in ("bml", "draft"))
        ):
            raise self.error(
                BmlSyntaxError,
                f"the root element must be <bml> in the BML 1.0 namespace {BML_NS}, "
                f"not {root.tag!r}",
                root,
            )
        dialect = DIALECTS[namespace]
        if self.count_attributes:
            self.check_attributes(root)
        attributes = tuple(root.items())
        values = dict(attributes)
        block_id = values.get("id")
        if not block_id or not block_id.strip():
            raise self.error(BmlSyntaxError, "<bml> has no id attribute", root)
        self.block_id = block_id
        self.block_lang = values.get(_XML_LANG)
        composition = values.get("composition", "MERGE")
        if composition != "MERGE" and composition.upper() not in COMPOSITIONS:
            raise self.error(
                BmlSyntaxError,
                f"composition {composition!r} is not one of {', '.join(COMPOSITIONS)}",
                root,
                'composition="',
            )
        fields, nsmap = self.common(root, {}, attributes)
        # Every namespace declaration needs the literal "xmlns" in the source
        # (entities are refused), so when all of them sit on the root, no
        # element below declares any and nsmap need not be asked again.
        self.flat_namespaces = self.data.count(b"xmlns") == len(nsmap)
        behaviours: list[Behaviour] = []
        constraints: list[Constraint] = []
        block_child = self.block_child
        fields[3] = tuple(
            [block_child(child, nsmap, False, behaviours, constraints) for child in root]
        )
        prolog: tuple[Node, ...] = ()
        if root.getprevious() is not None:
            preceding: list[Any] = list(root.itersiblings(preceding=True))
            preceding.reverse()
            prolog = tuple([self.other(sibling, {}, 0) for sibling in preceding])
        epilog: tuple[Node, ...] = ()
        if root.getnext() is not None:
            epilog = tuple([self.other(sibling, {}, 0) for sibling in root.itersiblings()])
        fields[4] = ""  # the tail
        return _new_block(
            *fields,
            block_id,  # id
            values.get("characterId"),  # character_id
            composition.upper(),
            dialect,
            tuple(behaviours),
            tuple(constraints),
            prolog,
            epilog,
            self.block_control(root, fields[1]),  # control
            "",  # source: set by parse_bml
        )

    def block_control(self, root: Any, attributes: tuple[tuple[str, str], ...]) -> BlockControl:
        """The BMLA attributes of ``<bml>`` (BlockControl); none: the shared empty one."""
        for name, _ in attributes:
            if name.startswith(_BMLA_PREFIX):
                break
        else:
            return NO_CONTROL

        def ids(name: str) -> tuple[str, ...]:
            raw = root.get(_BMLA_PREFIX + name, "")
            found = tuple(part.strip() for part in raw.split(",") if part.strip())
            if len(found) > self.limits.max_behaviours:
                raise self.error(BmlSecurityError, f"bmla:{name} names too many blocks", root)
            return found

        preplan = root.get(_BMLA_PREFIX + "preplan", "false").strip().lower()
        if preplan not in ("true", "false"):
            raise self.error(
                BmlSyntaxError, f"bmla:preplan={preplan!r} is not true or false", root, "preplan"
            )
        return BlockControl(
            interrupt=ids("interrupt"),
            on_start=ids("onStart"),
            append_after=ids("appendAfter"),
            chunk_after=ids("chunkAfter"),
            prepend_before=ids("prependBefore"),
            preplan=preplan == "true",
        )

    def block_child(
        self,
        el: Any,
        nsmap: dict[str | None, str],
        required: bool,
        behaviours: list[Behaviour],
        constraints: list[Constraint],
    ) -> Node:
        tag = el.tag
        if tag.__class__ is not str:
            return self.other(el, nsmap, 1)
        spec = _SPECS_BY_TAG.get(tag)
        if spec is not None:
            behaviour = self.behaviour(el, tag, nsmap, spec, required)
            if behaviour.__class__ is Behaviour:
                behaviours.append(behaviour)
            return behaviour
        namespace, _, local = tag[1:].partition("}") if tag[0] == "{" else ("", "", tag)
        dialect = DIALECTS.get(namespace)
        if dialect in ("bml", "draft") and local == "required":
            fields, inner = self.common(el, nsmap)
            fields[3] = tuple(
                [self.block_child(child, inner, True, behaviours, constraints) for child in el]
            )
            return _new_required(*fields)
        if dialect in ("bml", "draft") and local == "constraint":
            constraint = self.constraint(el, nsmap, required)
            constraints.append(constraint)
            return constraint
        if namespace == "" and self.vocab.spec(BML_NS, local) is not None:
            # The usual mistake: BML 1.0 written without its namespace.
            self.warn(
                WarningType.BEHAVIOR_TYPE_NOT_SUPPORTED,
                f"<{local}> is a BML 1.0 behaviour, but this document declares no namespace, "
                f"so it is read as the BML draft of 2008, which has no <{local}>; it is ignored. "
                f'To write BML 1.0, add xmlns="{BML_NS}" to <bml>',
                el,
                el.get("id", ""),
            )
            return self.other(el, nsmap, 1)
        if dialect in ("bml", "draft"):
            self.warn(
                WarningType.BEHAVIOR_TYPE_NOT_SUPPORTED,
                f"<{local}> is not a BML 1.0 behaviour; it is ignored",
                el,
                el.get("id", ""),
            )
        else:
            self.warn(
                WarningType.CUSTOM_BEHAVIOUR_NOT_SUPPORTED,
                f"custom behaviour {tag} is not supported; it is ignored",
                el,
                el.get("id", ""),
            )
        return self.other(el, nsmap, 1)

    def behaviour(
        self, el: Any, tag: str, nsmap: dict[str | None, str], spec: BehaviourSpec, required: bool
    ) -> Node:
        """One behaviour; an uncreatable one is kept as plain XML with a warning.

        The hot path of a parse: each attribute is looked at once, through
        the spec's table of what each name is (:func:`_attribute_kinds`).
        """
        behaviour_id = el.get("id")
        if not behaviour_id or not behaviour_id.strip():
            self.warn(
                WarningType.CANNOT_CREATE_BEHAVIOR,
                f"<{spec.element}> has no id attribute; it is ignored",
                el,
            )
            return self.other(el, nsmap, 1)
        ids = self.ids
        if behaviour_id in ids:
            raise self.error(
                BmlSyntaxError,
                f"id {behaviour_id!r} is used twice in block {self.block_id!r}",
                el,
                f'id="{behaviour_id}"',
            )
        ids.add(behaviour_id)
        if len(ids) > self.limits.max_behaviours:
            raise self.error(
                BmlSecurityError,
                f"more than {self.limits.max_behaviours} behaviours in one block",
                el,
            )

        aliases = spec.sync_aliases
        kinds = _ATTRIBUTE_KINDS[id(spec)]
        params: list[tuple[str, str]] = []
        sync_refs: list[tuple[str, SyncRef]] = []
        problem = ""
        if self.count_attributes:
            self.check_attributes(el)
        attributes = tuple(el.items())
        own_lang = False
        for item in attributes:
            name, value = item
            kind = kinds.get(name)
            if kind is None:
                if name == "id":
                    continue
                if name == _XML_LANG:
                    own_lang = True
                self.unknown_attribute(spec, name, value, behaviour_id, params, el)
            elif kind.__class__ is str:  # a sync attribute: its BML 1.0 sync name
                ref = fast_sync_ref(value) if not aliases else None
                if ref is None:
                    ref = self.sync_ref(value, el, name, aliases)
                sync_refs.append((kind, ref))
            else:
                if kind is True and not _number_within(value, self.limits.max_number):
                    problem = (
                        f"attribute {name}={value[:40]!r} of {behaviour_id!r} is not a number "
                        f"of magnitude at most {self.limits.max_number:g}"
                    )
                params.append(item)
        behaviour_type = spec.type
        if behaviour_type == "speech" and not own_lang:
            # BML 1.0: a speech's language is its own xml:lang, else the
            # nearest enclosing element's (the block's, or a <required>'s).
            if not required:
                if self.block_lang is not None:
                    params.append(("lang", self.block_lang))
            else:
                for ancestor in el.iterancestors():
                    lang = ancestor.get(_XML_LANG)
                    if lang is not None:
                        params.append(("lang", lang))
                        break
        for name in spec.required:
            for key, _ in params:
                if key == name:
                    break
            else:
                problem = f"<{spec.element}> {behaviour_id!r} lacks the attribute {name!r}"
                break
        if spec.dialect == "draft":
            behaviour_type, params, draft_problem = self.translate(spec, params, behaviour_id)
            problem = problem or draft_problem
        # a head's checks and extra strokes are all about its repetition
        repeated = behaviour_type == "head" and any(key == "repetition" for key, _ in params)
        if not problem and (
            repeated or (behaviour_type in _CHECKED_TYPES and behaviour_type != "head")
        ):
            problem = self.check_params(behaviour_type, params, behaviour_id, self.limits)

        if self.flat_namespaces:
            inner = nsmap
            decls: tuple[tuple[str | None, str], ...] = ()
        else:
            inner = el.nsmap
            decls = tuple(
                (prefix, uri) for prefix, uri in inner.items() if nsmap.get(prefix) != uri
            )
        descriptions: list[Description] = []
        speech: SpeechText | None = None
        children: tuple[Node, ...] = ()
        if len(el):
            listed: list[Node] = []
            for child in el:
                child_tag = child.tag
                if child_tag.__class__ is str and child_tag.rpartition("}")[0] in _CORE_PREFIXES:
                    local_child = child_tag.rpartition("}")[2]
                    if local_child == "description":
                        description = self.description(child, inner)
                        descriptions.append(description)
                        listed.append(description)
                        continue
                    if local_child == "text" and spec.type == "speech" and speech is None:
                        speech = self.speech_text(child, inner, behaviour_id, aliases)
                        listed.append(speech)
                        continue
                elif (
                    spec.type == "parameterValueChange"
                    and child_tag == _BMLA_PREFIX + "trajectory"
                    and "targetValue" not in dict(params)
                ):
                    problem = problem or self.trajectory(child, params, behaviour_id)
                listed.append(self.other(child, inner, 2))
            children = tuple(listed)
        if (
            spec.type == "parameterValueChange"
            and not problem
            and "targetValue" not in dict(params)
        ):
            problem = f"<bmla:parametervaluechange> {behaviour_id!r} has no <bmla:trajectory>"

        # the lossless fields of the element (as _new_element takes them)
        lossless = (
            tag,
            attributes,
            el.text or "",
            children,
            el.tail or "",
            el.prefix,
            decls,
            el.sourceline or 0,
        )
        if problem:
            self.warn(
                WarningType.CANNOT_CREATE_BEHAVIOR, problem + "; it is ignored", el, behaviour_id
            )
            return _new_element(*lossless)

        syncs = spec.syncs
        if speech is not None or repeated:
            syncs = self.sync_points(spec, params, speech)
        if len(sync_refs) > 1:
            times = 0
            for _, ref in sync_refs:
                if ref.behaviour is None:
                    times += 1
            if times > 1:
                self.check_absolute_order(syncs, sync_refs, el, behaviour_id)
        return _new_behaviour(
            *lossless,
            behaviour_id,  # id
            behaviour_type,  # type
            spec.dialect,  # dialect
            syncs,
            tuple(sync_refs),
            tuple(params),
            required,
            speech,
            tuple(descriptions),
        )

    def unknown_attribute(
        self,
        spec: BehaviourSpec,
        name: str,
        value: str,
        behaviour_id: str,
        params: list[tuple[str, str]],
        el: Any,
    ) -> None:
        """An attribute outside the spec's table: a speech's ``xml:lang``, or a warning."""
        if name == _XML_LANG and spec.type == "speech":
            params.append(("lang", value))
        elif name[0] == "{":
            self.warn(
                WarningType.CUSTOM_ATTRIBUTE_NOT_SUPPORTED,
                f"custom attribute {name} on {behaviour_id!r} is not supported; it is ignored",
                el,
                behaviour_id,
                needle=name.rpartition("}")[2],
            )
        else:
            self.warn(
                WarningType.CUSTOM_ATTRIBUTE_NOT_SUPPORTED,
                f"attribute {name!r} is not understood on <{spec.element}> {behaviour_id!r}; "
                "it is ignored",
                el,
                behaviour_id,
                needle=f"{name}=",
            )

    def trajectory(self, el: Any, params: list[tuple[str, str]], behaviour_id: str) -> str:
        """A BMLA ``<trajectory type initialValue? targetValue>`` into ``params``
        (``trajectory``, ``initialValue``, ``targetValue``); a problem or ``""``."""
        kind = el.get("type", "linear")
        if kind != "linear":
            return f"trajectory type {kind!r} of {behaviour_id!r} is not supported (linear is)"
        for name in ("initialValue", "targetValue"):
            value = el.get(name)
            if value is None:
                if name == "targetValue":
                    return f"the trajectory of {behaviour_id!r} has no targetValue"
                continue
            if not _number_within(value, self.limits.max_number):
                return f"{name}={value!r} in the trajectory of {behaviour_id!r} is not a number"
            params.append((name, value))
        params.append(("trajectory", kind))
        return ""

    @staticmethod
    def translate(
        spec: BehaviourSpec, params: list[tuple[str, str]], behaviour_id: str = ""
    ) -> tuple[str, list[tuple[str, str]], str]:
        """Map a draft behaviour onto the BML 1.0 type and attribute names.

        Returns (type, params under BML 1.0 names, problem or ""). The
        mapping tables are data (``[draft]`` of data/vocabulary.toml);
        docs/parser.md lists them. The raw attributes stay untouched on the
        node, so the document serialises back as the draft it was.
        """
        draft = vocabulary().draft
        values = dict(params)
        if spec.element == "face":
            if values.get("type", "").upper() == "FACS":
                kept = [(k, v) for k, v in params if k in ("au", "side", "amount")]
                return "faceFacs", kept, ""
            if "type" not in values:
                return spec.type, params, f"<face> {behaviour_id!r} needs type (a lexeme or FACS)"
            kept = [(k, v) for k, v in params if k != "type"]
            return "faceLexeme", [("lexeme", values["type"]), *kept], ""
        renamed = [(draft.attributes.get(k, k), v) for k, v in params]
        if spec.element == "head":
            action = values.get("action", "").upper()
            lexeme = values.get("lexeme") or values.get("type")
            if action == "ROTATION" and "rotation" in values:
                lexeme = values["rotation"].upper()
            elif action and action != "ROTATION":
                return (
                    spec.type,
                    renamed,
                    (
                        f"<head> {behaviour_id!r}: action={values['action']!r} is not supported "
                        "(the draft's ROTATION with rotation NOD, SHAKE or TILT is)"
                    ),
                )
            if lexeme is None:
                return (
                    spec.type,
                    renamed,
                    (f'<head> {behaviour_id!r} needs type, or action="ROTATION" with rotation'),
                )
            kept = [(k, v) for k, v in renamed if k not in ("lexeme", "type", "action", "rotation")]
            return "head", [("lexeme", lexeme), *kept], ""
        if spec.element == "gesture":
            kind = (values.get("type") or "").upper()
            mode = draft.hands.get((values.get("hand") or "").upper())
            kept = [(k, v) for k, v in renamed if k not in ("type", "hand", "lexeme", "target")]
            if mode is not None:
                kept.append(("mode", mode))
            if kind == "POINT":
                if "target" not in values:
                    return (
                        "pointing",
                        kept,
                        f'<gesture type="POINT"> {behaviour_id!r} needs a target',
                    )
                return "pointing", [("target", values["target"]), *kept], ""
            lexeme = values.get("lexeme") or values.get("type")
            if lexeme is None:
                return spec.type, kept, f"<gesture> {behaviour_id!r} needs a type"
            return "gesture", [("lexeme", lexeme), *kept], ""
        if spec.element == "gaze":
            out = []
            for key, value in renamed:
                if key == "modality":
                    influence = draft.modalities.get(value.upper())
                    if influence is None:
                        return (
                            spec.type,
                            renamed,
                            (
                                f"<gaze> {behaviour_id!r}: modality={value!r} is not one of "
                                f"{', '.join(draft.modalities)}"
                            ),
                        )
                    out.append(("influence", influence))
                elif key != "type":
                    out.append((key, value))
            return "gaze", out, ""
        return spec.type, renamed, ""

    @staticmethod
    def check_params(
        behaviour_type: str, params: list[tuple[str, str]], behaviour_id: str, limits: Limits
    ) -> str:
        """Checks of our extension behaviours; returns a problem or ``""``."""
        values = dict(params)
        if behaviour_type == "fap":
            pairs = values["values"].replace(",", " ").split()
            if not pairs:
                return f"fap behaviour {behaviour_id!r} has no values"
            for pair in pairs:
                if not _fap_pair_ok(pair, limits.max_number):
                    return (
                        f"fap behaviour {behaviour_id!r}: {pair[:40]!r} is not FAP=value "
                        "with a FAP number from 1 to 68 and a value of magnitude at most "
                        f"{limits.max_number:g}"
                    )
        elif behaviour_type == "emotion":
            if "word" not in values and not ("angle" in values and "activation" in values):
                return (
                    f"emotion behaviour {behaviour_id!r} needs a word, or an angle and an "
                    "activation"
                )
        elif behaviour_type == "head" and "repetition" in values:
            repetition = float(values["repetition"])  # a number within max_number
            if repetition < 1 or repetition != int(repetition):
                return f"head {behaviour_id!r}: repetition must be a whole number of at least 1"
            if repetition > limits.max_repetition:
                return (
                    f"head {behaviour_id!r}: repetition {repetition:g} is over the limit of "
                    f"{limits.max_repetition}"
                )
        return ""

    @staticmethod
    def sync_points(
        spec: BehaviourSpec, params: list[tuple[str, str]], speech: SpeechText | None
    ) -> tuple[str, ...]:
        syncs = spec.syncs
        if spec.type == "head":
            repetition = int(float(dict(params).get("repetition", "1")))
            if repetition > 1:
                index = syncs.index("stroke") + 1
                extra = tuple(f"stroke:{n}" for n in range(2, repetition + 1))
                syncs = syncs[:index] + extra + syncs[index:]
        if speech is not None:
            markers = [run.id for run in speech.runs if run.__class__ is TextSync]
            syncs = (syncs[0], *markers, *syncs[1:])
        return syncs

    def check_absolute_order(
        self,
        syncs: tuple[str, ...],
        sync_refs: list[tuple[str, SyncRef]],
        el: Any,
        behaviour_id: str,
    ) -> None:
        """BML 1.0: a behaviour whose own absolute times contradict its sync order is dropped."""
        timed = sorted(
            (syncs.index(name), ref.offset, name) for name, ref in sync_refs if ref.is_time
        )
        for (_, earlier, first), (_, later, second) in itertools.pairwise(timed):
            if later < earlier:
                self.dropped.add(behaviour_id)
                self.warn(
                    WarningType.IMPOSSIBLE_TO_SCHEDULE,
                    f"{behaviour_id!r} has {second}={later:g} before {first}={earlier:g}; "
                    "the behaviour is removed",
                    el,
                    behaviour_id,
                )
                return

    def description(self, el: Any, nsmap: dict[str | None, str]) -> Description:
        fields, inner = self.common(el, nsmap)
        fields[3] = tuple([self.other(child, inner, 3) for child in el])
        priority_text = el.get("priority", "0")
        try:
            if len(priority_text) > 12:  # int() of thousands of digits is slow
                raise ValueError(priority_text)
            priority = int(priority_text)
        except ValueError:
            raise self.error(
                BmlSyntaxError,
                f"description priority {priority_text[:40]!r} is not an integer of at most "
                "12 characters",
                el,
                'priority="',
            ) from None
        return _new_description(*fields, priority, el.get("type", ""))

    def speech_text(
        self, el: Any, nsmap: dict[str | None, str], behaviour_id: str, aliases: Any
    ) -> SpeechText:
        fields, inner = self.common(el, nsmap)
        children: list[Node] = []
        # runs of words between markers, joined once each (linear in the text)
        merged: list[str | TextSync] = []
        words: list[str] = [el.text or ""]
        seen: set[str] = set()
        for child in el:
            tag = child.tag
            if tag.__class__ is str and tag.rpartition("}")[2] == "sync":
                if self.count_attributes:
                    self.check_attributes(child)
                sync_attributes = tuple(child.items())
                sync_id = ref_text = None
                for key, value in sync_attributes:
                    if key == "id":
                        sync_id = value
                    elif key == "ref":
                        ref_text = value
                if not sync_id:
                    raise self.error(
                        BmlSyntaxError, f"<sync> in the text of {behaviour_id!r} has no id", child
                    )
                if sync_id in seen or sync_id in ("start", "end"):
                    raise self.error(
                        BmlSyntaxError,
                        f"sync id {sync_id!r} is used twice in speech {behaviour_id!r}",
                        child,
                        f'"{sync_id}"',
                    )
                seen.add(sync_id)
                if len(seen) > self.limits.max_sync_refs:
                    raise self.error(
                        BmlSecurityError,
                        f"speech {behaviour_id!r} has more than {self.limits.max_sync_refs} "
                        "<sync> markers",
                        child,
                    )
                ref = None
                if ref_text:
                    ref = fast_sync_ref(ref_text) if not aliases else None
                    if ref is None:
                        ref = self.sync_ref(ref_text, child, "ref", aliases)
                sync_fields, sync_inner = self.common(child, inner, sync_attributes)
                if len(child):
                    sync_fields[3] = tuple([self.other(c, sync_inner, 4) for c in child])
                marker = _new_text_sync(*sync_fields, sync_id, ref)
                children.append(marker)
                text = "".join(words)
                if text:
                    merged.append(text)
                merged.append(marker)
                words = []
            else:
                node = self.other(child, inner, 4)
                children.append(node)
                if node.__class__ is not Comment and node.__class__ is not ProcessingInstruction:
                    words.append("".join(child.itertext()))
            words.append(child.tail or "")
        text = "".join(words)
        if text:
            merged.append(text)
        fields[3] = tuple(children)
        spoken = 0
        for run in merged:
            if run.__class__ is str:
                spoken += len(run)
        if spoken > self.limits.max_speech_chars:
            raise self.error(
                BmlSecurityError,
                f"speech {behaviour_id!r} has {spoken} characters of text; the limit is "
                f"{self.limits.max_speech_chars}",
                el,
            )
        return _new_speech_text(*fields, tuple(merged))

    def constraint(self, el: Any, nsmap: dict[str | None, str], required: bool) -> Constraint:
        fields, inner = self.common(el, nsmap)
        children: list[Node] = []
        relations: list[Relation] = []
        for child in el:
            tag = child.tag
            if tag.__class__ is str:
                namespace, local = _split_tag(tag)
                is_relation = local in _RELATION_KINDS and DIALECTS.get(namespace) in (
                    "bml",
                    "draft",
                )
            else:
                is_relation = False
            if is_relation:
                relation = self.relation(child, inner, local)
                relations.append(relation)
                children.append(relation)
            else:
                children.append(self.other(child, inner, 2))
        fields[3] = tuple(children)
        return _new_constraint(*fields, el.get("id", ""), required, tuple(relations))

    def relation(self, el: Any, nsmap: dict[str | None, str], kind: str) -> Relation:
        fields, inner = self.common(el, nsmap)
        ref_text = el.get("ref")
        if kind != "synchronize" and ref_text is None:
            raise self.error(BmlSyntaxError, f"<{kind}> needs a ref attribute", el)
        ref = self.sync_ref(ref_text, el, "ref") if ref_text is not None else None
        children: list[Node] = []
        syncs: list[SyncRef] = []
        for child in el:
            tag = child.tag
            if tag.__class__ is str and tag.rpartition("}")[2] == "sync":
                sync_text = child.get("ref")
                if sync_text is None:
                    raise self.error(BmlSyntaxError, f"<sync> in <{kind}> needs a ref", child)
                if len(syncs) >= self.limits.max_sync_refs:
                    raise self.error(
                        BmlSecurityError,
                        f"<{kind}> has more than {self.limits.max_sync_refs} sync references",
                        child,
                    )
                syncs.append(self.sync_ref(sync_text, child, "ref"))
            children.append(self.other(child, inner, 3))
        fields[3] = tuple(children)
        if len(syncs) + (ref is not None) < 2 and kind == "synchronize":
            self.warn(
                WarningType.PARSING_FAILURE,
                "<synchronize> with fewer than two sync points constrains nothing",
                el,
            )
        return _new_relation(*fields, kind, ref, tuple(syncs))


_XML_SPACE: Final = b" \t\r\n"


def _has_doctype(raw: bytes) -> bool:
    """True when a DOCTYPE follows the BOM, whitespace, PIs and comments.

    A scanner, linear in the prolog's length: each step skips whitespace or
    jumps past the end of a PI or comment, and never looks back.
    """
    at = 3 if raw.startswith(b"\xef\xbb\xbf") else 0
    size = len(raw)
    while at < size:
        byte = raw[at : at + 1]
        if byte in (b" ", b"\t", b"\r", b"\n"):
            at += 1
            while at < size and raw[at] in _XML_SPACE:
                at += 1
        elif raw.startswith(b"<?", at):
            end = raw.find(b"?>", at + 2)
            if end < 0:
                return False
            at = end + 2
        elif raw.startswith(b"<!--", at):
            end = raw.find(b"-->", at + 4)
            if end < 0:
                return False
            at = end + 3
        else:
            return raw.startswith(b"<!DOCTYPE", at)
    return False


_DOCTYPE_MESSAGE: Final = (
    "DOCTYPE declarations are not allowed in BML (entity expansion and external DTDs are refused)"
)


# Positional constructors that set slots directly (nodes.builder): building
# the nodes is most of what parsing costs.
_new_element: Final = builder(XmlElement)
_new_behaviour: Final = builder(Behaviour)
_new_description: Final = builder(Description)
_new_text_sync: Final = builder(TextSync)
_new_speech_text: Final = builder(SpeechText)
_new_constraint: Final = builder(Constraint)
_new_relation: Final = builder(Relation)
_new_required: Final = builder(Required)
_new_block: Final = builder(Block, every_field=True)
_new_comment: Final = builder(Comment)
_new_pi: Final = builder(ProcessingInstruction)
_new_result: Final = builder(ParseResult)


def _split_tag(tag: str) -> tuple[str, str]:
    """``(namespace, local name)`` of a Clark name; ``""`` for no namespace."""
    if tag[0] == "{":
        namespace, _, local = tag[1:].partition("}")
        return namespace, local
    return "", tag


def _specs_by_tag() -> dict[str, BehaviourSpec]:
    """The behaviour specs by the Clark name of their element (``{ns}local``, or
    ``local`` for no namespace)."""
    return {
        (f"{{{namespace}}}{element}" if namespace else element): spec
        for (namespace, element), spec in vocabulary().specs.items()
    }


_SPECS_BY_TAG: Final = _specs_by_tag()


def _attribute_kinds(spec: BehaviourSpec) -> dict[str, str | bool]:
    """What each attribute name of a behaviour is: a sync attribute (its BML
    1.0 sync name), a numeric parameter (True) or another understood one
    (False); any other name is not in the table."""
    kinds: dict[str, str | bool] = {name: name in spec.numeric for name in spec.attributes}
    kinds.update(spec.sync_attributes)  # a sync attribute is read as one first
    return kinds


# by the spec's identity (the vocabulary is loaded once; a spec holds a dict
# and is not hashable)
_ATTRIBUTE_KINDS: Final = {id(spec): _attribute_kinds(spec) for spec in _SPECS_BY_TAG.values()}


_NOTHING_DROPPED: Final[frozenset[str]] = frozenset()
_UTF8_NAMES = frozenset({"UTF-8", "UTF8", "US-ASCII", "ASCII"})


def _source_text(data: str | bytes, raw: bytes, encoding: str | None) -> str:
    """The document as text without its XML declaration, for ``Block.source``;
    ``""`` for bytes in an encoding other than UTF-8 (those are written from
    the tree). Linear: one decode and one search for the declaration's end."""
    if isinstance(data, str):
        text = data
    else:
        if (encoding or "UTF-8").upper() not in _UTF8_NAMES:
            return ""
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            return ""
    if text.startswith("\ufeff"):
        text = text[1:]
    # the declaration, not a processing instruction such as <?xml-stylesheet?>
    if text.startswith("<?xml") and text[5:6] in (" ", "\t", "\r", "\n"):
        end = text.find("?>", 5)
        if end < 0:
            return ""
        text = text[end + 2 :].lstrip(" \t\r\n")
    return text


def _to_bytes(data: str | bytes) -> tuple[bytes, etree.XMLParser]:
    if isinstance(data, str):
        return data.encode("utf-8"), _TEXT_PARSER
    return data, _BYTES_PARSER


def parse_bml(
    data: str | bytes, *, source: str = "<bml>", limits: Limits = DEFAULT_LIMITS
) -> ParseResult:
    """Parse one BML block.

    Returns the immutable block with the warnings for parts the realizer
    will not run. Raises :class:`~realizer.bml_parser.errors.BmlError` (with
    line, column and a BML 1.0 warning type) when the whole block must be
    rejected: not well-formed, not a ``<bml>`` root, a malformed sync
    reference, a DTD or entity, or a limit exceeded.
    """
    raw, parser = _to_bytes(data)
    if len(raw) > limits.max_bytes:
        raise BmlSecurityError(
            f"document of {len(raw)} bytes exceeds the limit of {limits.max_bytes} bytes",
            line=1,
            column=1,
            source=source,
        )
    # A DOCTYPE is written "<!DOCTYPE" (XML names are case-sensitive, and
    # no entity can make one): without those bytes there is none to find.
    doctype = b"<!DOCTYPE" in raw
    if doctype and _has_doctype(raw):
        # Refuse before libxml2 even reads the internal subset.
        raise BmlSecurityError(_DOCTYPE_MESSAGE, line=1, column=1, source=source)
    try:
        root = etree.fromstring(raw, parser)
    except etree.XMLSyntaxError as exc:
        line, column = exc.position if exc.position else (exc.lineno or 0, 0)
        message = re.sub(r", line \d+, column \d+$", "", exc.msg or "not well-formed XML")
        raise BmlSyntaxError(message, line=line, column=column, source=source) from None
    if root is None:
        raise BmlSyntaxError("empty document", line=1, column=1, source=source)
    encoding: str | None = "UTF-8"
    if doctype or not raw.startswith(b"<") or raw.startswith(b"<?xml") or raw[1:2] == b"\0":
        # a declaration, a byte order mark or UTF-16 without one: ask libxml2
        docinfo: Any = root.getroottree().docinfo
        if docinfo.doctype or docinfo.internalDTD is not None:
            raise BmlSecurityError(_DOCTYPE_MESSAGE, line=1, column=1, source=source)
        encoding = docinfo.encoding
    reader = _Reader(raw, source, limits)
    # Building the tree allocates many small objects and no cycles; pausing
    # the cyclic garbage collector meanwhile (as JSON decoders do) saves a
    # third of the time on large blocks. It is restored on every exit, after
    # the result is built: the first allocation once it runs again starts a
    # pass over every object made meanwhile, which is the caller's to pay
    # while it keeps the tree (nothing, for a tree it drops).
    collecting = gc.isenabled()
    gc.disable()
    try:
        block = reader.block(root)
        text = _source_text(data, raw, encoding)
        if text:
            object.__setattr__(block, "source", text)  # see Block.source
        dropped = frozenset(reader.dropped) if reader.dropped else _NOTHING_DROPPED
        return _new_result(block, reader.final_warnings(), dropped)
    finally:
        if collecting:
            gc.enable()
