"""``python -m warpratchet.cli``: the ``warpratchet`` command."""

import sys

from . import main

sys.exit(main())
