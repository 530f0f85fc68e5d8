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
            print(f"{key:>7} = {'n/a' + _why_absent(summary) if value is None else value}")
    return 0


def _why_absent(summary: dict) -> str:
    """Why a closed form is absent at these parameters, as printed after ``n/a``."""
    if summary["K"] != 3.0:
        k = summary["K"]
        return f" (the closed forms of Sec. IV hold at K = 3 only, not K = {k}; try warpratchet sumrule)"
    return " (domain none: no accelerator-mode island, and the paper gives no formula for S_C)"
