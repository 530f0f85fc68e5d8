"""``python -m warpratchet``: the same as the ``warpratchet`` command."""

import sys

from .cli import main

sys.exit(main())
