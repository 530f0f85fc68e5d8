"""``python -m viz.figures ...``: the same as ``python -m viz figures ...``."""

import sys

from .cli import main

sys.exit(main())
