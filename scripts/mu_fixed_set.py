"""Why mu exceeds 2 near sticky islands: V(n) over the chaotic set of each n, and over one fixed set.

``run --transport`` fits mu to ``V(n)``, the variance of ``p_n - p_0`` over the points chaotic at
``n`` (FTLE above the threshold at ``n``, as a History row counts them). That set grows with ``n``
as the threshold ``10 (1 + ln n)/n`` falls, and a slope of ``log V`` above 2 (faster than
ballistic) cannot be the long-run spread of one set of orbits whose steps are bounded. This
script separates the two causes: it records every point's ``p_n - p_0`` and FTLE at the spread's
steps, then fits the slope over the last two decades of n for

* the chaotic set of each row (what ``run --transport`` reports as mu), and
* the set chaotic at the last row, held fixed over the whole range (no set change).

A fixed set can still show a slope above 2 for a while: an orbit that enters a long flight at
step ``tau`` gains ``v (n - tau)``, steeper than ``n`` while ``tau`` is not small against ``n``.

Usage::

    python scripts/mu_fixed_set.py                  # K = 2.99, b1 = 0.1361, b2 = 0.05; 30000 x 10^6 (~1 min)
    python scripts/mu_fixed_set.py --quick          # 10^4 points x 10^5 steps (seconds)
    python scripts/mu_fixed_set.py --K 3            # the diffusive case (no sticky islands at K = 3)
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from _options import options

from warpratchet import MapParams, Observer
from warpratchet.observables import lyapunov, lyapunov_threshold, momentum_gain
from warpratchet.transport import TransportEnsemble
from warpratchet.transport._diffusion import spread_steps
from warpratchet.transport._fits import MU_DECADES


class _Rows(Observer):
    """Every point's ``p_n - p_0`` and FTLE at the spread's steps (a few MB per row here)."""

    def __init__(self) -> None:
        self.gain: dict[int, np.ndarray] = {}
        self.ftle: dict[int, np.ndarray] = {}

    def begin(self, ensemble, target_step: int) -> None:
        self.todo = set(spread_steps(ensemble.step, target_step))

    def next_stop(self, step: int) -> int | None:
        return min((n for n in self.todo if n > step), default=None)

    def after_chunk(self, ensemble, seconds: float) -> None:
        if ensemble.step in self.todo:
            views = ensemble.views()
            self.gain[ensemble.step] = momentum_gain(views)
            self.ftle[ensemble.step] = lyapunov(views, ensemble.step)


def _slope(steps: np.ndarray, var: np.ndarray) -> float:
    return float(np.polyfit(np.log(steps), np.log(var), 1)[0])


def main(argv: list[str] | None = None) -> int:
    def extra(ap):
        ap.add_argument("--K", type=float, default=2.99)
        ap.add_argument("--b1", type=float, default=0.1361)
        ap.add_argument("--b2", type=float, default=0.05)

    sizes = {"--points": ("points", 30_000, 10_000), "--steps": ("steps", 1_000_000, 100_000)}
    _, args = options(__doc__, argv, quick="10^4 points x 10^5 steps", seed=1, sizes=sizes, extra=extra)
    start = time.perf_counter()
    ensemble = TransportEnsemble.sample(MapParams(args.K, args.b1, args.b2), args.points, "strip", args.seed)
    rows = _Rows()
    ensemble.run(args.steps, [rows])
    fit = ensemble.diffusion()
    steps = np.array(sorted(rows.gain))
    steps = steps[steps >= steps[-1] / 10.0**MU_DECADES]
    chaotic = {int(n): rows.ftle[n] > lyapunov_threshold(int(n)) for n in steps}
    fixed = chaotic[int(steps[-1])]
    moving_var = np.array([rows.gain[n][chaotic[int(n)]].var(ddof=1) for n in steps])
    fixed_var = np.array([rows.gain[n][fixed].var(ddof=1) for n in steps])
    out = {
        "K": args.K,
        "b1": args.b1,
        "b2": args.b2,
        "points": args.points,
        "steps": args.steps,
        "fit_steps": [int(steps[0]), int(steps[-1])],
        "mu": fit.mu,
        "mu_stderr": fit.stderr,
        "mu_reason": fit.reason,
        "slope_chaotic_set_of_each_row": _slope(steps, moving_var),
        "slope_fixed_set": _slope(steps, fixed_var),
        "chaotic_fraction_first_last": [float(chaotic[int(steps[0])].mean()), float(fixed.mean())],
        "seconds": round(time.perf_counter() - start, 1),
    }
    if args.json:
        json.dump(out, sys.stdout, indent=1)
        print()
        return 0
    print(f"K = {args.K}, b1 = {args.b1}, b2 = {args.b2}: {args.points} points x {args.steps} steps")
    print(f"  mu (run --transport)          = {fit.mu:.3f} +- {fit.stderr:.3f} over n = {out['fit_steps']}")
    print(f"  slope, chaotic set of each n  = {out['slope_chaotic_set_of_each_row']:.3f}")
    print(f"  slope, set chaotic at the end = {out['slope_fixed_set']:.3f}")
    first, last = out["chaotic_fraction_first_last"]
    print(f"  chaotic fraction {first:.4f} -> {last:.4f} over the fit range ({out['seconds']} s)")
    if fit.reason:
        print(f"  flagged: {fit.reason}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
