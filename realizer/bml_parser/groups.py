"""Constraint groups: which sync points a block makes coincide, and by how much.

Every sync attribute (``start="g1:end+1"``) and every ``<synchronize>`` says
that some sync points coincide up to offsets. Sync points tied together,
directly or through others, form one group (the reference parser
saiba/OpenBMLParser builds the same groups). A group lists members
``(point, offset)`` such that ``time(point) + offset`` is the same for all
members; a bare time ``t`` is the member ``(bml:start, t)``. Offsets are
normalised so that the first member, in document order, has offset 0.

``<before>`` and ``<after>`` give :class:`Ordering` values instead.

The scheduler builds its own problem from the tree; these groups are the
parser's account of the constraints, used by tests against the conformance
corpus's ``Constraints:`` headers and by ``realizer parse``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from realizer.bml_parser.syncref import SyncRef
from realizer.bml_parser.tree import Block

#: A sync point: (block or None for this block, behaviour, sync name).
Point = tuple[str | None, str, str]
BLOCK_START: Point = (None, "bml", "start")


@dataclass(frozen=True, slots=True)
class GroupMember:
    point: Point
    offset: float

    def __str__(self) -> str:
        block, behaviour, sync = self.point
        name = f"{block}:{behaviour}:{sync}" if block else f"{behaviour}:{sync}"
        return f"{name}{self.offset:+g}" if self.offset else name


@dataclass(frozen=True, slots=True)
class ConstraintGroup:
    """Sync points that coincide: ``time(m.point) + m.offset`` equal for all members.

    ``consistent`` is False when the ties within the group disagree (e.g.
    ``a = b + 1`` and ``a = b + 2``); ``required`` when any tie is inside
    ``<required>``.
    """

    members: tuple[GroupMember, ...]
    consistent: bool = True
    required: bool = False

    @property
    def points(self) -> frozenset[Point]:
        return frozenset(member.point for member in self.members)


@dataclass(frozen=True, slots=True)
class Ordering:
    """``time(earlier) + earlier_offset <= time(later) + later_offset``."""

    earlier: GroupMember
    later: GroupMember
    constraint_id: str
    required: bool


_TIME = "\x00time"


def _point_of(ref: SyncRef) -> tuple[Point, float]:
    """The sync point a reference names and its offset (times hang off bml:start)."""
    if ref.is_time:
        return BLOCK_START, ref.offset
    assert ref.behaviour is not None
    if ref.behaviour == "bml" and ref.block is None:
        return BLOCK_START, ref.offset
    return (ref.block, ref.behaviour, ref.sync_name), ref.offset


class _Ties:
    """Union-find with offsets: ``time(x) = time(parent) + delta``."""

    def __init__(self) -> None:
        self.parent: dict[Point, Point] = {}
        self.delta: dict[Point, float] = {}
        self.order: dict[Point, int] = {}
        self.bad: set[Point] = set()
        self.required: set[Point] = set()

    def add(self, point: Point) -> None:
        if point not in self.parent:
            self.parent[point] = point
            self.delta[point] = 0.0
            self.order[point] = len(self.order)

    def find(self, point: Point) -> tuple[Point, float]:
        path = []
        while self.parent[point] != point:
            path.append(point)
            point = self.parent[point]
        root = point
        total = 0.0
        for node in reversed(path):  # compress, accumulating offsets from the root
            total += self.delta[node]
            self.delta[node] = total
            self.parent[node] = root
        return root, 0.0

    def offset_to_root(self, point: Point) -> float:
        self.find(point)
        return self.delta[point] if self.parent[point] != point else 0.0

    def tie(self, a: Point, ka: float, b: Point, kb: float, required: bool) -> None:
        """time(a) + ka == time(b) + kb."""
        self.add(a)
        self.add(b)
        ra, _ = self.find(a)
        rb, _ = self.find(b)
        da, db = self.offset_to_root(a), self.offset_to_root(b)
        # time(a) = time(ra) + da; time(b) = time(rb) + db
        if ra == rb:
            if abs((da + ka) - (db + kb)) > 1e-9:
                self.bad.add(ra)
        else:
            # time(rb) = time(ra) + da + ka - kb - db
            self.parent[rb] = ra
            self.delta[rb] = da + ka - kb - db
            if rb in self.bad:
                self.bad.add(ra)
            if rb in self.required:
                self.required.add(ra)
        if required:
            self.required.add(self.find(a)[0])


def constraint_groups(block: Block) -> tuple[tuple[ConstraintGroup, ...], tuple[Ordering, ...]]:
    """The equality groups and the orderings a block states, in document order."""
    ties = _Ties()
    times = 0

    def point_of(ref: SyncRef) -> tuple[Point, float]:
        # Each bare time (and bml:start) is a point of its own, so that times
        # do not merge unrelated groups; it maps back to bml:start below.
        nonlocal times
        point, offset = _point_of(ref)
        if point == BLOCK_START:
            times += 1
            return (_TIME, "bml", str(times)), offset
        return point, offset

    orderings: list[Ordering] = []
    for behaviour in block.behaviours:
        for sync_name, ref in behaviour.sync_refs:
            target, offset = point_of(ref)
            ties.tie((None, behaviour.id, sync_name), 0.0, target, offset, behaviour.required)
        if behaviour.speech is not None:
            for run in behaviour.speech.runs:
                if not isinstance(run, str) and run.ref is not None:
                    target, offset = point_of(run.ref)
                    ties.tie((None, behaviour.id, run.id), 0.0, target, offset, behaviour.required)
    for constraint in block.constraints:
        for relation in constraint.relations:
            if relation.kind != "synchronize":
                refs = [_point_of(ref) for ref in relation.syncs]
            else:
                refs = [point_of(ref) for ref in relation.syncs]
            if relation.kind == "synchronize":
                if relation.ref is not None:
                    refs.insert(0, point_of(relation.ref))
                for (a, ka), (b, kb) in itertools.pairwise(refs):
                    ties.tie(a, ka, b, kb, constraint.required)
                continue
            assert relation.ref is not None
            anchor_point, anchor_offset = _point_of(relation.ref)
            anchor = GroupMember(anchor_point, anchor_offset)
            for point, offset in refs:
                member = GroupMember(point, offset)
                earlier, later = (anchor, member) if relation.kind == "after" else (member, anchor)
                orderings.append(Ordering(earlier, later, constraint.id, constraint.required))

    members: dict[Point, list[tuple[Point, float]]] = {}
    for point in sorted(ties.parent, key=ties.order.__getitem__):
        root, _ = ties.find(point)
        # time(point) = time(root) + d  =>  time(point) - d == time(root)
        members.setdefault(root, []).append((point, -ties.offset_to_root(point)))
    groups = []
    for root, listed in members.items():
        if len(listed) < 2:
            continue
        base = listed[0][1]
        group_members = tuple(
            GroupMember(BLOCK_START if point[0] == _TIME else point, offset - base)
            for point, offset in listed
        )
        # time(bml:start) is 0, so every time member pins the common value.
        pinned = {round(m.offset, 9) for m in group_members if m.point == BLOCK_START}
        groups.append(
            ConstraintGroup(
                group_members,
                consistent=root not in ties.bad and len(pinned) <= 1,
                required=root in ties.required,
            )
        )
    return tuple(groups), tuple(orderings)
