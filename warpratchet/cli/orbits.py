"""``warpratchet orbits``: every periodic orbit of exact period M with its residue, and the families.

For the torus map at ``(K, b1, b2)`` (:mod:`warpratchet.orbits`, docs/orbits.md): each cycle once,
with its points, winding ``w``, ``nu = w/m`` (Eq. AIn), Greene's residue ``R = (2 - tr DM^m)/4``
and kind; where ``det(DM^m - I) = 0``, the families (polygons or segments of periodic points).
The exact enumeration grows about 3.3x per period: a period whose
enumeration is estimated to take more than a minute is refused with the estimate unless
``--long`` is given.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from .common import UsageError, count_type, emit_json, spec_flags

#: Periods up to this one always run (their cost: benchmarks/README.md, orbits.py).
ALWAYS = 8
#: Periods probed to extrapolate the cost of a longer one.
PROBES = (5, 6, 7)
#: Estimated seconds above which ``--long`` is required.
LONG_SECONDS = 60.0


def add(sub) -> None:
    p = sub.add_parser(
        "orbits", help="every periodic orbit of exact period M with its residue and kind, and the families"
    )
    spec_flags(p, ("K", "b1", "b2", "knots", "values"))
    p.add_argument("--period", type=count_type("period", 1), required=True, help="exact period m (>= 1)")
    p.add_argument(
        "--long",
        action="store_true",
        help=f"run a period whose enumeration is estimated to take over {LONG_SECONDS:.0f} s",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def extrapolate_nodes(nodes: Sequence[int], period: int) -> tuple[float, float]:
    """``(tree nodes, growth per period at period)`` of the search, from the node counts of the
    consecutive periods :data:`PROBES`.

    The growth per period itself rises with m (3.01, 3.14, 3.25, 3.35 from m = 5 to 9 at K = 3,
    b1 = 0.1, b2 = 0.01), so it is extrapolated linearly from the probes' last two ratios (never
    below 1). From periods 5-7 this gives the exact counts of periods 8 and 9 at both points of
    docs/orbits.md within 2%, where a constant growth is ~10% low by period 9.
    """
    ratios = [b / max(a, 1) for a, b in zip(nodes, nodes[1:], strict=False)]
    step = ratios[-1] - ratios[-2]
    count, growth = float(nodes[-1]), ratios[-1]
    for k in range(1, period - PROBES[-1] + 1):
        growth = max(1.0, ratios[-1] + k * step)
        count *= growth
    return count, growth


def estimate_seconds(params, period: int) -> tuple[float, float]:
    """``(seconds, growth per period)``: the cost of ``period`` extrapolated from :data:`PROBES`.

    Nodes by :func:`extrapolate_nodes`; a node costs more the longer the period, about in
    proportion to m (its exact integers grow with the steps), so the last probe's seconds per node
    are scaled by ``period / PROBES[-1]`` (why both corrections: benchmarks/README.md, orbits.py).
    """
    from ..orbits import enumerate_orbits

    probes = [enumerate_orbits(params, m) for m in PROBES]
    nodes, growth = extrapolate_nodes([probe.nodes for probe in probes], period)
    per_node = probes[-1].seconds / max(probes[-1].nodes, 1) * period / PROBES[-1]
    return per_node * nodes, growth


def command(args: argparse.Namespace) -> int:
    from ..orbits import format_orbits, orbits_report
    from ..spec import params_of

    params = params_of(args.K, args.b1, args.b2, args.knots, args.values)
    if args.period > ALWAYS and not args.long:
        seconds, growth = estimate_seconds(params, args.period)
        if seconds > LONG_SECONDS:
            if seconds < 300:
                minutes = f"{seconds:.0f} s"
            else:
                minutes = f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"
            raise UsageError(
                f"period {args.period} would take about {minutes} (x{growth:.1f} per period, extrapolated "
                f"from periods {PROBES[0]}-{PROBES[-1]}); pass --long to run it"
            )
    report = orbits_report(params, args.period)
    if args.json:
        emit_json(report)
    else:
        print(format_orbits(report))
    return 0
