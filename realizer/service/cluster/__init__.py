"""Beyond one machine: realizer workers and stateless gateways over NATS.

``realizer serve`` stays the one-process default. For many characters or
many viewers, ``realizer worker --nats URL`` runs characters (the same
sans-I/O :class:`~realizer.service.stage.Stage` and sessions, and the same
clock as ``realizer serve``) and ``realizer gateway --nats URL`` serves the
same endpoints as ``realizer serve`` without holding any character
(docs/architecture.md). NATS does the distribution: core NATS for
requests, feedback and frames (at most once: the next frame supersedes a
lost one), a JetStream key-value bucket for the leases that give each
character one owner.

* :mod:`~realizer.service.cluster.protocol`: subjects and message layouts
  (protocols/cluster.md), sans-I/O;
* :mod:`~realizer.service.cluster.leases`: the lease table and its expiry
  rule, sans-I/O;
* :mod:`~realizer.service.cluster.bus`: the NATS connection and bucket;
* :mod:`~realizer.service.cluster.worker`, :mod:`~realizer.service.cluster.gateway`:
  the two roles, subclasses of :class:`~realizer.service.server.RealizerService`.

The NATS client (nats-py, the ``cluster`` extra) is imported only by
``bus``, ``worker`` and ``gateway``; importing this package does not need it.
"""
