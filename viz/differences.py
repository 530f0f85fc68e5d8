"""The last section of the validation report: where the numbers and the paper differ."""

from __future__ import annotations

from typing import Any

from warpratchet import paper, theory
from warpratchet.params import MapParams

from .checks import Z_MAX, CheckedRow, rises, robust_stderr, sigma_range, sigma_stderr
from .paths import fig9_domain_edge

__all__ = ["differences_section"]


def differences_section(
    checked: dict[str, list[CheckedRow]],
    printed_rejected: list[CheckedRow],
    fig7_all: list[CheckedRow],
    identity: float,
    misprint_at: float,
    misprint_rel: float,
    sweeps: dict[str, list[dict[str, Any]]],
) -> list[str]:
    items: list[str] = []
    # 1. Eq. (Amax): the point where the numerics speak most clearly against the printed form.
    z_printed = [
        (c.row["A"] - theory.acceleration_on_maximal_path_as_printed(c.row["b2"])) / c.row["A_stderr"]
        for c in fig7_all
    ]
    z_at, at = max(zip(z_printed, fig7_all, strict=True), key=lambda item: abs(item[0]))
    at_printed = theory.acceleration_on_maximal_path_as_printed(at.row["b2"])
    items.append(
        "**Eq. (Amax) is misprinted.** The paper prints A(b2) = {5 - 6r}^2 / (20{5 - 4b2 - r}), "
        "r = [5b2(1 - b2)]^(1/2). Substituting Eq. (b2max) into Eq. (Aa) and reducing with "
        "r^2 = 5b2(1 - b2) gives (5 - 6r)^2 / (20(5 - 4b2 - 2r)): 2r, not r, in the denominator. "
        f"Evidence: (i) the corrected form equals Eq. (Aa) evaluated on the path to {identity:.1e} at every "
        f"point of Fig. 7; (ii) the printed form is {100 * misprint_rel:.1f}% low at b2 = {misprint_at} "
        f"(printed {theory.acceleration_on_maximal_path_as_printed(misprint_at):.5f}, corrected "
        f"{theory.acceleration_on_maximal_path(misprint_at):.5f}); (iii) at b2 = {at.row['b2']:.5f} the "
        f"numerics give A = {at.row['A']:.5f} +- {at.row['A_stderr']:.1g} against {at.theory:.5f} "
        f"corrected (z = {at.z:+.1f}) and {at_printed:.5f} printed (z = {z_at:+.0f}); over the whole "
        f"figure the numerics reject the printed form at {len(printed_rejected)} of {len(fig7_all)} points "
        f"(|z| up to {max(map(abs, z_printed)):.0f}) and accept the corrected one at all. Both forms agree "
        "at the end points (1/4 as b2 -> 0, 0 at b2 = 1/6), so the limit of Eq. (Am) and the paper's "
        "conclusions stand; Fig. 7 draws both curves."
    )
    # 2. The Fig. 9 path and domain R.
    paper_rows = checked["fig9_paper"]
    outside = [
        c.row for c in paper_rows if theory.domain(MapParams(paper.K3, c.row["b1"], c.row["b2"])) != "R"
    ]
    if outside:
        low, high = paper.FIG9.b2_range
        where = ", ".join(f"{r['b2']:.4f}" for r in outside)
        found = ", ".join(f"{r['A']:.5f} +- {robust_stderr(r):.1g}" for r in outside)
        items.append(
            f"**The Fig. 9 path leaves domain R.** The caption says the path b1 = {paper.FIG9.b1}, "
            f'{low} <= b2 <= {high} "lies entirely in domain R". By Eq. (lai) the right island needs '
            f"b1 < F(b2), which fails for b2 > {fig9_domain_edge(paper.K3):.4f} at K = 3 (b2 > "
            f"{fig9_domain_edge(paper.FIG9.K):.4f} at K = {paper.FIG9.K}): {len(outside)} of the "
            f"{len(paper_rows)} points (b2 = {where}) have no period-1 island, where the closed form "
            f"is A = 0 (case c of Sec. IV), not Eq. (Ab). The K = {paper.FIG9.K} numerics there are not "
            f"zero (paper's ensemble): A = {found}. By the sum rule, Eq. (sum), an accelerating island that "
            'is not of period 1 must exist there: the island census finds the nu = -1/3 chain ("Where '
            'Eq. (Ae) stops describing the census").'
        )
    # 3. The Lyapunov range of Fig. 9: answered by the paper's ensemble.
    lo, hi = sigma_range(sweeps["fig9_paper"])
    strip_lo, strip_hi = sigma_range(sweeps["fig9"])
    fig9_std = max(r["lyapunov_std"] for r in sweeps["fig9"])
    k3_std = max(r["lyapunov_std"] for r in sweeps["fig7"] + sweeps["fig8"])
    items.append(
        f"**Lyapunov range of Fig. 9: answered.** The paper's ensemble (initial conditions uniform on the "
        "torus, chaotic when the FTLE exceeds (1 + ln n)/n, `warpratchet.paper.FIG9_ENSEMBLE`) gives "
        f"{lo:.4f} <= sigma <= {hi:.4f} against the caption's {paper.FIG9_SIGMA[0]} < sigma < "
        f"{paper.FIG9_SIGMA[1]} ({100 * (lo / paper.FIG9_SIGMA[0] - 1):+.2f} % and "
        f"{100 * (hi / paper.FIG9_SIGMA[1] - 1):+.2f} %; standard error of each sigma "
        f"{max(sigma_stderr(r) for r in sweeps['fig9_paper']):.1e} at most). The strip B of Figs. 7-8 gives "
        f"{strip_lo:.4f} ... {strip_hi:.4f}: it starts in the chaotic sea, while the torus criterion also "
        "counts weakly chaotic orbits locked to the normal island, which pull sigma down (FTLE spread up "
        f"to {fig9_std:.3f} at K = 2.99 against {k3_std:.3f} at K = 3 on Figs. 7-8). Which ensemble, and "
        "why unique up to where the line is drawn inside a gap of FTLEs: the Fig. 9 section."
    )
    # 4. Fig. 9: K = 2.99 against the K = 3 formula, how smooth A(b2) is there, and convergence.
    fig9_max = max(paper_rows, key=lambda c: abs(c.deviation))
    a_peak = max(abs(c.row["A"]) for c in paper_rows)
    plain, robust = rises(paper_rows), rises(paper_rows, robust=True)
    strip_plain, strip_robust = rises(checked["fig9"]), rises(checked["fig9"], robust=True)
    rises_k3 = sum(len(rises(checked[name])) for name in ("fig7", "fig7_inset", "fig8"))
    drifting = [c for name in ("fig9_paper", "fig9") for c in checked[name] if c.drifting]
    text = (
        f"**Fig. 9 compares K = {paper.FIG9.K} numerics with a K = 3 formula.** The deviation is real, "
        f"not noise: up to {fig9_max.deviation:+.5f} "
        f"({fig9_max.deviation / robust_stderr(fig9_max.row):+.0f} "
        f"robust standard errors) at b2 = {fig9_max.row['b2']:.3f} (paper's ensemble), "
        f"{100 * abs(fig9_max.deviation) / a_peak:.0f}% of the largest A on the path ({a_peak:.4f}). The "
        "paper claims no more than that the K = 3 curve stays close (continuity in K); the table shows how "
        f"close. A(b2) at K = {paper.FIG9.K} is not monotonic: with the paper's ensemble it rises between "
        f"neighbouring points {len(plain)} times by more than {Z_MAX:g} combined plain standard errors and "
        f"{len(robust)} times by more than {Z_MAX:g} robust ones (the strip ensemble: {len(strip_plain)} and "
        f"{len(strip_robust)} times), where the K = 3 formula decreases (on the K = 3 paths of Figs. 7-8: "
        f"{rises_k3} times)."
    )
    if drifting:
        named = ", ".join(
            f"b2 = {c.row['b2']:.3f} ({c.row['init']}, z = {c.row['drift_z']:+.1f})" for c in drifting
        )
        text += (
            f" {len(drifting)} points have not converged at n = {paper_rows[0].row['steps']}: {named}; "
            "their A still moves between n/2 and n by more than 3 robust standard errors."
        )
    text += (
        " What remains rough with the robust errors is structure in b2 (islands of higher period and "
        "their sticky layers coming and going) or the bias of drifting points, not sampling noise."
    )
    items.append(text)
    # 5. Fig. 8 at small sigma.
    small = checked["fig8"][0]
    items.append(
        f"**Fig. 8 at small sigma** (agreement, stated for completeness). The caption says A ~ "
        f"{paper.FIG8_SMALL_SIGMA_A} for small sigma, close to the limit 1/8. At the smallest b2 = "
        f"{small.row['b2']:.3f} (sigma = {small.row['lyapunov']:.3f}) we find A = {small.row['A']:.5f} +- "
        f"{small.row['A_stderr']:.1g} (closed form {small.theory:.5f}): consistent with the caption; the "
        "limit "
        "1/8 itself is reached only as b2 -> 0."
    )
    # 6. Orbits from B that the FTLE threshold counts as regular.
    k3 = checked["fig7"] + checked["fig7_inset"] + checked["fig8"]
    regular = [c.row for c in k3 if c.row["chaotic_fraction"] < 1.0]
    if regular:
        worst = min(regular, key=lambda r: r["chaotic_fraction"])
        items.append(
            "**Not every orbit started in B looks chaotic after n steps.** The paper reports all "
            f"finite-time exponents of orbits from B strictly positive. At {len(regular)} of the {len(k3)} "
            f"K = 3 points a few orbits (at most {round((1 - worst['chaotic_fraction']) * worst['points'])} "
            f"of {worst['points']}, at b2 = {worst['b2']:.5f}) fall below the FTLE threshold "
            f"{worst['threshold']:.1e} (presumably orbits stuck near an island edge for much of the run); "
            "they are left "
            "out of the mean, and beta accounts for them."
        )
    else:
        items.append(
            "**Every orbit started in B is chaotic**, as the paper reports: at every K = 3 point all "
            "finite-time Lyapunov exponents lie above the chaos threshold."
        )
    lines = ["## Where the numbers and the paper differ", ""]
    lines += [f"{i}. {item}" for i, item in enumerate(items, start=1)]
    lines.append("")
    return lines
