"""Which ensemble reproduces the Lyapunov range of the paper's Fig. 9, and what it does to A.

The caption of Fig. 9 (K = 2.99, b1 = 0.25, 0.005 <= b2 <= 0.14) gives 0.4787 < sigma < 0.8326,
with the ensemble "as described in the caption of Fig. 7": 10^4 initial conditions "in the
chaotic region, i.e., all having positive finite-time Lyapunov exponents", n = 120000. That
leaves open (i) where the initial conditions are drawn (the strip B of Eq. B, or the whole
torus) and (ii) when a finite-time exponent counts as "positive". This script measures sigma
(the mean FTLE of the points called chaotic) at both ends of the path for every combination of

* initial conditions: ``strip`` (uniform in B, the package's default for Figs. 7-9) or
  ``torus`` (uniform on [0, 1)^2);
* chaos criterion: FTLE > 10 (1 + ln n)/n (the package default), FTLE > (1 + ln n)/n, FTLE > 0,
  fixed FTLE thresholds, MEGNO > 4, FLI > 2 ln n (``warpratchet.sumrule.chaotic_by``), and the
  census's global chaotic region (FTLE-chaotic and locked to no island class nu = w/m),

then scans the fixed FTLE threshold for the window that reproduces both ends within 1.5 %,
measures A and sigma along the whole path for the ensemble that does (torus, MEGNO > 4) next to
the strip ensemble, splits the difference into the orbits' island classes (Eq. AIn), and shows
how sigma and A of that ensemble drift with n.

Everything comes from one kernel pass per ensemble (``warpratchet.sumrule.classify``: map,
tangent, FTLE, MEGNO, FLI and the momentum record that identifies nu = w/m). Errors are standard
errors std/sqrt(N) over the points of the pooled replicas; at the two ends the spread of the
replica means gives a second, independent error (``se_rep``), a check on the first where orbits
stick for heavy-tailed times.

Seeds: the points of (b2 index i, sampler s, replica r) come from
``numpy.random.default_rng([seed, i, s, r])`` with s = 0 (strip) or 1 (torus); the ends reuse
replica 0 of the path at b2 = 0.005 and 0.14. Default ``--seed 2024``.

Usage::

    python scripts/fig9_ensembles.py            # full: 10^4 points x 1.2e5 steps, 4 replicas,
                                                # 28 path points, n up to 9.6e5 (~10-15 min on 2 cores)
    python scripts/fig9_ensembles.py --quick    # 2000 points x 3e4 steps, 2 replicas, 4 path points (~1 min)
    python scripts/fig9_ensembles.py --json     # also write every number as one JSON object on stdout
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable

import numpy as np
from _options import options

from warpratchet import MapParams, theory
from warpratchet.ensemble import sample_strip, sample_torus
from warpratchet.observables import default_lyapunov_threshold, finite_time_acceleration, lyapunov
from warpratchet.sumrule import MEGNO_THRESHOLD, IndicatorEnsemble, chaotic_by, classify, fli_threshold

K, B1 = 2.99, 0.25
#: The caption of Fig. 9: sigma at the ends of the path, b2 = 0.005 and b2 = 0.14.
PAPER_SIGMA = {0.005: 0.4787, 0.14: 0.8326}
TOLERANCE = 0.015
SAMPLER_CODE = {"strip": 0, "torus": 1}
#: The size options: ``flag: (what, default, default with --quick)``.
SIZES = {
    "--points": ("points per ensemble", 10_000, 2000),
    "--steps": ("iterations n", 120_000, 30_000),
    "--replicas": ("independent ensembles at each end", 4, 2),
    "--path-points": ("b2 values on 0.005..0.14", 28, 4),
}


def points_for(params: MapParams, init: str, n: int, seed: int, index: int, replica: int):
    """Initial points of (b2 index, sampler, replica): ``default_rng([seed, index, code, replica])``."""
    rng = np.random.default_rng([seed, index, SAMPLER_CODE[init], replica])
    return sample_strip(params, n, rng) if init == "strip" else sample_torus(n, rng)


def pooled(pcs) -> dict[str, np.ndarray]:
    """Concatenate the per-point arrays of several ``PointClasses`` (replicas of one ensemble)."""
    names = ("ftle", "megno", "fli", "A", "w", "m", "chaotic")
    out = {name: np.concatenate([getattr(pc, name) for pc in pcs]) for name in names}
    out["replica"] = np.concatenate([np.full(pc.ftle.size, r) for r, pc in enumerate(pcs)])
    return out


def criteria(steps: int) -> dict[str, Callable[[dict], np.ndarray]]:
    """Chaos criteria by name: each maps pooled per-point arrays to a boolean mask."""
    default = default_lyapunov_threshold(steps)
    return {
        "FTLE > 10(1+ln n)/n (default)": lambda d: d["ftle"] > default,
        "FTLE > (1+ln n)/n": lambda d: d["ftle"] > default / 10.0,
        "FTLE > 0": lambda d: d["ftle"] > 0.0,
        "FTLE > 0.01": lambda d: d["ftle"] > 0.01,
        "FTLE > 0.1": lambda d: d["ftle"] > 0.1,
        f"MEGNO > {MEGNO_THRESHOLD:g}": lambda d: d["megno"] > MEGNO_THRESHOLD,
        "FLI > 2 ln n": lambda d: d["fli"] > fli_threshold(steps),
        "census C (default FTLE, no nu lock)": lambda d: d["chaotic"] & (d["m"] == 0),
        "all points": lambda d: np.ones(d["ftle"].size, dtype=bool),
    }


def mean_se(values: np.ndarray) -> tuple[float, float]:
    if values.size < 2:
        return (float(values.mean()) if values.size else math.nan), math.nan
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size))


def replica_se(values: np.ndarray, replica: np.ndarray) -> float:
    """Standard error of the pooled mean from the spread of the replica means (equal-size replicas)."""
    means = [values[replica == r].mean() for r in np.unique(replica) if np.any(replica == r)]
    return float(np.std(means, ddof=1) / math.sqrt(len(means))) if len(means) > 1 else math.nan


def stats(d: dict, mask: np.ndarray) -> dict:
    sigma, sigma_se = mean_se(d["ftle"][mask])
    a, a_se = mean_se(d["A"][mask])
    return {
        "N": int(mask.sum()),
        "fraction": float(mask.mean()),
        "sigma": sigma,
        "sigma_se": sigma_se,
        "sigma_se_rep": replica_se(d["ftle"][mask], d["replica"][mask]),
        "A": a,
        "A_se": a_se,
        "A_se_rep": replica_se(d["A"][mask], d["replica"][mask]),
    }


def paper_mask(d: dict) -> np.ndarray:
    """The ensemble that reproduces Fig. 9 (torus points) : MEGNO > 4."""
    return d["megno"] > MEGNO_THRESHOLD


def decompose(d: dict, mask: np.ndarray) -> dict:
    """Split a chaotic set into the sea (no nu lock) and orbits locked to island classes nu = w/m.

    ``A_pred = f_sea A_sea + sum_nu f_nu nu`` reproduces the set's mean A when the locked orbits
    move at their class's nu (to within 4m/n, Eq. AIn).
    """
    sea = mask & (d["m"] == 0)
    locked = mask & (d["m"] > 0)
    classes = {}
    for w, m in sorted(set(zip(d["w"][locked].tolist(), d["m"][locked].tolist(), strict=True))):
        member = locked & (d["w"] == w) & (d["m"] == m)
        classes[f"{w}/{m}"] = {"share": float(member.sum() / mask.sum()), "nu": w / m}
    a_sea, a_sea_se = mean_se(d["A"][sea])
    f_sea = float(sea.sum() / mask.sum())
    pred = f_sea * a_sea + sum(c["share"] * c["nu"] for c in classes.values())
    return {"sea_share": f_sea, "A_sea": a_sea, "A_sea_se": a_sea_se, "locked": classes, "A_pred": pred}


def threshold_window(ends: dict, steps: int) -> dict:
    """Fixed FTLE thresholds t for which torus points with FTLE > t give both ends within 1.5 %."""
    grid = np.logspace(-6, -1, 201)
    ok = []
    for t in grid:
        good = True
        for b2, target in PAPER_SIGMA.items():
            ftle = ends[(b2, "torus")]["ftle"]
            good &= abs(ftle[ftle > t].mean() / target - 1.0) < TOLERANCE
        ok.append(bool(good))
    ok = np.array(ok)
    runs, start = [], None
    for i, flag in enumerate(list(ok) + [False]):
        if flag and start is None:
            start = i
        if not flag and start is not None:
            runs.append((float(grid[start]), float(grid[i - 1])))
            start = None
    return {
        "grid_points": int(grid.size),
        "windows": runs,
        "regular_floor": default_lyapunov_threshold(steps) / 10,
    }


def n_dependence(
    params: MapParams, n_points: int, checkpoints: list[int], seed: int, index: int
) -> list[dict]:
    """sigma and A of the torus + MEGNO ensemble at several n, from one run (replica 0's points)."""
    x, p = points_for(params, "torus", n_points, seed, index, 0)
    ens = IndicatorEnsemble(params, x, p)
    rows = []
    for n in checkpoints:
        ens.run(n - ens.step)
        state = ens.state()
        mask = chaotic_by("megno", state, ens.indicators(), n)
        sigma, sigma_se = mean_se(lyapunov(state, n)[mask])
        a, a_se = mean_se(finite_time_acceleration(state, n)[mask])
        rows.append(
            {
                "n": n,
                "fraction": float(mask.mean()),
                "sigma": sigma,
                "sigma_se": sigma_se,
                "A": a,
                "A_se": a_se,
            }
        )
    return rows


def fmt_se(value: float, se: float, digits: int) -> str:
    return f"{value:.{digits}f} ± {se:.{digits}f}"


def main(argv: list[str] | None = None) -> int:
    quick_help = "small ensembles, short runs (about a minute)"
    ap, args = options(__doc__, argv, quick=quick_help, seed=2024, sizes=SIZES)
    n_points, steps, replicas, path_count = args.points, args.steps, args.replicas, args.path_points
    if n_points < 2 or steps < 13_824 or replicas < 2 or path_count < 2:
        ap.error(
            "need points >= 2, steps >= 13824 (nu identification up to m = 12), "
            "replicas >= 2, path-points >= 2"
        )
    seed = args.seed
    out = sys.stderr if args.json else sys.stdout
    started = time.perf_counter()

    def log(msg: str) -> None:
        print(f"[{time.perf_counter() - started:7.1f} s] {msg}", file=sys.stderr, flush=True)

    b2_path = np.linspace(0.005, 0.14, path_count)
    end_index = {0.005: 0, 0.14: path_count - 1}

    def run(b2: float, init: str, index: int, replica: int):
        params = MapParams(K, B1, float(b2))
        x, p = points_for(params, init, n_points, seed, index, replica)
        log(f"b2 = {b2:.4f} {init} replica {replica}")
        return classify(params, x, p, steps)

    # -- 1. the two ends, every ensemble and criterion ---------------------------------------
    ends = {}
    for b2, index in end_index.items():
        for init in ("strip", "torus"):
            ends[(b2, init)] = pooled([run(b2, init, index, r) for r in range(replicas)])
    crit = criteria(steps)
    end_rows = []
    for init in ("strip", "torus"):
        for name, select in crit.items():
            row = {"init": init, "criterion": name}
            for b2, target in PAPER_SIGMA.items():
                s = stats(ends[(b2, init)], select(ends[(b2, init)]))
                s["dev_percent"] = 100.0 * (s["sigma"] / target - 1.0)
                s["dev_se"] = (s["sigma"] - target) / s["sigma_se"]
                row[str(b2)] = s
            row["both_within"] = all(abs(row[str(b2)]["dev_percent"]) < 100 * TOLERANCE for b2 in PAPER_SIGMA)
            end_rows.append(row)
    window = threshold_window(ends, steps)

    # -- 2. the path: paper's ensemble (torus, MEGNO > 4) beside the strip ---------------------
    path_rows = []
    default = crit["FTLE > 10(1+ln n)/n (default)"]
    for index, b2 in enumerate(b2_path):
        b2 = float(b2)
        end = next((e for e, i in end_index.items() if i == index), None)
        per = {}
        for init in ("torus", "strip"):
            if end is None:
                per[init] = pooled([run(b2, init, index, 0)])
            else:  # replica 0 of the ends: every path point has exactly one replica
                first = ends[(end, init)]["replica"] == 0
                per[init] = {k: v[first] for k, v in ends[(end, init)].items()}
        params = MapParams(K, B1, b2)
        paper = stats(per["torus"], paper_mask(per["torus"]))
        strip = stats(per["strip"], default(per["strip"]))
        path_rows.append(
            {
                "b2": b2,
                "domain_K3": theory.domain(MapParams(3.0, B1, b2)),
                "domain_K299": theory.domain(params),
                "paper": paper,
                "paper_parts": decompose(per["torus"], paper_mask(per["torus"])),
                "strip": strip,
                "strip_parts": decompose(per["strip"], default(per["strip"])),
                "dA_se": (strip["A"] - paper["A"]) / math.hypot(strip["A_se"], paper["A_se"]),
            }
        )

    # -- 3. n-dependence of the paper's ensemble ----------------------------------------------
    n_max = 8 * steps
    checkpoints = sorted({steps // 8, steps // 4, steps // 2, steps, 2 * steps, 4 * steps, n_max})
    ndep = {}
    for b2, index in end_index.items():
        log(f"n-dependence b2 = {b2}, n up to {n_max}")
        ndep[str(b2)] = n_dependence(MapParams(K, B1, b2), n_points, checkpoints, seed, index)
    seconds = time.perf_counter() - started

    # -- report --------------------------------------------------------------------------------
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p(f"# Fig. 9 ensembles: K = {K}, b1 = {B1}; {n_points} points x n = {steps}, seed {seed}")
    p(
        f"\n## 1. sigma at the ends ({replicas} replicas pooled; "
        "paper: 0.4787 at b2 = 0.005, 0.8326 at b2 = 0.14)\n"
    )
    p(
        "sigma ± se (se_rep from the replica spread); dev = sigma/paper - 1 (and in se); "
        "N = chaotic points of "
        f"{replicas * n_points}.\n"
    )
    p(
        "| init | chaos criterion | sigma(0.005) ± se [se_rep] | dev | N "
        "| sigma(0.14) ± se [se_rep] | dev | N "
        "| both within 1.5 % |"
    )
    p("|---|---|---|---|---|---|---|---|---|")
    for row in end_rows:
        cells = []
        for b2 in PAPER_SIGMA:
            s = row[str(b2)]
            cells += [
                f"{fmt_se(s['sigma'], s['sigma_se'], 4)} [{s['sigma_se_rep']:.4f}]",
                f"{s['dev_percent']:+.2f} % ({s['dev_se']:+.1f} se)",
                str(s["N"]),
            ]
        p(
            f"| {row['init']} | {row['criterion']} | "
            + " | ".join(cells)
            + f" | {'yes' if row['both_within'] else 'no'} |"
        )
    p(
        f"\nFixed FTLE thresholds t giving both ends within 1.5 % (torus, scan of {window['grid_points']} "
        "log-spaced t in [1e-6, 0.1]): "
        + (", ".join(f"[{lo:.2e}, {hi:.2e}]" for lo, hi in window["windows"]) or "none")
        + f"; (1 + ln n)/n = {window['regular_floor']:.2e}, default 10(1 + ln n)/n = "
        f"{default_lyapunov_threshold(steps):.2e}."
    )

    p(f"\nA at the ends ({replicas} replicas pooled; se_rep from the replica spread):\n")
    p(
        "| init | chaos criterion | A(0.005) ± se [se_rep] | chaotic share "
        "| A(0.14) ± se [se_rep] | chaotic share |"
    )
    p("|---|---|---|---|---|---|")
    shown = (
        "FTLE > 10(1+ln n)/n (default)",
        "FTLE > (1+ln n)/n",
        f"MEGNO > {MEGNO_THRESHOLD:g}",
        "census C (default FTLE, no nu lock)",
    )
    for row in end_rows:
        if row["criterion"] in shown:
            cells = [
                f"{fmt_se(s['A'], s['A_se'], 5)} [{s['A_se_rep']:.5f}] | {s['fraction']:.4f}"
                for s in (row[str(b2)] for b2 in PAPER_SIGMA)
            ]
            p(f"| {row['init']} | {row['criterion']} | " + " | ".join(cells) + " |")

    p("\n## 2. Along the path: paper's ensemble (torus, MEGNO > 4) beside the strip (FTLE > default)\n")
    p(
        "One replica per point. frac = chaotic share of the sample; sea = share of the chaotic set "
        "locked to no island class; A_pred = sea share x A_sea + sum over locked classes of share x nu; "
        "dA = A_strip - A_paper "
        "in combined se.\n"
    )
    p(
        "| b2 | domain K=3 / K=2.99 | paper: frac | sigma | A ± se | sea | locked classes (share) "
        "| A_sea ± se "
        "| A_pred | strip: sigma | A ± se | strip locked share | dA/se |"
    )
    p("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for row in path_rows:
        pa, pp, st, sp = row["paper"], row["paper_parts"], row["strip"], row["strip_parts"]
        locked = ", ".join(f"{k}: {v['share']:.4f}" for k, v in pp["locked"].items()) or "-"
        p(
            f"| {row['b2']:.4f} | {row['domain_K3']} / {row['domain_K299']} | {pa['fraction']:.4f} | "
            f"{pa['sigma']:.4f} | {fmt_se(pa['A'], pa['A_se'], 5)} | {pp['sea_share']:.4f} | {locked} | "
            f"{fmt_se(pp['A_sea'], pp['A_sea_se'], 5)} | {pp['A_pred']:.5f} | {st['sigma']:.4f} | "
            f"{fmt_se(st['A'], st['A_se'], 5)} | {1 - sp['sea_share']:.4f} | {row['dA_se']:+.1f} |"
        )
    p("\n## 3. n-dependence of the paper's ensemble (torus, MEGNO > 4; replica 0 of each end, one run)\n")
    p("| b2 | n | chaotic fraction | sigma ± se | A ± se |")
    p("|---|---|---|---|---|")
    for b2, rows in ndep.items():
        for r in rows:
            p(
                f"| {b2} | {r['n']} | {r['fraction']:.4f} | {fmt_se(r['sigma'], r['sigma_se'], 4)} | "
                f"{fmt_se(r['A'], r['A_se'], 5)} |"
            )
    p(f"\nTotal {seconds:.0f} s.")
    if args.json:
        result = {
            "settings": {
                "K": K,
                "b1": B1,
                "points": n_points,
                "steps": steps,
                "replicas": replicas,
                "path_points": path_count,
                "seed": seed,
            },
            "ends": end_rows,
            "threshold_window": window,
            "path": path_rows,
            "n_dependence": ndep,
            "seconds": seconds,
        }
        json.dump(result, sys.stdout, default=float)
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
