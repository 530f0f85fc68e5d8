"""Steps each chaos indicator needs to agree with a long-run FTLE classification.

For each parameter point, ``points`` uniform torus points (seed 1) are iterated once with
:class:`warpratchet.sumrule.IndicatorEnsemble` (map, tangent, MEGNO and FLI in one kernel pass)
to ``reference`` steps (10^5 by default). At every checkpoint ``n`` (powers of 2^(1/2) from 16)
each indicator classifies the points with its default threshold
(:func:`warpratchet.sumrule.chaotic_by`):

* ``ftle``: FTLE > 10 (1 + ln n)/n (the package default);
* ``megno``: mean MEGNO of M^8 > 4 (regular orbits -> 2, or 0 where DM is periodic);
* ``fli``: FLI of M^8 > 2 ln n;

and the share of points on which it agrees with the FTLE classification at ``reference`` steps
is recorded. Reported per indicator: ``steps_to_999``, the first checkpoint from which agreement
stays >= 99.9% at every later checkpoint (None if never before the reference), and the whole
agreement curve. ``ambiguous_reference`` is the share of points whose reference FTLE lies within a
factor 3 of its threshold: classifications there are not settled at 10^5 steps either.

Also measured, within the same run: the throughput of the indicator kernel over the plain
``advance_map`` kernel (same points, same steps), as a ratio.

Usage::

    python benchmarks/classifiers.py             # 4 parameter points, 20000 points, 1e5 steps
    python benchmarks/classifiers.py --json      # one JSON object on stdout
    python benchmarks/classifiers.py --quick     # 2000 points, reference 2e4 steps: seconds
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from warpratchet import Ensemble, MapParams
from warpratchet.observables import default_lyapunov_threshold, lyapunov
from warpratchet.sumrule import INDICATORS, IndicatorEnsemble, chaotic_by

#: (K, b1, b2): two K at b1 = 0.1, b2 = 0.01, and one more point each
#: (Fig. 12's domain-R point at K = 3, Fig. 9's path at K = 2.99).
CASES = [(3.0, 0.1, 0.01), (2.99, 0.1, 0.01), (3.0, 0.3, 0.03), (2.99, 0.25, 0.05)]
TARGET = 0.999


def _checkpoints(reference: int) -> list[int]:
    steps = sorted({int(round(16 * 2 ** (k / 2))) for k in range(0, 64)})
    return [n for n in steps if n < reference] + [reference]


def _steps_to_target(curve: list[tuple[int, float]]) -> int | None:
    first = None
    for n, agreement in curve:
        if agreement >= TARGET:
            first = n if first is None else first
        else:
            first = None
    return first


def run_case(K: float, b1: float, b2: float, points: int, reference: int) -> dict:
    p = MapParams(K, b1, b2)
    rng = np.random.default_rng(1)
    x, y = rng.random(points), rng.random(points)
    ens = IndicatorEnsemble(p, x, y)
    records = {}
    start = time.perf_counter()
    for n in _checkpoints(reference):
        ens.run(n - ens.step)
        state, ind = ens.state(), ens.indicators()
        records[n] = {name: chaotic_by(name, state, ind, n) for name in INDICATORS}
    indicator_seconds = time.perf_counter() - start
    ref_ftle = lyapunov(ens.state(), reference)
    reference_mask = records[reference]["ftle"]
    threshold = default_lyapunov_threshold(reference)
    ambiguous = float(np.mean((ref_ftle > threshold / 3.0) & (ref_ftle < threshold * 3.0)))
    # Plain kernel, same work, one chunk per checkpoint interval like above.
    plain = Ensemble(p, x, y)
    start = time.perf_counter()
    for n in _checkpoints(reference):
        plain.run(n - plain.step)
        plain.state()
    plain_seconds = time.perf_counter() - start
    out = {"K": K, "b1": b1, "b2": b2, "points": points, "reference_steps": reference,
           "chaotic_fraction": float(reference_mask.mean()), "ambiguous_reference": ambiguous,
           "indicator_over_plain_time": indicator_seconds / plain_seconds, "indicators": {}}  # fmt: skip
    for name in INDICATORS:
        curve = [(n, float(np.mean(masks[name] == reference_mask))) for n, masks in records.items()]
        # The FTLE at the reference length is the reference itself: leave that point out.
        scored = curve[:-1] if name == "ftle" else curve
        out["indicators"][name] = {"steps_to_999": _steps_to_target(scored), "agreement": curve}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2000 points, reference 2e4 steps")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--points", type=int, default=None, help="points per case (default 20000)")
    parser.add_argument("--reference", type=int, default=None, help="reference FTLE steps (default 1e5)")
    args = parser.parse_args(argv)
    points = args.points or (2_000 if args.quick else 20_000)
    reference = args.reference or (20_000 if args.quick else 100_000)
    results = []
    for K, b1, b2 in CASES:
        print(f"K = {K}, b1 = {b1}, b2 = {b2} ...", file=sys.stderr, flush=True)
        results.append(run_case(K, b1, b2, points, reference))
    if args.json:
        print(json.dumps({"target": TARGET, "cases": results}))
        return 0
    print(f"steps until >= {TARGET:.1%} agreement with the FTLE classification at the reference length")
    header = " ".join(f"{c:>8}" for c in INDICATORS)
    print(f"{'K':>5} {'b1':>5} {'b2':>5} {'chaotic':>8} {'ambig.':>7} {header}  indicator/plain time")
    for r in results:
        cells = []
        for c in INDICATORS:
            steps = r["indicators"][c]["steps_to_999"]
            cells.append(f"{'never' if steps is None else steps:>8}")
        where = f"{r['K']:>5} {r['b1']:>5} {r['b2']:>5}"
        shares = f"{r['chaotic_fraction']:8.4f} {r['ambiguous_reference']:7.4f}"
        print(f"{where} {shares} {' '.join(cells)}  {r['indicator_over_plain_time']:.2f}")
    print("agreement at selected n (ftle / megno / fli):")
    for r in results:
        curves = {c: dict(r["indicators"][c]["agreement"]) for c in INDICATORS}
        picks = [n for n in curves["ftle"] if math.log2(n).is_integer() and n >= 64] + [r["reference_steps"]]
        row = "  ".join(f"{n}: " + "/".join(f"{curves[c][n]:.4f}" for c in INDICATORS) for n in picks)
        print(f"  K = {r['K']}, b1 = {r['b1']}, b2 = {r['b2']}: {row}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
