"""``realizer parse FILE...``: read BML files and show what the parser built.

Prints each block's behaviours and sync references; ``--json`` prints the
tree as JSON; ``--roundtrip`` checks that serialising the parsed tree gives
back the document under C14N 2.0 (``OK path`` / ``DIFF path`` with the first
difference; exit 1 if any differs). Invalid input: ``path:line:col: error:
message`` on stderr and exit 2. ``--strict`` (for planners' CI) makes every
warning an error: ``path:line:col: error: TYPE: message`` and exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from realizer.commands import error_line, plain_text


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "parse",
        help="parse BML files and print their behaviours",
        description=plain_text(__doc__.split("\n\n")[1]) if __doc__ else None,
    )
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE")
    parser.add_argument(
        "--strict", action="store_true", help="every warning is an error (exit status 2)"
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--json", action="store_true", help="print the tree as JSON")
    mode.add_argument(
        "--roundtrip", action="store_true", help="check the C14N round trip of each file"
    )
    parser.set_defaults(run=run)


def unknown_references(block: Any) -> list[str]:
    """References to a behaviour or sync point the block does not have.

    What the parser alone can tell: references into other blocks need a
    session and are left to ``realizer schedule --strict``.
    """
    problems = []
    behaviours = {b.id: b for b in block.behaviours}
    for holder, ref in block.all_sync_refs():
        if ref.is_time or (ref.block is not None and ref.block != block.id):
            continue
        if ref.behaviour == "bml":
            if ref.sync != "start":
                problems.append(
                    f"{holder.id or 'a constraint'}: {ref.raw.strip()!r}: bml has only a start"
                )
            continue
        target = behaviours.get(ref.behaviour or "")
        name = "stroke" if ref.sync == "stroke" and ref.iteration == 1 else ref.sync_name
        if target is None:
            problems.append(
                f"{holder.id or 'a constraint'}: {ref.raw.strip()!r}: no behaviour "
                f"{ref.behaviour!r} in block {block.id!r}"
            )
        elif name not in target.syncs:
            problems.append(
                f"{holder.id or 'a constraint'}: {ref.raw.strip()!r}: {ref.behaviour!r} has no "
                f"sync point {name!r}"
            )
    return problems


def _first_difference(expected: str, actual: str) -> str:
    for index, (a, b) in enumerate(zip(expected, actual, strict=False)):
        if a != b:
            start = max(0, index - 30)
            return (
                f"at character {index}: expected {expected[start : index + 30]!r}, "
                f"got {actual[start : index + 30]!r}"
            )
    return f"lengths differ: expected {len(expected)} characters, got {len(actual)}"


def tree_json(node: Any) -> Any:
    """A JSON-able form of a BML tree node (typed fields first, then the XML)."""
    from realizer.bml_parser import Behaviour, Block, Constraint, SyncRef
    from realizer.bml_parser.nodes import Comment, ProcessingInstruction, XmlElement

    if isinstance(node, SyncRef):
        return {
            "raw": node.raw,
            "block": node.block,
            "behaviour": node.behaviour,
            "sync": node.sync,
            "iteration": node.iteration,
            "offset": node.offset,
        }
    if isinstance(node, Comment):
        return {"comment": node.text}
    if isinstance(node, ProcessingInstruction):
        return {"pi": node.target, "text": node.text}
    assert isinstance(node, XmlElement)
    out: dict[str, Any] = {"tag": node.tag, "line": node.line}
    if isinstance(node, Block):
        out.update(
            id=node.id,
            characterId=node.character_id,
            composition=node.composition,
            dialect=node.dialect,
            behaviours=[tree_json(b) for b in node.behaviours],
            constraints=[tree_json(c) for c in node.constraints],
        )
        return out
    if isinstance(node, Behaviour):
        out.update(
            id=node.id,
            type=node.type,
            dialect=node.dialect,
            required=node.required,
            syncs=list(node.syncs),
            syncRefs={name: tree_json(ref) for name, ref in node.sync_refs},
            params=dict(node.params),
        )
        if node.speech is not None:
            out["text"] = [
                run if isinstance(run, str) else {"sync": run.id} for run in node.speech.runs
            ]
        if node.descriptions:
            out["descriptions"] = [
                {"priority": d.priority, "type": d.type} for d in node.descriptions
            ]
        return out
    if isinstance(node, Constraint):
        out.update(
            id=node.id,
            required=node.required,
            relations=[
                {
                    "kind": r.kind,
                    "ref": tree_json(r.ref) if r.ref is not None else None,
                    "syncs": [tree_json(s) for s in r.syncs],
                }
                for r in node.relations
            ],
        )
        return out
    out["attributes"] = dict(node.attributes)
    return out


def _print_block(path: Path, result: Any) -> None:
    block = result.block
    composition = f" composition={block.composition}"
    character = f" characterId={block.character_id}" if block.character_id else ""
    print(f"{path}: block {block.id}{character}{composition} ({block.dialect})")
    for behaviour in block.behaviours:
        flags = " required" if behaviour.required else ""
        flags += " DROPPED" if behaviour.id in result.dropped else ""
        params = " ".join(f"{k}={v}" for k, v in behaviour.params)
        print(f"  {behaviour.type} {behaviour.id}{flags} {params}".rstrip())
        print(f"    syncs: {' '.join(behaviour.syncs)}")
        for name, ref in behaviour.sync_refs:
            print(f"    {name} = {ref.raw.strip()}")
    for constraint in block.constraints:
        label = constraint.id or "(no id)"
        flags = " required" if constraint.required else ""
        print(f"  constraint {label}{flags}")
        for relation in constraint.relations:
            ref = f" ref={relation.ref.raw.strip()}" if relation.ref else ""
            syncs = ", ".join(s.raw.strip() for s in relation.syncs)
            print(f"    {relation.kind}{ref}: {syncs}")
    for warning in result.warnings:
        print(f"{path}:{warning}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    from realizer.bml_parser import BmlError, canonical, parse_bml, serialise

    status = 0
    documents = []
    for path in args.files:
        try:
            data = path.read_bytes()
        except OSError as exc:
            print(error_line("parse", exc, path), file=sys.stderr)
            status = 2
            continue
        try:
            result = parse_bml(data, source=str(path))
        except BmlError as exc:
            print(str(exc), file=sys.stderr)
            status = 2
            continue
        if args.strict:
            problems = [
                f"{path}:{w.line}:{w.column}: error: {w.type}: {w.message}" for w in result.warnings
            ] + [
                f"{path}:0:0: error: NO_SUCH_TARGET: {p}" for p in unknown_references(result.block)
            ]
            if problems:
                print("\n".join(problems), file=sys.stderr)
                status = 2
                continue
        if args.roundtrip:
            expected = canonical(data)
            actual = canonical(serialise(result.block, from_source=False))
            if expected == actual:
                print(f"OK {path}")
            else:
                print(f"DIFF {path}: {_first_difference(expected, actual)}")
                status = max(status, 1)
        elif args.json:
            documents.append(
                {
                    "path": str(path),
                    "block": tree_json(result.block),
                    "warnings": [
                        {"type": str(w.type), "id": w.id, "message": w.message, "line": w.line}
                        for w in result.warnings
                    ],
                    "dropped": sorted(result.dropped),
                }
            )
        else:
            _print_block(path, result)
    if args.json:
        json.dump(documents, sys.stdout, indent=2)
        print()
    return status
