"""``warpratchet sweep``: one ensemble per parameter point; rows to an HDF5 sweep file.

Where the points are: ``--path`` (the paper's paths, :mod:`warpratchet.sweep`) or
``--grid``, with ranges ``START:STOP:COUNT`` that include both ends. What runs at each point:
the :class:`~warpratchet.spec.SweepSpec` flags (``--points --steps --seed --init
--threshold --threshold-rule``), plus ``--threads`` and ``--scheduler`` (where it runs, never what).
"""

from __future__ import annotations

import argparse
import math

from ..errors import ParameterError, check_count
from ..observables import MIN_CHAOTIC_POINTS
from ..spec import params_of
from .common import (
    Interrupted,
    UsageError,
    add_long_flag,
    check_duration,
    emit_json,
    spec_flag,
    spec_flags,
    spec_from_args,
)

#: What each kind of sweep reads besides --K: the flags it needs (any other is an error).
_SWEEP_NEEDS = {
    "maximal": ("b2",),
    "line": ("a", "b2"),
    "fixed-b1": ("b1", "b2"),
    "k": ("Ks", "b1", "b2"),
    "grid": (),
}


def add(sub) -> None:
    p = sub.add_parser("sweep", help="one ensemble per parameter point; rows to an HDF5 sweep file")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--path",
        choices=[name for name in _SWEEP_NEEDS if name != "grid"],
        help="maximal: Eq. (b2max) over --b2; line: b1 = b2/a (Eq. Ama) over --b2; "
        "fixed-b1: --b1 with --b2 varying (Fig. 9); k: --Ks at fixed --b1, --b2",
    )
    where.add_argument(
        "--grid",
        metavar="b1=START:STOP:COUNT,b2=START:STOP:COUNT",
        help="every (b1, b2) pair of two ranges (pairs with b1 + b2 >= 1 are skipped)",
    )
    spec_flag(p, "K", default=None, help="kick strength, 0 < K < 4 (default 3; not with --path k)")
    p.add_argument("--Ks", metavar="START:STOP:COUNT", help="K range of --path k")
    spec_flag(p, "b1", default=None, help="fixed b1 of --path fixed-b1 and --path k")
    p.add_argument(
        "--b2",
        metavar="START:STOP:COUNT",
        help="b2 range (a single value for --path k); ranges include both ends",
    )
    p.add_argument("--a", type=float, default=None, help="slope of --path line: b1 = b2 / a")
    spec_flag(p, "knots", help="with --path k: another force's knots, instead of --b1, --b2")
    spec_flag(p, "values", help="with --path k and --knots: the force's values")
    p.add_argument(
        "--domain",
        metavar="NAMES",
        help="with --grid: keep points in these domains of Fig. 3, e.g. LR or LR,R",
    )
    spec_flags(
        p,
        ("points", "steps", "seed", "init", "threshold", "threshold_rule"),
        points={"help": "ensemble size per point (default 10000)"},
        steps={"help": "iterations per point (default 120000)"},
        seed={"help": "root seed; point i uses child i of numpy SeedSequence(seed) (default 0)"},
    )
    p.add_argument(
        "--out",
        default=None,
        help="sweep file (HDF5); if it holds this same sweep, only missing points are run",
    )
    p.add_argument("--force", action="store_true", help="replace --out if it holds anything else")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on a Dask cluster, e.g. tcp://host:8786 (default: here, every core per point)",
    )
    spec_flag(p, "threads", help="CPU threads per point (default: every core here; 1 per Dask worker thread)")
    p.add_argument("--json", action="store_true", help='print {"rows": [...]} on stdout')
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_long_flag(p)


def _parse_range(flag: str, text: str) -> list[float]:
    """``START:STOP:COUNT`` (COUNT values, both ends included) or one number."""
    parts = text.split(":")
    try:
        if len(parts) == 1:
            start = stop = float(parts[0])
            count = 1
        elif len(parts) == 3:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        else:
            raise ValueError
    except ValueError:
        raise UsageError(
            f"{flag} {text!r} is not START:STOP:COUNT (both ends included) or a number"
        ) from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise UsageError(f"{flag} {text!r}: START and STOP must be finite numbers")
    try:
        check_count("COUNT", count, 1)
    except ParameterError as exc:
        raise UsageError(f"{flag} {text!r}: {exc}") from None
    if count == 1 and start != stop:
        raise UsageError(f"{flag} {text!r}: COUNT = 1 cannot include both ends of a range; use COUNT >= 2")
    import numpy as np

    from ..sweep import check_sweep_size

    check_sweep_size(count, f"{flag} {text!r} ({count} points)")  # before the values are made
    return np.linspace(start, stop, count).tolist()


def _parse_value(flag: str, text: str) -> float:
    values = _parse_range(flag, text)
    if len(values) != 1:
        raise UsageError(f"{flag} {text!r}: this sweep needs a single value, not a range")
    return values[0]


