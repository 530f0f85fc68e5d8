"""``warpratchet theory``: the closed forms of the paper at (K, b1, b2), no simulation."""

from __future__ import annotations

import argparse

from .common import emit_json, spec_flags


def add(sub) -> None:
    p = sub.add_parser("theory", help="closed forms of the paper at (K, b1, b2)")
    spec_flags(p, ("K", "b1", "b2", "knots", "values"))
    p.add_argument("--json", action="store_true", help="print one JSON object")


def command(args: argparse.Namespace) -> int:
    from .. import theory
    from ..spec import params_of

    summary = theory.summary(params_of(args.K, args.b1, args.b2, args.knots, args.values))
    if args.json:
        emit_json(summary)
    else:
        for key, value in summary.items():
            print(f"{key:>7} = {'n/a' if value is None else value}")
    return 0
