"""The Markdown tables of the validation report: rows of Figs. 7-9, limits and Lyapunov ranges."""

from __future__ import annotations

from typing import Any

from warpratchet import paper, theory

from .checks import CheckedRow, sigma_range

__all__ = ["fixed", "general", "table", "settings_line", "limits_section", "lyapunov_section"]


def fixed(value: float, digits: int = 6) -> str:
    return f"{value:.{digits}f}"


def general(value: float, digits: int = 2) -> str:
    return f"{value:.{digits}g}"


def table(checked: list[CheckedRow], printed: bool = False, verdict: bool = True) -> list[str]:
    head = [
        "b1",
        "b2",
        "domain",
        "sigma",
        "A (numerics)",
        "stderr",
        "robust se",
        "A (closed form)",
        "z",
        "beta",
    ]
    if printed:
        head += ["Eq. (Amax) as printed", "z (printed)"]
    head.append("result" if verdict else "note")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in checked:
        r = c.row
        cells = [
            fixed(r["b1"]),
            fixed(r["b2"]),
            r["domain"],
            fixed(r["lyapunov"], 4),
            fixed(r["A"]),
            general(r["A_stderr"]),
            general(r["A_stderr_robust"]),
            fixed(c.theory),
            f"{c.z:+.2f}",
            general(c.bias.bound),
        ]
        if printed:
            a_printed = theory.acceleration_on_maximal_path_as_printed(r["b2"])
            cells += [fixed(a_printed), f"{(r['A'] - a_printed) / r['A_stderr']:+.1f}"]
        if verdict:
            cells.append(c.result)
        else:
            cells.append("K = 2.99 vs K = 3 formula")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def settings_line(rows: list[dict[str, Any]]) -> str:
    r = rows[0]
    rule = ", FTLE > (1 + ln n)/n" if r["threshold_rule"] == "positive" else ""
    return (
        f"{len(rows)} points, {r['points']} initial conditions ({r['init']}{rule}) x n = {r['steps']} steps "
        "each"
    )


def limits_section(checked: dict[str, list[CheckedRow]]) -> list[str]:
    lines = [
        "## Limits along the paths",
        "",
        "As b2 -> 0, A -> 1/4 on the maximal path (Eq. Am) and A -> (1 - a)/(4(1 + a)) = 1/8 on b1 = 3 b2 "
        "(Eq. Ama, a = 1/3). The points with the smallest b2:",
        "",
        "| path | b2 | sigma | A (numerics) | stderr | A (closed form) | limit | limit - A (numerics) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    paths = (
        ("maximal (Fig. 7 inset)", checked["fig7_inset"], theory.LIMIT_MAXIMAL_PATH),
        ("b1 = 3 b2 (Fig. 8)", checked["fig8"], theory.limit_on_line(paper.FIG8.a)),
    )
    for label, rows, limit in paths:
        for c in rows[:3]:
            r = c.row
            lines.append(
                f"| {label} | {fixed(r['b2'], 5)} | {fixed(r['lyapunov'], 4)} | {fixed(r['A'])} | "
                f"{general(r['A_stderr'])} | "
                f"{fixed(c.theory)} | {limit:g} | {limit - r['A']:+.5f} |"
            )
    lines += [
        "",
        "Both limits are approached from below as sigma -> 0, the closed forms and the numerics together: "
        "the largest ratchet acceleration sits in the limit of arbitrarily weak chaos.",
        "",
    ]
    return lines


def lyapunov_section(
    sweeps: dict[str, list[dict[str, Any]]], checked: dict[str, list[CheckedRow]]
) -> list[str]:
    lines = [
        "## Lyapunov exponents",
        "",
        "| sweep | sigma min | sigma max | smallest per-orbit FTLE counted chaotic | chaotic fraction min |",
        "|---|---|---|---|---|",
    ]
    names = [n for n in ("fig7", "fig7_inset", "fig8", "fig9", "fig9_paper", "fig6") if n in sweeps]
    for name in names:
        rows = sweeps[name]
        lo, hi = sigma_range(rows)
        lines.append(
            f"| {name} | {lo:.4f} | {hi:.4f} | {min(r['lyapunov_min'] for r in rows):.4f} | "
            f"{min(r['chaotic_fraction'] for r in rows):.4f} |"
        )
    lo, hi = sigma_range(sweeps["fig9_paper"])
    strip_lo, strip_hi = sigma_range(sweeps["fig9"])
    low, high = paper.FIG9.b2_range
    lines += [
        "",
        f"Fig. 9 (K = {paper.FIG9.K}, b1 = {paper.FIG9.b1}, {low} <= b2 <= {high}): measured {lo:.4f} "
        f"<= sigma <= {hi:.4f} with the paper's ensemble (`fig9_paper`: torus, FTLE > (1 + ln n)/n), "
        f"{strip_lo:.4f} <= sigma <= {strip_hi:.4f} with the strip B (`fig9`); the caption of Fig. 9 gives "
        f"{paper.FIG9_SIGMA[0]} < sigma < {paper.FIG9_SIGMA[1]}.",
        "",
    ]
    return lines
