"""The root of every exception the realizer raises on purpose.

::

    RealizerError
     ├── bml_parser.errors.BmlError          bad BML (carries line, column and a
     │    └── ...                             BML 1.0 warning type)
     ├── scheduler errors                     a block that cannot be scheduled
     └── face errors                          bad face files, FAP values, ...

Catch :class:`RealizerError` to handle everything the realizer reports about
its input; anything else escaping is a bug.
"""

from __future__ import annotations


class RealizerError(Exception):
    """Base class of all the realizer's own errors."""
