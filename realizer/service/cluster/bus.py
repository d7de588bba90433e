"""The NATS connection both cluster roles open, and the lease bucket.

The only module besides the worker and the gateway that imports the NATS
client (nats-py, the ``cluster`` extra).
"""

from __future__ import annotations

import os
import socket
import uuid
from dataclasses import dataclass, field
from typing import Any

import nats
from nats.aio.client import Client
from nats.js.api import KeyValueConfig, StorageType
from nats.js.kv import KeyValue

from realizer.service.cluster.protocol import LEASE_BUCKET

#: This machine's name (in lease values: a gateway on the same machine may
#: compare the owner's monotonic clock with its own).
HOST = socket.gethostname()[:200]


def default_node_id(role: str) -> str:
    """``role-host-pid-xxxx``: unique per process, readable in logs."""
    host = HOST.split(".")[0][:40] or "host"
    return f"{role}-{host}-{os.getpid()}-{uuid.uuid4().hex[:4]}"


@dataclass(frozen=True, slots=True)
class ClusterConfig:
    """How a worker or gateway joins the cluster (all times in seconds).

    ``lease_ttl``: how long an owner's lease lives without renewal (the
    takeover time after a worker dies is between 0.75 and 1.1 times it);
    ``drain_timeout``: how long a worker leaving on SIGTERM lets running
    blocks finish before it interrupts them; ``owner_wait``: how long a
    gateway waits for a character to get an owner before it refuses the
    request; ``request_timeout``: one request to an owner;
    ``want_interval``: how often a gateway repeats its viewers' formats.
    """

    nats_url: str
    node_id: str = ""
    lease_ttl: float = 2.0
    drain_timeout: float = 10.0
    owner_wait: float = 15.0
    request_timeout: float = 2.0
    want_interval: float = 1.0
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("lease_ttl", "drain_timeout", "owner_wait", "request_timeout"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive")


async def connect(config: ClusterConfig, name: str) -> Client:
    """A NATS connection that keeps reconnecting (a restarted server is
    found again), with a short wait between attempts."""
    return await nats.connect(
        config.nats_url,
        name=name,
        allow_reconnect=True,
        max_reconnect_attempts=-1,
        reconnect_time_wait=0.2,
        connect_timeout=5,
        ping_interval=5,
        max_outstanding_pings=2,
    )


async def lease_bucket(client: Client) -> KeyValue:
    """The lease bucket, made if absent: one value per key (history 1), in
    memory (a lease is worth nothing after the NATS server restarts: every
    live owner writes its leases again within ``lease_ttl / 4``)."""
    js = client.jetstream()
    return await js.create_key_value(
        KeyValueConfig(bucket=LEASE_BUCKET, history=1, storage=StorageType.MEMORY)
    )
