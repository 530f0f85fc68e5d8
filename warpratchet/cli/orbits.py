"""``warpratchet orbits``: every periodic orbit of exact period M with its residue, and the families.

For the torus map at ``(K, b1, b2)`` (:mod:`warpratchet.orbits`, docs/orbits.md): each cycle once,
with its points, winding ``w``, ``nu = w/m`` (Eq. AIn), Greene's residue ``R = (2 - tr DM^m)/4``
and kind; where ``det(DM^m - I) = 0``, the families (polygons or segments of periodic points).
The exact enumeration grows about 3.3x per period (period 9 takes ~40 s here): a period whose
enumeration is estimated to take more than a minute is refused with the estimate unless
``--long`` is given.
"""

from __future__ import annotations

import argparse

from .common import UsageError, count_type, emit_json, spec_flags

#: Periods up to this one always run (measured: under 15 s on the shared 2-core machine).
ALWAYS = 8
#: Periods probed to extrapolate the cost of a longer one.
PROBES = (5, 6)
#: Estimated seconds above which ``--long`` is required.
LONG_SECONDS = 60.0


def add(sub) -> None:
    p = sub.add_parser(
        "orbits", help="every periodic orbit of exact period M with its residue and kind, and the families"
    )
    spec_flags(p, ("K", "b1", "b2"))
    p.add_argument("--period", type=count_type("period", 1), required=True, help="exact period m (>= 1)")
    p.add_argument(
        "--long",
        action="store_true",
        help=f"run a period whose enumeration is estimated to take over {LONG_SECONDS:.0f} s",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def estimate_seconds(params, period: int) -> tuple[float, float]:
    """``(seconds, growth per period)``: the cost of ``period`` extrapolated from :data:`PROBES`.

    The search visits ``~ g^m`` tree nodes; ``g`` is the ratio of the probes' node counts, and
    the seconds per node the larger probe's.
    """
    from ..orbits import enumerate_orbits

    small, large = (enumerate_orbits(params, m) for m in PROBES)
    growth = (large.nodes / max(small.nodes, 1)) ** (1.0 / (PROBES[1] - PROBES[0]))
    per_node = large.seconds / max(large.nodes, 1)
    return per_node * large.nodes * growth ** (period - PROBES[1]), growth


def command(args: argparse.Namespace) -> int:
    from ..orbits import format_orbits, orbits_report
    from ..params import MapParams

    params = MapParams(args.K, args.b1, args.b2)
    if args.period > ALWAYS and not args.long:
        seconds, growth = estimate_seconds(params, args.period)
        if seconds > LONG_SECONDS:
            minutes = f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"
            raise UsageError(
                f"period {args.period} would take about {minutes} (x{growth:.1f} per period, extrapolated "
                f"from periods {PROBES[0]} and {PROBES[1]}); pass --long to run it"
            )
    report = orbits_report(params, args.period)
    if args.json:
        emit_json(report)
    else:
        print(format_orbits(report))
    return 0
