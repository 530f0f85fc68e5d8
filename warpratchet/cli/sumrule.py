"""``warpratchet sumrule``: island census of the torus and the sum rule, Eq. (sum), for any K.

Samples the torus (``--points``) or a lattice (``--grid``), so the run's defaults differ from
``run``'s: 10^5 points, 30000 steps (at least ``8 m_max^3``), the threshold of the chosen
indicator (``--indicator``).
"""

from __future__ import annotations

import argparse
import math

from ..params import map_text
from .common import ProgressBar, count_type, emit_json, spec_flag, spec_flags

DEFAULT_POINTS = 100_000


def add(sub) -> None:
    p = sub.add_parser("sumrule", help="island census of the torus and the sum rule, Eq. (sum), for any K")
    spec_flags(p, ("K", "b1", "b2", "knots", "values"))
    where = p.add_mutually_exclusive_group()
    spec_flag(
        where, "points", default=None, help=f"random points uniform on the torus (default {DEFAULT_POINTS})"
    )
    where.add_argument(
        "--grid",
        type=count_type("grid", 1),
        default=None,
        help="a G x G lattice off the kinks instead of random points",
    )
    spec_flag(p, "steps", default=30_000, help="iterations per point (default 30000; at least 8 m_max^3)")
    p.add_argument(
        "--m-max",
        type=count_type("m_max", 1),
        default=12,
        help="largest period m of an island's nu = w/m (default 12)",
    )
    spec_flags(
        p,
        ("indicator", "threshold", "seed", "threads", "device"),
        threshold={"help": "indicator value above which a point is chaotic (default: per indicator)"},
        seed={"help": "NumPy seed for --points (default 0)"},
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _print_census(result, out: dict) -> None:
    err = "+-" if result.error_kind == "stderr" else "bound"
    print(
        f"{map_text(vars(result))}: {result.points} points ({result.sampling}) "
        f"x {result.steps} steps, indicator {result.indicator}"
    )
    print(f"  {'nu':>8} {'w':>4} {'m':>3} {'area':>10}  {err:>9}  chaotic")
    print(f"  {'C':>8} {'':>4} {'':>3} {result.S_C:10.6f}  {result.S_C_stderr:9.2g}")
    for item in result.islands:
        print(
            f"  {item.nu:8.4f} {item.w:4d} {item.m:3d} {item.area:10.6f}  {item.area_stderr:9.2g}  "
            f"{item.chaotic_fraction:.3f}"
        )
    if result.unidentified_area:
        print(
            f"  {'?':>8} {'':>4} {'':>3} {result.unidentified_area:10.6f}  "
            f"{result.unidentified_area_stderr:9.2g}  (regular, no nu with m <= {result.m_max})"
        )
    print(
        f"  C: chaotic by {result.indicator} and locked to no nu; by {result.indicator} alone "
        f"(islands' chaotic points too) S_C = {result.S_C_indicator:.6f} {err} "
        f"{result.S_C_indicator_stderr:.2g}"
    )
    for key in ("A_sumrule", "A_direct", "A_force", "torus_mean_A"):
        spread = out.get(f"{key}_stderr")
        label = err if key == "A_sumrule" else "+-"  # means over points always carry a standard error
        value = "n/a (no points to average)" if out[key] is None else f"{out[key]:.6g}"
        print(f"  {key:<12} = {value}" + ("" if spread is None else f" {label} {spread:.2g}"))
    if result.theory is not None:
        t = result.theory
        print(
            "  theory (K = 3): "
            + ", ".join(
                f"{k} = {'n/a' if t[k] is None else f'{t[k]:.6g}'}" for k in ("S_C", "S_L", "S_R", "A")
            )
        )
    if result.C_check is not None:  # shares of the points, against C = B u MB u M^2 B
        shares = ", ".join(f"{key.replace('_', ' ')} {share:.2g}" for key, share in result.C_check.items())
        print(f"  vs Eq. (Cs), shares of the points: {shares}")
    print(f"  {result.seconds:.1f} s")


def command(args: argparse.Namespace) -> int:
    from ..spec import params_of
    from ..sumrule import census

    points = DEFAULT_POINTS if args.points is None and args.grid is None else args.points
    result = census(
        params_of(args.K, args.b1, args.b2, args.knots, args.values),
        args.steps,
        points=points,
        grid=args.grid,
        seed=args.seed,
        m_max=args.m_max,
        indicator=args.indicator,
        threshold=args.threshold,
        threads=args.threads,
        device=args.device,
        observers=[ProgressBar(disable=args.quiet)],
    )
    # NaN (a mean over no points) is null in JSON and "n/a" in text, never printed as a number.
    out = {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in result.as_dict().items()}
    if args.json:
        emit_json(out)
    else:
        _print_census(result, out)
    return 0
