"""Where Eq. (Ae) stops describing the island census: islands of higher period away from K = 3.

Eq. (Ae), A = (S_R - S_L)/S_C, is the sum rule Eq. (sum), S_C A + sum_j S_j nu_j = 0, with the
period-1 accelerator islands L (nu = +1) and R (nu = -1) only: exact at K = 3 (Sec. IV), where no
other accelerating island exists. For any K, ``warpratchet.sumrule.census`` finds every island
class nu = w/m (m <= 12) on the torus. This script evaluates, from one census per parameter point,

* A_(Ae) = (S_R - S_L)/S_C with the census's own areas of the classes nu = -1 and +1;
* A_sumrule = -sum_j S_j nu_j / S_C over all classes, and A_direct (mean A_n over C);
* D = A_sumrule - A_(Ae) = -sum_{m > 1} S_j nu_j / S_C, the part of A carried by islands of
  higher period, in its standard error (delta method over the multinomial of the sample:
  se(D)^2 = (sum_{m>1} S_j nu_j^2 + D^2 S_C) / (N S_C^2)); likewise
  se(A_(Ae))^2 = (S_L + S_R + A_(Ae)^2 S_C) / (N S_C^2);
* the classes with m > 1 (nu, area, share of sum_j S_j nu_j).

Note: the census classifies by mean velocity, so its nu = +-1 classes hold every island moving
one unit per kick, including chains of period m with w = +-m (none is separable by momentum).

Two parts: a table at the paper's figures (K = 3 control, Fig. 1(b) K = 3.618, Fig. 1(c)
K = 2.725, K = 2.99 at b1 = 0.1, b2 = 0.01 and on Fig. 9's path) and a scan in K at b1 = 0.1,
b2 = 0.01 from 2.9 to 3.1. All censuses use the same seed (``--seed``, default 0), so their
sampling errors are correlated across rows (same initial points).

Usage::

    python scripts/ae_census.py            # 10^5 points, n = 10^5 (table), 5e4 (scan); ~10-15 min on 2 cores
    python scripts/ae_census.py --quick    # 2e4 points, n = 2e4, 5 scan points (~1 min)
    python scripts/ae_census.py --json     # also every number as one JSON object on stdout
"""

from __future__ import annotations

import json
import math
import sys
import time

from _options import options

from warpratchet import MapParams, theory
from warpratchet.sumrule import census

#: (label, K, b1, b2) of the table.
CASES = [
    ("K = 3 control", 3.0, 0.1, 0.01),
    ("Fig. 1(b)", 3.618034, 0.05, 0.02),
    ("Fig. 1(c)", 2.72475, 0.05, 0.02),
    ("K = 2.99", 2.99, 0.1, 0.01),
    ("Fig. 9 path", 2.99, 0.25, 0.005),
    ("Fig. 9 path", 2.99, 0.25, 0.05),
    ("Fig. 9 path", 2.99, 0.25, 0.1),
    ("Fig. 9 path", 2.99, 0.25, 0.14),
]
SCAN_K = [2.9, 2.95, 2.98, 2.99, 2.995, 3.0, 3.005, 3.01, 3.02, 3.05, 3.1]
SCAN_B1, SCAN_B2 = 0.1, 0.01
#: The size options: ``flag: (what, default, default with --quick)``.
SIZES = {
    "--points": ("points per census", 100_000, 20_000),
    "--steps": ("n of the table", 100_000, 20_000),
    "--scan-steps": ("n of the K scan", 50_000, 20_000),
}


def analyse(c) -> dict:
    """Eq. (Ae) against the census ``c`` (a :class:`warpratchet.sumrule.Census`), with errors."""
    n, s_c = c.points, c.S_C
    s_l = sum(i.area for i in c.islands if i.nu == 1.0)
    s_r = sum(i.area for i in c.islands if i.nu == -1.0)
    higher = [i for i in c.islands if i.m > 1]
    a_ae = (s_r - s_l) / s_c
    se_ae = math.sqrt((s_l + s_r + a_ae**2 * s_c) / n) / s_c
    flux = -sum(i.area * i.nu for i in c.islands)  # = S_C A_sumrule
    d = -sum(i.area * i.nu for i in higher) / s_c
    se_d = math.sqrt((sum(i.area * i.nu**2 for i in higher) + d**2 * s_c) / n) / s_c
    return {
        "K": c.K,
        "b1": c.b1,
        "b2": c.b2,
        "points": n,
        "steps": c.steps,
        "S_C": s_c,
        "S_C_se": c.S_C_stderr,
        "S_L": s_l,
        "S_R": s_r,
        "higher_area": sum(i.area for i in higher),
        "higher": [
            {"nu": f"{i.w}/{i.m}", "area": i.area, "area_se": i.area_stderr, "share": -i.area * i.nu / flux}
            for i in higher
        ],
        "unidentified": c.unidentified_area,
        "A_Ae": a_ae,
        "A_Ae_se": se_ae,
        "A_sumrule": c.A_sumrule,
        "A_sumrule_se": c.A_sumrule_stderr,
        "A_direct": c.A_direct,
        "A_direct_se": c.A_direct_stderr,
        "D": d,
        "D_se": se_d,
        "D_z": d / se_d if se_d > 0 else 0.0,
        # A_(Ae) and A_direct use the same points; their errors are combined as if independent.
        "direct_z": (c.A_direct - a_ae) / math.hypot(se_ae, c.A_direct_stderr),
        "A_theory": theory.acceleration(MapParams(c.K, c.b1, c.b2)) if c.K == 3.0 else math.nan,
    }


