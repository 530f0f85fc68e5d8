"""``python -m warpratchet.cli``: the ``warpratchet`` command."""

import sys

from . import console_main

sys.exit(console_main())
