"""The Fig. 9 section of the validation report: the paper's ensemble, the strip beside it, convergence.

Numbers come from two sweeps on Fig. 9's path (``fig9_paper``: the paper's ensemble,
:data:`warpratchet.paper.FIG9_ENSEMBLE`; ``fig9``: the strip B of Figs. 7-8) and, when present,
from the JSON output of ``scripts/fig9_ensembles.py`` (every ensemble and chaos criterion at the
two ends of the path, the island classes of the chaotic orbits, the dependence on n).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from warpratchet import paper, theory
from warpratchet.params import MapParams

from .checks import CheckedRow, rises, robust_stderr
from .sections import fixed, general, settings_line

__all__ = [
    "fig9_section",
    "ENSEMBLES_COMMAND",
    "THRESHOLDS_COMMAND",
    "path_ends",
    "deviation",
    "threshold_verdict",
]

#: How the JSON of the ensemble comparison is made (the report reads it from the sweeps folder).
ENSEMBLES_COMMAND = "python scripts/fig9_ensembles.py --json > {dir}/fig9_ensembles.json"
THRESHOLDS_COMMAND = "python scripts/fig9_thresholds.py --json > {dir}/fig9_thresholds.json"


def threshold_verdict(verdict: str, sensitivity: float, error: float) -> str:
    """The convergence ``verdict``, with ``threshold-sensitive`` where moving the FTLE threshold from
    (1 + ln n)/n to 10 (1 + ln n)/n moves A by more than its (robust) standard ``error``: then the
    threshold, not the sampling, dominates the uncertainty of A."""
    if not sensitivity > error:  # also NaN: no measurement, no claim
        return verdict
    return "threshold-sensitive" if verdict in ("converged", "") else f"{verdict}, threshold-sensitive"


#: Criteria of ``scripts/fig9_ensembles.py`` shown in the comparison table, with their labels.
_SHOWN = (
    ("strip", "FTLE > 10(1+ln n)/n (default)", "strip B, FTLE > 10 (1 + ln n)/n (Figs. 7-8)"),
    ("strip", "all points", "strip B, every point"),
    ("torus", "FTLE > 10(1+ln n)/n (default)", "torus, FTLE > 10 (1 + ln n)/n"),
    ("torus", "FTLE > (1+ln n)/n", "**torus, FTLE > (1 + ln n)/n (the paper's)**"),
    ("torus", "MEGNO > 4", "torus, MEGNO > 4"),
    ("torus", "FLI > 2 ln n", "torus, FLI > 2 ln n"),
    ("torus", "census C (default FTLE, no nu lock)", "torus, census C (sea only)"),
)
_ENDS = ("0.005", "0.14")  # the keys of the two ends in the JSON


def deviation(value: float, target: float) -> str:
    """``value`` against ``target`` in percent, signed (``"+0.28 %"``)."""
    return f"{100 * (value / target - 1):+.2f} %"


def path_ends(rows: list[dict[str, Any]]) -> list[tuple[dict[str, Any], float]]:
    """The sweep rows at both ends of the path, with the caption's sigma there."""
    ordered = sorted(rows, key=lambda r: r["b2"])
    return [(ordered[0], paper.FIG9_SIGMA[0]), (ordered[-1], paper.FIG9_SIGMA[1])]


