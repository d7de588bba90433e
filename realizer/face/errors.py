"""Errors of the face part: bad face files, bad FAP values, bad settings.

::

    RealizerError
     └── FaceError                 anything wrong with a face or its input
          ├── FaceFileError        a mesh or parameter file that cannot be read
          └── FapValueError        a FAP vector of the wrong shape, or a value a
                                   strict check rejects (e.g. a negative value
                                   of a unidirectional FAP)
"""

from __future__ import annotations

from realizer.errors import RealizerError


class FaceError(RealizerError):
    """Something is wrong with a face, its settings, or a FAP vector."""


class FaceFileError(FaceError):
    """A face mesh or face parameter file cannot be read or is inconsistent."""


class FapValueError(FaceError, ValueError):
    """A FAP vector or FAP value is malformed or out of its allowed range."""