def _parse_grid(text: str) -> dict[str, list[float]]:
    axes = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        if not sep or name.strip() not in ("b1", "b2") or name.strip() in axes:
            raise UsageError(f"--grid {text!r} is not b1=START:STOP:COUNT,b2=START:STOP:COUNT")
        axes[name.strip()] = _parse_range(f"--grid {name.strip()}", value.strip())
    if set(axes) != {"b1", "b2"}:
        raise UsageError(f"--grid {text!r} needs both b1=START:STOP:COUNT and b2=START:STOP:COUNT")
    return axes


def _sweep_points(args: argparse.Namespace) -> list:
    from .. import sweep

    kind = "grid" if args.grid is not None else args.path
    needs = _SWEEP_NEEDS[kind]
    if kind == "k" and args.knots is not None:
        needs = ("Ks", "knots", "values")
    what = "--grid" if kind == "grid" else f"--path {kind}"
    for name in ("Ks", "b1", "b2", "a", "domain", "K", "knots", "values"):
        given = getattr(args, name) is not None
        used = name in needs or (name == "domain" and kind == "grid") or (name == "K" and kind != "k")
        if name in needs and not given:
            raise UsageError(f"{what} needs --{name}")
        if given and not used:
            raise UsageError(f"--{name} is not used by {what}")
    K = 3.0 if args.K is None else args.K
    if kind == "maximal":
        return sweep.maximal_path(_parse_range("--b2", args.b2), K=K)
    if kind == "line":
        return sweep.line_path(args.a, _parse_range("--b2", args.b2), K=K)
    if kind == "fixed-b1":
        return sweep.fixed_b1_path(args.b1, _parse_range("--b2", args.b2), K)
    if kind == "k" and args.knots is not None:
        table = params_of(3.0, knots=args.knots, values=args.values).table
        return sweep.k_path(_parse_range("--Ks", args.Ks), table=table)
    if kind == "k":
        return sweep.k_path(_parse_range("--Ks", args.Ks), args.b1, _parse_value("--b2", args.b2))
    axes = _parse_grid(args.grid)
    domain = None if args.domain is None else [name.strip() for name in args.domain.split(",")]
    points = sweep.grid_points(axes["b1"], axes["b2"], K=K, domain=domain)
    if not points:
        raise UsageError(
            f"--grid {args.grid!r} has no point with b1 + b2 < 1"
            + ("" if domain is None else f" in domain {args.domain}")
        )
    return points


def _cell(value: float, width: int, spec: str) -> str:
    return f"{'n/a' if math.isnan(value) else format(value, spec):>{width}}"


def _print_rows(rows: list[dict], computed: int, out: str | None) -> None:
    """The table of a sweep; a row with too few chaotic points for A is marked ``*`` and explained.

    Sweep files keep the chaotic-point count but not the classification bound of
    :func:`warpratchet.observables.reliability`, so only its first rule is checked here.
    """
    print(
        f"{'K':>6} {'b1':>10} {'b2':>10} {'domain':>6} {'A':>11} {'+-':>8} {'A_theory':>11} "
        f"{'lyapunov':>9} {'chaotic':>7} {'seconds':>8} {'drift z':>7} verdict"
    )
    few = 0
    for r in rows:
        mark = " *" if r["chaotic_points"] < MIN_CHAOTIC_POINTS else ""
        few += bool(mark)
        print(
            f"{r['K']:>6.4g} {r['b1']:>10.4g} {r['b2']:>10.4g} {r['domain']:>6} {_cell(r['A'], 11, '.5g')} "
            f"{_cell(r['A_stderr'], 8, '.2g')} {_cell(r['A_theory'], 11, '.5g')} "
            f"{_cell(r['lyapunov'], 9, '.4g')} {r['chaotic_fraction']:>7.4f} {r['seconds']:>8.2f} "
            f"{_cell(r['drift_z'], 7, '+.2f')} {r['verdict'] or 'n/a'}{mark}"
        )
    source = f", {len(rows) - computed} read from {out}" if out is not None else ""
    print(f"{len(rows)} points: {computed} computed{source}")
    if few:
        print(
            f"* {few} points have fewer than {MIN_CHAOTIC_POINTS} chaotic points: their A is not an "
            "estimate (UNRELIABLE); run longer or with more points"
        )


def command(args: argparse.Namespace) -> int:
    from .. import sweep

    if args.force and args.out is None:
        raise UsageError("--force needs --out FILE (it replaces that file)")
    points = _sweep_points(args)
    spec = spec_from_args(args, sweep.SweepSpec)
    if args.scheduler is None:  # here, one point after another (a cluster's size is not known)
        what = f"{len(points)} sweep points x {spec.points} points x {spec.steps} steps"
        check_duration(args, what, len(points) * spec.points * spec.steps, args.threads, None)
    computed = []
    try:
        rows = sweep.run_sweep(
            points,
            spec,
            out=args.out,
            client=args.scheduler,
            progress=not args.quiet,
            threads=args.threads,
            force=args.force,
            on_row=computed.append,
        )
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    except KeyboardInterrupt:
        kept = (
            f"{args.out} keeps them: run the same command again to compute the rest"
            if args.out is not None
            else "nothing was saved (no --out)"
        )
        raise Interrupted(f"after {len(computed)} of {len(points)} points; {kept}") from None
    if args.json:
        emit_json({"rows": rows})
    else:
        _print_rows(rows, len(computed), args.out)
    return 0