def _ensemble_table(ensembles: dict[str, Any]) -> list[str]:
    s = ensembles["settings"]
    pooled = s["replicas"] * s["points"]
    lines = [
        f"Every ensemble at the ends (`scripts/fig9_ensembles.py`, seed {s['seed']}: {s['replicas']} "
        "replicas "
        f"of {s['points']} points pooled, n = {s['steps']}; errors std/sqrt(N), confirmed by the spread of "
        "the replicas):",
        "",
        "| initial conditions, chaos criterion | sigma at b2 = 0.005 (paper 0.4787) | chaotic share "
        "| sigma at b2 = 0.14 (paper 0.8326) | chaotic share |",
        "|---|---|---|---|---|",
    ]
    found = {(r["init"], r["criterion"]): r for r in ensembles["ends"]}
    for init, criterion, label in _SHOWN:
        r = found.get((init, criterion))
        if r is None:
            continue
        cells = [
            f"{r[end]['sigma']:.4f} ± {r[end]['sigma_se']:.4f} ({r[end]['dev_percent']:+.2f} %) | "
            f"{r[end]['N'] / pooled:.3f}"
            for end in _ENDS
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    strip = [r for r in ensembles["ends"] if r["init"] == "strip"]
    closest = min(min(abs(r[end]["dev_percent"]) for end in _ENDS) for r in strip)
    window = ensembles["threshold_window"]["windows"]
    lines += [
        "",
        f"No ensemble started in the strip B comes closer than {closest:.1f} % at either end, whatever is "
        "counted as chaotic (its chaotic orbits are almost all in the global sea). On the torus the "
        "criterion is unique up to where, inside a gap, the line is drawn: after n steps regular orbits "
        "have FTLE below ~(1 + ln n)/n (a tangent that grows at most linearly) and few orbits lie "
        "between that and ~10 (1 + ln n)/n, and every fixed FTLE threshold "
        + " or ".join(f"from {lo:.1e} to {hi:.1e}" for lo, hi in window)
        + " reproduces both ends within 1.5 %; so do MEGNO > 4 and FLI > 2 ln n. The package's stricter "
        "default, 10 (1 + ln n)/n, sits just above that window and misses the low end.",
        "",
    ]
    return lines


def _difference(ensembles: dict[str, Any] | None) -> list[str]:
    if ensembles is None:
        return []
    lines = []
    for row in ensembles["path"]:
        if not any(math.isclose(row["b2"], end) for end in paper.FIG9.b2_range):
            continue
        parts = row["paper_parts"]
        locked = ", ".join(f"nu = {k}: {v['share']:.3f}" for k, v in parts["locked"].items()) or "none"
        lines.append(
            f"at b2 = {row['b2']:.3f}: sea share {parts['sea_share']:.3f} (A_sea = {parts['A_sea']:.5f} ± "
            f"{parts['A_sea_se']:.5f}), locked {locked}; A_pred = {parts['A_pred']:.5f} against "
            f"A_paper = {row['paper']['A']:.5f} ± {row['paper']['A_se']:.5f} and A_strip = "
            f"{row['strip']['A']:.5f} ± {row['strip']['A_se']:.5f}"
        )
    return [
        "**Why A differs between the ensembles.** The paper's criterion counts, besides the chaotic sea, "
        "weakly chaotic orbits (FTLE between ~1e-4 and ~1e-2) that stay locked to the normal island "
        "nu = 0 for the whole run: chaotic layers inside that island and orbits of C stuck to it. They "
        "pull sigma down and move with A ~ 0, so A_paper = f_sea A_sea + sum_nu f_nu nu (f: shares of "
        "the chaotic set, nu = w/m of Eq. AIn; `scripts/fig9_ensembles.py`, one replica): "
        + "; ".join(lines)
        + ". The sea parts of the two ensembles agree: the strip and the torus sample the same invariant "
        "sea. The island classes nu = +-1/3, +-2/3 that overlap the strip are regular (FTLE ~ 1e-5), "
        "neither criterion counts them; they enter A through the sum rule instead (Eq. (Ae) below).",
        "",
    ]


def _n_dependence(ensembles: dict[str, Any] | None) -> list[str]:
    if ensembles is None:
        return []
    parts = []
    for b2, rows in ensembles["n_dependence"].items():
        values = ", ".join(f"{r['sigma']:.4f} at n = {r['n']:.3g}" for r in rows[:: max(1, len(rows) // 3)])
        parts.append(f"b2 = {b2}: {values}")
    return [
        "The paper's sigma is a finite-n property of that set, but it moves little with n ("
        + "; ".join(parts)
        + "; torus, MEGNO > 4): the match is not an accident of n = 120000.",
        "",
    ]


def _paired(
    paper_rows: list[CheckedRow], strip_rows: list[CheckedRow]
) -> list[tuple[CheckedRow, CheckedRow | None, float]]:
    """Each row of the paper's ensemble with the strip's row at the same b2 (None if the strip sweep
    has none) and the gap A(strip) - A(paper) in combined robust standard errors (NaN without one).

    Rows are matched by b2, not by position: the two sweeps need not hold the same points in the
    same order."""
    strip = {round(c.row["b2"], 12): c for c in strip_rows}
    out = []
    for c in paper_rows:
        s = strip.get(round(c.row["b2"], 12))
        gap = math.nan
        if s is not None:
            gap = (s.row["A"] - c.row["A"]) / math.hypot(robust_stderr(s.row), robust_stderr(c.row))
        out.append((c, s, gap))
    return out


def _sensitivities(thresholds: dict[str, Any] | None) -> dict[float, float]:
    """``|A((1 + ln n)/n) - A(10 (1 + ln n)/n)|`` by b2, from ``scripts/fig9_thresholds.py``'s JSON."""
    if not thresholds:
        return {}
    return {round(r["b2"], 12): float(r["sensitivity"]) for r in thresholds["rows"]}


def _main_table(
    paper_rows: list[CheckedRow], strip_rows: list[CheckedRow], thresholds: dict[str, Any] | None = None
) -> list[str]:
    head = (
        "| b2 | domain (K = 3) | sigma | A (paper's ensemble) | stderr | robust se | threshold sensitivity "
        "| drift z | verdict | A (strip B) | robust se | strip - paper (se) | A (Eq. Ab at K = 3) |"
    )
    lines = [head, "|" + "---|" * 13]
    sensitivity = _sensitivities(thresholds)
    for c, s, gap in _paired(paper_rows, strip_rows):
        r = c.row
        moved = sensitivity.get(round(r["b2"], 12), math.nan)
        cells = [
            fixed(r["b2"], 4),
            theory.domain(MapParams(paper.K3, r["b1"], r["b2"])),
            fixed(r["lyapunov"], 4),
            fixed(r["A"]),
            general(r["A_stderr"]),
            general(r["A_stderr_robust"]),
            "n/a" if math.isnan(moved) else general(moved),
            f"{r['drift_z']:+.1f}",
            threshold_verdict(r["verdict"], moved, robust_stderr(r)) or "n/a",
        ]
        if s is None:
            cells += ["", "", ""]
        else:
            cells += [fixed(s.row["A"]), general(s.row["A_stderr_robust"]), f"{gap:+.1f}"]
        cells.append(fixed(c.theory))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _threshold_summary(paper_rows: list[CheckedRow], thresholds: dict[str, Any] | None) -> list[str]:
    """One sentence: at how many points the threshold moves A by more than its robust error."""
    sensitivity = _sensitivities(thresholds)
    pairs = [
        (sensitivity[round(c.row["b2"], 12)], robust_stderr(c.row))
        for c in paper_rows
        if round(c.row["b2"], 12) in sensitivity
    ]
    if not pairs:
        return []
    ratios = [moved / err for moved, err in pairs if err > 0]
    sensitive = sum(moved > err for moved, err in pairs)
    return [
        f"The threshold moves A by more than its robust standard error at {sensitive} of {len(pairs)} "
        f"points ({min(ratios):.1f} to {max(ratios):.1f} robust standard errors; "
        f"`{THRESHOLDS_COMMAND.format(dir='DIR')}`, {thresholds['points']} points x "
        f"n = {thresholds['steps']} each, the sweep's seeds).",
        "",
    ]


def _span(values: np.ndarray) -> str:
    """``lo-hi`` of the finite values (one number if they agree to 2 decimals)."""
    lo, hi = f"{np.nanmin(values):.2f}", f"{np.nanmax(values):.2f}"
    return lo if lo == hi else f"{lo}-{hi}"


def _convergence(paper_rows: list[CheckedRow], strip_rows: list[CheckedRow]) -> list[str]:
    lines = ["### Convergence along the path", ""]
    for label, rows in (("Paper's ensemble", paper_rows), ("Strip B", strip_rows)):
        ratio = [robust_stderr(c.row) / c.row["A_stderr"] for c in rows]
        mu = np.array([c.row["diffusion_exponent"] for c in rows])
        island = np.array(
            [theory.island_exists(MapParams(c.row["K"], c.row["b1"], c.row["b2"]), "R") for c in rows]
        )
        drifting = [c for c in rows if c.drifting]
        named = ", ".join(f"{c.row['b2']:.3f} (z = {c.row['drift_z']:+.1f})" for c in drifting) or "none"
        plain, robust = rises(rows), rises(rows, robust=True)
        mu_text = ""
        if np.any(island) and np.any(np.isfinite(mu[island])):
            mu_text = (
                f"mu = {np.nanmin(mu[island]):.2f}-{np.nanmax(mu[island]):.2f} where the right island exists"
            )
            if np.any(~island) and np.any(np.isfinite(mu[~island])):
                mu_text += f", {np.nanmin(mu[~island]):.2f}-{np.nanmax(mu[~island]):.2f} beyond"
        lines.append(
            f"- **{label}.** The robust error is {min(ratio):.1f}-{max(ratio):.1f} times the "
            "plain "
            f"one ({mu_text}: the block variance of the momentum gain grows like T^mu, mu > 1 from "
            f"near-ballistic flights of orbits stuck to the islands, 1 for normal diffusion). Drifting "
            f"(|A_n - A_n/2| > 3 standard errors, robust): {len(drifting)} of {len(rows)} points, b2 = "
            f"{named}. "
            f"A rises from one b2 to the next by more than 4 combined errors {len(plain)} times with the "
            "plain "
            f"errors, {len(robust)} times with the robust ones"
            + (
                " (" + ", ".join(f"{lo:.3f} -> {hi:.3f}: {z:.1f}" for lo, hi, z in robust) + ")."
                if robust
                else "."
            )
        )
    lines += [
        "",
        "A drifting point's A is still moving at n = 120000: |A_n - A_n/2| estimates its bias, at least as "
        "large when orbits stick for heavy-tailed times (`warpratchet.convergence`). The two ensembles "
        "differ "
        "here for a reason: the torus ensemble's chaotic orbits start uniformly on C, which the "
        "area-preserving "
        "map leaves invariant, so A_n has no transient to outgrow; the strip B is not invariant, and orbits "
        "started in it relax onto the sea's measure through sticky layers whose flights decay slowly. Where "
        "A(b2) stays rough with the robust errors, the roughness is real structure in b2 (islands and their "
        "sticky layers coming and going) or the bias of drifting points, not sampling noise.",
        "",
    ]
    return lines


def fig9_section(
    checked: dict[str, list[CheckedRow]],
    sweeps: dict[str, list[dict[str, Any]]],
    ensembles: dict[str, Any] | None,
    sweeps_dir: str,
    thresholds: dict[str, Any] | None = None,
) -> list[str]:
    """The Markdown of the Fig. 9 section (``ensembles``: the JSON of ``scripts/fig9_ensembles.py``;
    ``thresholds``: that of ``scripts/fig9_thresholds.py``)."""
    paper_rows, strip_rows = checked["fig9_paper"], checked["fig9"]
    (low, sig_lo), (high, sig_hi) = path_ends(sweeps["fig9_paper"])
    (slow, _), (shigh, _) = path_ends(sweeps["fig9"])
    se = [r["lyapunov_std"] / math.sqrt(r["chaotic_points"]) for r in (low, high)]
    ens = paper.FIG9_ENSEMBLE
    out = [
        f"## Fig. 9: K = {paper.FIG9.K}, b1 = {paper.FIG9.b1}, the paper's ensemble "
        f"({settings_line(sweeps['fig9_paper'])})",
        "",
        '**The ensemble.** The caption of Fig. 7, which Fig. 9 refers to, takes "10^4 initial conditions in '
        'the chaotic region, i.e., all having positive finite-time Lyapunov exponents", n = 120000. Read '
        "literally, initial conditions **uniform on the torus**, kept when their finite-time exponent is "
        "**positive**, i.e. above the (1 + ln n)/n of a regular orbit (`warpratchet.paper.FIG9_ENSEMBLE`: "
        f"`init={ens['init']!r}, threshold_rule={ens['threshold_rule']!r}`; `warpratchet run --init torus "
        "--threshold-rule positive`), reproduces the caption's range at both ends: "
        f"**sigma = {low['lyapunov']:.4f} ± {se[0]:.4f} at b2 = {low['b2']:.3f}** "
        f"({deviation(low['lyapunov'], sig_lo)} "
        f"from {sig_lo}) and **sigma = {high['lyapunov']:.4f} ± {se[1]:.4f} at b2 = {high['b2']:.3f}** "
        f"({deviation(high['lyapunov'], sig_hi)} from {sig_hi}), with {low['chaotic_points']} and "
        f"{high['chaotic_points']} of the {low['points']} points chaotic. The strip B of Figs. 7-8 gives "
        f"{slow['lyapunov']:.4f} and {shigh['lyapunov']:.4f} ({deviation(slow['lyapunov'], sig_lo)}, "
        f"{deviation(shigh['lyapunov'], sig_hi)}).",
        "",
    ]
    if ensembles is None:
        out += [
            "_The comparison of every ensemble and criterion is not in this report: make it with "
            f"`{ENSEMBLES_COMMAND.format(dir=sweeps_dir)}` and run the report again._",
            "",
        ]
    else:
        out += _ensemble_table(ensembles)
        out += _n_dependence(ensembles)
    gaps = [gap for _, s, gap in _paired(paper_rows, strip_rows) if s is not None]
    dev = [c.deviation for c in paper_rows]
    worst = max(paper_rows, key=lambda c: abs(c.deviation))
    out += [
        "**A depends on the ensemble.** Both ensembles along the path: A of the paper's ensemble with its "
        "plain and robust standard errors and the convergence verdict (drift z = (A_n - A_n/2) / its "
        "standard error), A of the strip ensemble, and the K = 3 closed form the paper draws (Eq. (Ab); "
        "A = 0 where no period-1 island exists at K = 3, domain `none`). No closed form exists at "
        "K = 2.99, so there is no pass/fail column. The **threshold sensitivity** is a second error of A, "
        "not a sampling one: |A with FTLE > (1 + ln n)/n - A with FTLE > 10 (1 + ln n)/n| on the same final "
        "state (both thresholds lie in the gap between regular and chaotic FTLEs, neither is wrong; "
        "`warpratchet run` on this ensemble says `reliable: false` for the same reason). Where it exceeds "
        "the robust standard error the verdict says **threshold-sensitive**: there the choice of threshold, "
        "not the sampling, limits A.",
        "",
        *(
            []
            if thresholds
            else [
                "_The threshold sensitivity is not in this report: make it with "
                f"`{THRESHOLDS_COMMAND.format(dir=sweeps_dir)}` and run the report again._",
                "",
            ]
        ),
        *_main_table(paper_rows, strip_rows, thresholds),
        "",
        *_threshold_summary(paper_rows, thresholds),
        (
            f"A of the paper's ensemble lies below the strip's at {sum(g > 0 for g in gaps)} of {len(gaps)} "
            f"points, by {min(gaps):.1f} to {max(gaps):.1f} combined robust standard errors. "
            if gaps
            else "The two ensembles share no b2, so they are not compared. "
        )
        + "Against the K = 3 formula: "
        f"largest |A(K = 2.99) - A(K = 3)| = {abs(worst.deviation):.5f} (b2 = {worst.row['b2']:.3f}), mean "
        f"deviation {np.mean(dev):+.5f}.",
        "",
        *_difference(ensembles),
        *_convergence(paper_rows, strip_rows),
    ]
    return out
