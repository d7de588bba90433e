"""``python -m realizer``: the same as the ``realizer`` command."""

from __future__ import annotations

import sys

from realizer.cli import main

sys.exit(main())
