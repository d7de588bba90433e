"""The real-time service: BML in, feedback and frames out.

* :mod:`~realizer.service.stage`: the sans-I/O core (characters, sessions,
  limits, routing, frame encoding); no sockets, no clock;
* :mod:`~realizer.service.server`: the thin asyncio/websockets layer (the
  endpoints, plain HTTP, the frame clock, viewer mailboxes, shutdown);
* :mod:`~realizer.service.messages` and :mod:`~realizer.service.codec`: the
  wire messages (``protocols/``);
* :mod:`~realizer.service.limits`, :mod:`~realizer.service.errors`;
* :mod:`~realizer.service.client`: a blocking Python client;
* :mod:`~realizer.service.offline`: the same stage driven frame by frame
  for ``realizer render``.

Only this package imports asyncio and websockets (the core is sans-I/O,
see docs/architecture.md), and only :mod:`~realizer.service.server` and
:mod:`~realizer.service.client` do within it.
"""