def main(argv: list[str] | None = None) -> int:
    _, args = options(__doc__, argv, quick="2e4 points, n = 2e4, 5 scan points", seed=0, sizes=SIZES)
    points, steps, scan_steps = args.points, args.steps, args.scan_steps
    scan = [2.95, 2.99, 3.0, 3.01, 3.05] if args.quick else SCAN_K
    out = sys.stderr if args.json else sys.stdout
    started = time.perf_counter()

    def run(K, b1, b2, n):
        print(
            f"[{time.perf_counter() - started:7.1f} s] census K = {K}, b1 = {b1}, b2 = {b2}, n = {n}",
            file=sys.stderr,
            flush=True,
        )
        return analyse(census(MapParams(K, b1, b2), n, points=points, seed=args.seed))

    table = [dict(run(K, b1, b2, steps), label=label) for label, K, b1, b2 in CASES]
    scan_rows = [run(K, SCAN_B1, SCAN_B2, scan_steps) for K in scan]
    seconds = time.perf_counter() - started

    p = lambda *a: print(*a, file=out)  # noqa: E731
    p(f"# Eq. (Ae) against the island census: {points} torus points (seed {args.seed})\n")
    p(f"## 1. The paper's figures (n = {steps})\n")
    p(
        "D = A_sumrule - A_(Ae): the share of A carried by islands of period m > 1; z = D / se(D). "
        "Higher-period classes: nu: area (share of sum_j S_j nu_j).\n"
    )
    header = (
        "| case | K | b1 | b2 | S_C | S_L (nu=+1) | S_R (nu=-1) | classes m > 1 | A_(Ae) | A_sumrule | "
        "A_direct | D ± se (z) | A_direct - A_(Ae) in se |"
    )
    p(header)
    p("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in table:
        hi = "; ".join(f"{h['nu']}: {h['area']:.5f} ({h['share']:+.0%})" for h in r["higher"]) or "none"
        p(
            f"| {r['label']} | {r['K']} | {r['b1']} | {r['b2']} | {r['S_C']:.4f} ± {r['S_C_se']:.4f} | "
            f"{r['S_L']:.5f} | {r['S_R']:.5f} | {hi} | {r['A_Ae']:.5f} ± {r['A_Ae_se']:.5f} | "
            f"{r['A_sumrule']:.5f} ± {r['A_sumrule_se']:.5f} | "
            f"{r['A_direct']:.5f} ± {r['A_direct_se']:.5f} | "
            f"{r['D']:+.5f} ± {r['D_se']:.5f} ({r['D_z']:+.1f}) | {r['direct_z']:+.1f} |"
        )
    p(f"\n## 2. Scan in K at b1 = {SCAN_B1}, b2 = {SCAN_B2} (n = {scan_steps})\n")
    p(
        "| K | S_C | S_L | S_R | area of classes m > 1 | largest m > 1 classes | A_(Ae) | A_sumrule "
        "| A_direct | D ± se (z) | A_direct - A_(Ae) in se |"
    )
    p("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in scan_rows:
        top = sorted(r["higher"], key=lambda h: -h["area"])[:4]
        hi = "; ".join(f"{h['nu']}: {h['area']:.5f}" for h in top) or "none"
        p(
            f"| {r['K']} | {r['S_C']:.4f} | {r['S_L']:.5f} | {r['S_R']:.5f} | "
            f"{r['higher_area']:.5f} | {hi} | "
            f"{r['A_Ae']:.5f} ± {r['A_Ae_se']:.5f} | {r['A_sumrule']:.5f} ± {r['A_sumrule_se']:.5f} | "
            f"{r['A_direct']:.5f} ± {r['A_direct_se']:.5f} | "
            f"{r['D']:+.5f} ± {r['D_se']:.5f} ({r['D_z']:+.1f}) | {r['direct_z']:+.1f} |"
        )
    p(f"\nTotal {seconds:.0f} s.")
    if args.json:
        settings = {"points": points, "steps": steps, "scan_steps": scan_steps, "seed": args.seed}
        json.dump({"settings": settings, "table": table, "scan": scan_rows, "seconds": seconds}, sys.stdout)
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
