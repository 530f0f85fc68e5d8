"""Cost of enumerating every periodic orbit (``warpratchet.orbits``), period by period.

For each case, ``enumerate_orbits`` runs for m = 1, 2, ... and the table gives per period: wall
and CPU seconds, tree nodes visited, candidate itineraries (necklaces with a non-empty cell),
orbits by kind, families (polygons / segments) and the nu of the elliptic orbits. A case stops
at ``--max-period`` or once the next period is predicted (last time x last growth) to exceed
``--budget`` seconds; ``largest_under_budget`` is the largest period that finished within it.

The brute-force alternative solves all ``30^m`` words: its NumPy cost (compose, solve, one
cell test per word, float64) is measured up to ``--brute-max`` and extrapolated at the same
words per second, next to the tree search's nodes. At K = 3 the period-3 families are summed by
``nu`` and compared with Eqs. (SL), (SR) and (SC1)-(SC3).

Usage::

    python benchmarks/orbits.py             # K = 3 (0.1, 0.01) and K = 2.99 (0.25, 0.05), budget 60 s
    python benchmarks/orbits.py --json      # one JSON object on stdout
    python benchmarks/orbits.py --quick     # periods <= 4: seconds
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict

import numpy as np

from warpratchet import MapParams, theory
from warpratchet.orbits import (
    KINDS,
    all_words,
    compose,
    enumerate_orbits,
    fixed_points,
    orbit_families,
    symbol_table,
    word_kicks,
)

#: (K, b1, b2): two cases (Fig. 7's range at K = 3, Fig. 9's path at K = 2.99).
CASES = [(3.0, 0.1, 0.01), (2.99, 0.25, 0.05)]


def _brute_force_seconds(p: MapParams, m: int) -> float:
    """Seconds for the float64 brute force over all (10 n)^m words: compose, solve, test the
    piece of the first symbol."""
    start = time.perf_counter()
    words = all_words(p, m)
    kicks = word_kicks(p)
    x, q, _ = fixed_points(*compose(words, kicks))
    s = symbol_table(len(kicks))[words[:, 0], 0]
    masks = p.table.select(x)
    piece = np.select(masks, range(len(masks)), len(masks))
    np.count_nonzero((x >= 0) & (x < 1) & (q >= 0) & (q < 1) & (s == piece))
    return time.perf_counter() - start


def _run_case(p: MapParams, max_period: int, budget: float, brute_max: int, log) -> dict:
    rows = []
    largest = 0
    for m in range(1, max_period + 1):
        if len(rows) >= 2 and rows[-2]["seconds"] > 0.05:
            growth = rows[-1]["seconds"] / rows[-2]["seconds"]
            if rows[-1]["seconds"] * growth > budget:
                log(f"  period {m}: predicted {rows[-1]['seconds'] * growth:.0f} s > budget, stopping")
                break
        cpu = time.process_time()
        result = enumerate_orbits(p, m)
        cpu = time.process_time() - cpu
        kinds = Counter(o.kind for o in result.orbits)
        shapes = Counter(f.shape for f in result.families)
        row = {
            "period": m,
            "seconds": result.seconds,
            "cpu_seconds": cpu,
            "nodes": result.nodes,
            "candidates": result.candidates,
            "words": len(symbol_table(p.table.n_pieces)) ** m,
            "orbits": {kind: kinds.get(kind, 0) for kind in KINDS},
            "families": {"polygon": shapes.get("polygon", 0), "segment": shapes.get("segment", 0)},
            "elliptic_nu": sorted({o.nu for o in result.orbits if o.kind == "elliptic"}),
        }
        if m <= brute_max:
            row["brute_force_seconds"] = _brute_force_seconds(p, m)
        rows.append(row)
        if result.seconds <= budget:
            largest = m
        log(f"  period {m}: {result.seconds:.2f} s, {result.nodes} nodes, {dict(kinds)}, {dict(shapes)}")
    measured = [r for r in rows if "brute_force_seconds" in r]
    rate = measured[-1]["words"] / measured[-1]["brute_force_seconds"] if measured else None
    for row in rows:
        row["brute_force_extrapolated_seconds"] = row["words"] / rate if rate else None
    return {"K": p.K, "b1": p.b1, "b2": p.b2, "rows": rows, "largest_under_budget": largest}


def _k3_families(p: MapParams) -> dict:
    """Period-3 families at K = 3 summed by nu, against Eqs. (SL), (SR), (SC1)-(SC3)."""
    areas: dict = defaultdict(float)
    for family in orbit_families(p, 3):
        areas[family.nu] += family.invariant_area
    return {
        "invariant_area_by_nu": {str(nu): area for nu, area in sorted(areas.items())},
        "S_L": theory.area_left(p),
        "S_R": theory.area_right(p),
        "one_minus_families": 1.0 - sum(areas.values()),
        "S_C": theory.area_chaotic(p),
    }


def _table(case: dict) -> str:
    lines = [f"K = {case['K']}, b1 = {case['b1']}, b2 = {case['b2']}"]
    head = f"{'m':>3} {'wall s':>8} {'cpu s':>8} {'nodes':>9} {'30^m words':>11} {'brute s':>9}"
    lines.append(head + f" {'ell':>5} {'hyp':>6} {'par':>4} {'poly':>5} {'seg':>4}  elliptic nu")
    for r in case["rows"]:
        brute = r.get("brute_force_seconds", r["brute_force_extrapolated_seconds"])
        brute_text = ("" if "brute_force_seconds" in r else "~") + format(brute, ".3g") if brute else "-"
        lines.append(
            f"{r['period']:>3} {r['seconds']:>8.2f} {r['cpu_seconds']:>8.2f} {r['nodes']:>9}"
            f" {r['words']:>11.2e} {brute_text:>9} {r['orbits']['elliptic']:>5}"
            f" {r['orbits']['hyperbolic']:>6} {r['orbits']['parabolic']:>4} {r['families']['polygon']:>5}"
            f" {r['families']['segment']:>4}  {', '.join(f'{nu:.4g}' for nu in r['elliptic_nu'])}"
        )
    lines.append(f"largest period within the budget: {case['largest_under_budget']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max-period", type=int, default=12)
    parser.add_argument("--budget", type=float, default=60.0, help="seconds per period (default 60)")
    parser.add_argument("--brute-max", type=int, default=4, help="largest m for the measured brute force")
    parser.add_argument("--quick", action="store_true", help="periods <= 4, brute force <= 3")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    if args.quick:
        args.max_period, args.brute_max = 4, 3

    def log(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    cases = []
    for K, b1, b2 in CASES:
        log(f"K = {K}, b1 = {b1}, b2 = {b2}")
        cases.append(_run_case(MapParams(K, b1, b2), args.max_period, args.budget, args.brute_max, log))
    families = _k3_families(MapParams(*CASES[0]))
    report = {"cases": cases, "budget_seconds": args.budget, "k3_families": families}
    if args.json:
        print(json.dumps(report))
    else:
        print("\n\n".join(_table(case) for case in cases))
        print("\nK = 3 period-3 families:", json.dumps(report["k3_families"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
