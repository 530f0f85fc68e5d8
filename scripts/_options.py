"""The options every validation script takes (``--quick``, sizes, ``--seed``, ``--json``); not a script.

A size option (``--points``, ``--steps``, ...) has a full and a quick default; left out (or 0),
it takes the one ``--quick`` selects, so ``args.points`` is always the size to run.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable


def options(
    doc: str,
    argv: list[str] | None,
    *,
    quick: str | None,
    seed: int,
    sizes: dict[str, tuple[str, int, int]],
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    """The parser and its parsed arguments: ``--quick`` (help ``quick``), what ``extra(parser)``
    adds, one integer option per entry ``flag: (what, full default, quick default)`` of
    ``sizes``, ``--seed`` (default ``seed``) and ``--json``."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help=quick)
    if extra is not None:
        extra(ap)
    for flag, (what, full, small) in sizes.items():
        ap.add_argument(flag, type=int, help=f"{what} (default {full}; quick {small})")
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--json", action="store_true", help="print every number as one JSON object on stdout")
    args = ap.parse_args(argv)
    for flag, (_, full, small) in sizes.items():
        name = flag.removeprefix("--").replace("-", "_")
        setattr(args, name, getattr(args, name) or (small if args.quick else full))
    return ap, args
