"""How much A on Fig. 9's path depends on where "chaotic" starts: the threshold sensitivity.

The paper's ensemble of Fig. 9 (``warpratchet.paper.FIG9_ENSEMBLE``: initial conditions uniform
on the torus, chaotic when the FTLE exceeds (1 + ln n)/n) counts weakly chaotic orbits that a
threshold ten times higher, 10 (1 + ln n)/n (the package's default rule), leaves out. Both
thresholds sit in the gap between regular FTLEs (below ~(1 + ln n)/n) and the chaotic sea, so
neither is wrong; A moves between them. For every point of the path this script runs the
ensemble of the ``fig9_paper`` sweep (the same points, seeds ``point_seed(seed, i)``, so A under
the paper's rule equals that sweep's row bit for bit) and summarises the one final state under
both rules: A and its standard error under each, the difference, and the classification bound
of each summary (``Summary.classification_bound``: how far the points within a factor 2 of the
threshold could move A). ``python -m viz.report`` reads the JSON (``--json``) as
``fig9_thresholds.json`` in the sweeps folder and adds the difference to the Fig. 9 table as an
error column.

Usage::

    python scripts/fig9_thresholds.py --json > figures/sweeps/fig9_thresholds.json   # 28 points
    python scripts/fig9_thresholds.py --quick                                        # 4 points, small
"""

from __future__ import annotations

import json
import sys

from _options import options

from warpratchet import Ensemble, paper
from warpratchet.sweep import fixed_b1_path, point_seed

RULES = ("positive", "strict")


SIZES = {
    "--points": ("initial conditions per point", 10_000, 2_000),
    "--steps": ("iterations n", 120_000, 30_000),
    "--count": ("points of the path", 28, 4),
}


def main(argv: list[str] | None = None) -> int:
    _, args = options(
        __doc__,
        argv,
        quick="4 points of the path, 2000 initial conditions x 30000 steps",
        seed=0,
        sizes=SIZES,
    )
    path = paper.FIG9
    params = fixed_b1_path(path.b1, path.b2_values(args.count), K=path.K)
    rows = []
    for i, p in enumerate(params):
        ens = Ensemble.sample(p, args.points, paper.FIG9_ENSEMBLE["init"], seed=point_seed(args.seed, i))
        ens.run(args.steps)
        row = {"b2": p.b2}
        for rule in RULES:
            s = ens.summary(None, rule, warn=False)
            row.update(
                {
                    f"A_{rule}": s.A,
                    f"A_stderr_{rule}": s.A_stderr,
                    f"threshold_{rule}": s.threshold,
                    f"chaotic_points_{rule}": s.chaotic_points,
                    f"classification_bound_{rule}": s.classification_bound,
                }
            )
        row["sensitivity"] = abs(row["A_positive"] - row["A_strict"])
        rows.append(row)
        print(
            f"b2 = {p.b2:.4f}: A = {row['A_positive']:.6f} +- {row['A_stderr_positive']:.2g} ((1 + ln n)/n), "
            f"{row['A_strict']:.6f} +- {row['A_stderr_strict']:.2g} (10 (1 + ln n)/n): "
            f"|difference| = {row['sensitivity']:.2g}",
            file=sys.stderr,
        )
    result = {
        "K": path.K,
        "b1": params[0].b1,
        "points": args.points,
        "steps": args.steps,
        "seed": args.seed,
        "init": paper.FIG9_ENSEMBLE["init"],
        "rows": rows,
    }
    if args.json:
        print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
