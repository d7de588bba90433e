"""Who owns which character, as one process observes it (sans-I/O).

The lease protocol (protocols/cluster.md, "Leases"): a lease is a key of
the JetStream key-value bucket whose value names the owning worker. It is
taken with *create* (succeeds only where the key is absent or deleted) and
renewed by *compare-and-set* (an update that names the revision the writer
last saw). Every write makes a new revision.

Expiry is judged on the observer's own monotonic clock, never by comparing
clocks of two machines: a lease whose revision an observer has watched stay
the same for ``ttl`` seconds is expired *for that observer*, which may then
try to take it over by compare-and-set on that very revision. Only one
writer can win a compare-and-set on one revision, so two workers never both
take a character over; a slow owner that was taken over learns it at its
next renewal (its compare-and-set fails) and lets the character go. An
owner renews every ``ttl / 4`` seconds and stops acting as owner (publishes
no frames, accepts no BML) when it has not renewed for ``ttl / 2``, so even
a paused owner stops before anyone else may start.
"""

from __future__ import annotations

from dataclasses import dataclass

from realizer.service.cluster.protocol import ClusterMessageError, LeaseValue


@dataclass(frozen=True, slots=True)
class ObservedLease:
    """A lease as last seen: ``revision`` in the bucket, ``seen`` the
    observer's monotonic time (seconds) when that revision arrived."""

    character: str
    revision: int
    value: LeaseValue
    seen: float


class LeaseTable:
    """The leases one process has watched, with the expiry rule above."""

    def __init__(self, ttl: float) -> None:
        if ttl <= 0:
            raise ValueError(f"lease ttl must be positive, not {ttl}")
        self.ttl = ttl
        self.leases: dict[str, ObservedLease] = {}

    def observe(self, character: str, revision: int, data: bytes | None, now: float) -> None:
        """A watched update: ``data`` the lease value, None for a deletion.

        An unreadable value (another version, a stray writer) counts as a
        lease of nobody: it expires like any other and can then be taken.
        """
        if data is None:
            self.leases.pop(character, None)
            return
        known = self.leases.get(character)
        if known is not None and known.revision >= revision:
            return  # an old update delivered late
        try:
            value = LeaseValue.unpack(data)
        except ClusterMessageError:
            value = LeaseValue(owner="")
        self.leases[character] = ObservedLease(character, revision, value, now)

    def owner(self, character: str) -> str | None:
        lease = self.leases.get(character)
        return lease.value.owner if lease is not None else None

    def expired(self, now: float) -> list[ObservedLease]:
        """Leases not renewed for ``ttl`` seconds as this observer saw them."""
        return [lease for lease in self.leases.values() if now - lease.seen > self.ttl]

    def owners(self) -> set[str]:
        return {lease.value.owner for lease in self.leases.values() if lease.value.owner}
