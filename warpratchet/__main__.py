"""``python -m warpratchet``: the same as the ``warpratchet`` command."""

import sys

from .cli import console_main

sys.exit(console_main())
