"""``warpratchet figures``: regenerate the paper's figures (PNG and PDF; needs the ``figures`` extra).

The installed twin of ``python -m warpratchet_viz figures`` (``python -m viz figures`` in a
checkout): the options and the work are :func:`warpratchet_viz.figures.main`'s, so ``warpratchet
figures --help`` lists them. Without matplotlib it exits 2 with one line naming the extra.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

PROG = "warpratchet figures"
HELP = "regenerate the paper's figures, PNG and PDF (pip install 'warpratchet[figures]')"


def add(sub) -> None:
    # Listed in `warpratchet --help`; its arguments never reach this parser (main passes them on).
    sub.add_parser("figures", help=HELP, add_help=False)


def _viz_figures():
    try:
        from warpratchet_viz import figures
    except ImportError:  # a source checkout run without installing: the folder is viz/
        from viz import figures
    return figures


def main(argv: Sequence[str]) -> int:
    """Run ``warpratchet_viz.figures.main(argv, prog="warpratchet figures")``; its exit status."""
    try:
        figures = _viz_figures()
    except ImportError as exc:
        print(f"{PROG}: error: the figures are not installed ({exc}); pip install 'warpratchet[figures]'",
              file=sys.stderr)  # fmt: skip
        return 2
    return figures.main(list(argv), prog=PROG)


def command(args: argparse.Namespace) -> int:  # pragma: no cover - main dispatches before parsing
    return main([])
