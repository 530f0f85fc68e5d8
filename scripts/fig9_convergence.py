"""Convergence of A_n along Fig. 9's path: drift between n/2 and n, and the robust standard error.

For each b2 on K = 2.99, b1 = 0.25, 0.005 <= b2 <= 0.14, one ensemble (``--init``: the strip B,
the package default, or the torus; ``--threshold-rule``: strict or positive) is run to n steps
with a :class:`warpratchet.history.History` (what every ``warpratchet run`` and sweep point
records: A_n over chaotic points with its standard error and Var(p_n - p_0) over them at 8
log-spaced steps per decade and at n, and the momentum gains of 4096 of the orbits over 64
equal blocks of n/64 steps). Printed per point: A with the plain error std/sqrt(N), the robust
error of ``warpratchet.convergence.robust_stderr`` (variance-time batch means, never below the
plain one) and its exponent mu, the drift A_n - A_{n/2} in units of its standard error, and the
verdict (:meth:`History.convergence`). At the end: where A rises from one b2 to the next by more
than 4 combined errors, with either error (Eq. Ab at K = 3 decreases along the path; rises are
islands coming and going, or errors that are still too small).

Seeds: point i uses ``warpratchet.sweep.point_seed(seed, i)`` as a sweep would (``--seed``,
default 0, the seed of ``python -m viz figures``), so its rows are those of the Fig. 9 sweep
(``--init torus --threshold-rule positive``: the ``fig9_paper`` sweep).

Usage::

    python scripts/fig9_convergence.py               # 28 points, 10^4 strip points x 1.2e5 steps (~3 min)
    python scripts/fig9_convergence.py --init torus --threshold-rule positive   # the paper's ensemble
    python scripts/fig9_convergence.py --quick       # 6 points, 2000 x 2e4 (seconds)
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
from _options import options

from warpratchet import Ensemble, MapParams
from warpratchet.convergence import diffusion_exponent
from warpratchet.history import History
from warpratchet.sweep import point_seed

K, B1 = 2.99, 0.25
#: The size options: ``flag: (what, default, default with --quick)``.
SIZES = {"--points": ("points per ensemble", 10_000, 2000), "--steps": ("iterations n", 120_000, 20_000)}


def record(params: MapParams, points: int, steps: int, init: str, seed: int, rule: str) -> History:
    """Run one ensemble with a History (rows and block gains) and return it."""
    history = History(rule=rule)
    Ensemble.sample(params, points, init, seed).run(steps, [history])
    return history


def main(argv: list[str] | None = None) -> int:
    def extra(ap: argparse.ArgumentParser) -> None:
        ap.add_argument("--init", choices=("strip", "torus"), default="strip")
        ap.add_argument("--threshold-rule", choices=("strict", "positive"), default="strict")

    _, args = options(__doc__, argv, quick=None, seed=0, sizes=SIZES, extra=extra)
    points, steps = args.points, args.steps
    b2_values = np.linspace(0.005, 0.14, 28)
    indices = [0, 5, 8, 13, 20, 27] if args.quick else range(28)
    out = sys.stderr if args.json else sys.stdout
    started = time.perf_counter()
    rows = []
    for i in indices:
        params = MapParams(K, B1, float(b2_values[i]))
        print(f"[{time.perf_counter() - started:6.1f} s] b2 = {params.b2:.4f}", file=sys.stderr, flush=True)
        history = record(params, points, steps, args.init, point_seed(args.seed, i), args.threshold_rule)
        h, v = history.rows, history.convergence()
        rows.append(
            {
                "b2": params.b2,
                "A": h["A"][-1],
                "naive": h["A_stderr"][-1],
                "robust": v.A_stderr_robust,
                "mu": v.exponent,
                "mu_history": diffusion_exponent(h["step"], h["var_dp_chaotic"]),
                "delta": v.drift,
                "z": v.drift_z,
                "verdict": v.verdict,
            }
        )
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p(
        f"# Fig. 9 path, {args.init} ensemble ({args.threshold_rule} threshold): {points} points x "
        f"n = {steps}, seed {args.seed}\n"
    )
    p(
        "| b2 | A | plain se | robust se | robust/plain | mu (blocks) | mu (history) | A_n - A_n/2 | z "
        "| verdict |"
    )
    p("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        p(
            f"| {r['b2']:.4f} | {r['A']:.5f} | {r['naive']:.5f} | {r['robust']:.5f} | "
            f"{r['robust'] / r['naive']:.2f} | {r['mu']:.2f} | {r['mu_history']:.2f} | {r['delta']:+.5f} | "
            f"{r['z']:+.1f} | {r['verdict']} |"
        )
    # Eq. (Ab) at K = 3 decreases along the path; count where A(K = 2.99) rises instead.
    for key in ("naive", "robust"):
        rises = [
            ((b["A"] - a["A"]) / math.hypot(a[key], b[key]), a["b2"], b["b2"])
            for a, b in zip(rows[:-1], rows[1:], strict=True)
        ]
        big = [r for r in rises if r[0] > 4]
        listed = ", ".join(f"{lo:.3f} -> {hi:.3f} ({z:.1f})" for z, lo, hi in big) or "none"
        p(
            f"\nA rises from one b2 to the next by more than 4 combined {key} errors: "
            f"{len(big)} of {len(rises)}: {listed}."
        )
    p(f"\nTotal {time.perf_counter() - started:.0f} s.")
    if args.json:
        json.dump(
            {
                "points": points,
                "steps": steps,
                "init": args.init,
                "threshold_rule": args.threshold_rule,
                "seed": args.seed,
                "rows": rows,
            },
            sys.stdout,
        )
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
