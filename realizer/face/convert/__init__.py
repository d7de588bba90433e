"""Converters from high-level face descriptions into MPEG-4 FAP values.

Each converter is driven by a plain text data file a user can edit
(``realizer/face/data/facs``, ``.../emotion``, ``.../visemes``):

- :mod:`.facs`: FACS Action Units -> FAPs (Paul 2010, chapter 5, figure 5.2).
- :mod:`.lexemes`: BML 1.0 ``faceLexeme`` lexemes -> AUs -> FAPs.
- :mod:`.emotion`: emotion words and emotion-wheel points -> FAP ranges
  (Raouzaiou et al. 2002, sections 4 and 6, Paul 2010, chapter 6, figure 6.5).
- :mod:`.visemes`: FAP 1 (visemes) and FAP 2 (expressions) expanded into
  low-level FAPs (Tekalp and Ostermann 2000, Tables 3 and 4).

Every converter returns FAP numbers 1..68 (Tekalp and Ostermann 2000, Table 7) with values in
FAPU-scaled units, as :mod:`realizer.face` expects.
"""

from __future__ import annotations

from realizer.face.convert.errors import ConversionError, DataFileError

__all__ = ["ConversionError", "DataFileError"]
