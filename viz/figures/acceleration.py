"""Figs. 7-9: the ratchet acceleration A against the Lyapunov exponent sigma along the paper's paths.

Numerics from sweeps with the paper's settings (10^4 initial conditions in B and n = 120000
steps, :data:`warpratchet.paper.POINTS`, :data:`warpratchet.paper.STEPS`), next to the closed
forms (Eqs. Aa, Ab, Amax) evaluated on a fine b2 grid whose sigma is interpolated between the
numerical points.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from warpratchet import paper, theory

from ..paths import domain_edge, fig9_domain_edge, point_on
from .canvas import Context

__all__ = ["fig7", "fig8", "fig9"]


def _columns(rows: list[dict], *keys: str) -> list[np.ndarray]:
    order = np.argsort([float(r["b2"]) for r in rows])
    return [np.array([float(rows[i][k]) for i in order]) for k in keys]


def _dense_along_path(b2: np.ndarray, sigma: np.ndarray, samples: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """A fine b2 grid on the path and sigma interpolated linearly in b2 (the abscissa of the curves)."""
    fine = np.linspace(b2.min(), b2.max(), samples)
    return fine, np.interp(fine, b2, sigma)


def _numeric_points(
    ax, sigma, a, err, label: str, color: str = "black", marker: str = "o", ms: float = 5
) -> None:
    ax.errorbar(
        sigma,
        a,
        yerr=err,
        fmt=marker,
        mfc="none",
        mec=color,
        ecolor=color,
        ms=ms,
        lw=0.8,
        label=label,
        zorder=3 if color == "black" else 2,
    )


def _a_against_sigma(
    ctx: Context,
    ax,
    name: str,
    curves: dict[str, tuple[Callable[[float], float], dict]],
    numerics: str,
    limit: tuple[float, str] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Sweep ``name`` as circles with error bars and each closed form as a line; returns ``(b2, sigma)``.

    ``curves`` maps a legend label to ``(A as a function of b2, line style)``; ``limit`` is an
    ``(A, legend label)`` drawn as a dotted horizontal line, listed between curves and numerics.
    """
    b2, sigma, a, err = _columns(ctx.sweep(name), "b2", "lyapunov", "A", "A_stderr")
    fine, fine_sigma = _dense_along_path(b2, sigma)
    for label, (closed, style) in curves.items():
        ax.plot(fine_sigma, [closed(v) for v in fine], label=label, **style)
    if limit is not None:
        ax.axhline(limit[0], color="gray", lw=0.8, ls=":", label=limit[1])
    _numeric_points(ax, sigma, a, err, numerics)
    return b2, sigma


def _labels(ax, path: paper.Path, legend: str, where: str) -> None:
    """Axis labels, legend, and a title saying ``where`` the path runs and its range of b2."""
    low, high = path.b2_range
    ax.set_xlabel(r"Lyapunov exponent $\sigma$ (per kick)")
    ax.set_ylabel(r"ratchet acceleration $A$ (momentum per kick)")
    ax.legend(loc=legend, fontsize=8)
    ax.set_title(rf"{where}, ${low}\leq b_2\leq {high}$", fontsize=9)


NUMERICS = r"numerics, $\langle (p_n-p_0)/n\rangle$"
SOLID = {"color": "C0", "lw": 1.5}


def fig7(ctx: Context) -> None:
    s = ctx.settings
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.3))
    inset = ax.inset_axes([0.5, 0.5, 0.46, 0.44])
    curves = {
        "Eq. (Amax), corrected": (theory.acceleration_on_maximal_path, SOLID),
        "Eq. (Amax) as printed": (
            theory.acceleration_on_maximal_path_as_printed,
            {"color": "C1", "lw": 1.2, "ls": "--"},
        ),
    }
    for axes, name in ((ax, "fig7"), (inset, "fig7_inset")):
        _a_against_sigma(ctx, axes, name, curves, NUMERICS)
    inset.axhline(theory.LIMIT_MAXIMAL_PATH, color="gray", lw=0.8, ls=":")
    inset.tick_params(labelsize=7)
    low, high = paper.FIG7_INSET.b2_range
    inset.set_title(rf"inset: ${low}\leq b_2\leq {high}$", fontsize=7)
    _labels(ax, paper.FIG7, "lower left", r"$K=3$, maximal path $b_1(b_2)$")
    ctx.save(
        fig,
        "fig7",
        f"""
        Fig. 7. A against sigma on the maximal path, Eq. (b2max): circles, <(p_n - p_0)/n> over the chaotic
        orbits of {s.points} initial conditions in B, n = {s.steps} (error bars: standard errors, smaller than
        the circles); sigma on the curves is interpolated between the numerical points. Solid: A of Eq. (Aa)
        on the path, i.e. the corrected Eq. (Amax) (5-6r)^2 / (20(5-4b2-2r)), r = [5b2(1-b2)]^(1/2). Dashed:
        Eq. (Amax) as printed in the paper (r instead of 2r in the denominator), which the numerics rule out.
        Inset: small b2, where A approaches 1/4 (dotted, Eq. Am).
        """,
    )


def fig8(ctx: Context) -> None:
    s = ctx.settings
    path = paper.FIG8
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.0))

    def closed(b2: float) -> float:
        return theory.acceleration(point_on(path, b2))

    limit = theory.limit_on_line(path.a)
    b2, sigma = _a_against_sigma(
        ctx,
        ax,
        "fig8",
        {"Eqs. (Aa) (domain LR), (Ab) (domain R)": (closed, SOLID)},
        NUMERICS,
        limit=(limit, f"limit $b_2\\to 0$: {limit:g}, Eq. (Ama)"),
    )
    # Where the path leaves domain LR (the left island disappears, Eq. lai) and enters R.
    if theory.domain(point_on(path, b2.max())) != "LR":
        edge_b2 = domain_edge(lambda v: theory.domain(point_on(path, v)) == "LR", b2.min(), b2.max())
        edge = float(np.interp(edge_b2, b2, sigma))
        ax.axvline(edge, color="gray", lw=0.8, ls="--")
        ax.annotate(
            rf"LR $\leftarrow$ | $\rightarrow$ R ($b_2={edge_b2:.4f}$)",
            (edge, 0.5),
            xycoords=("data", "axes fraction"),
            ha="center",
            fontsize=8,
            backgroundcolor="white",
        )
    _labels(ax, path, "lower left", r"$K=3$, path $b_1=3b_2$")
    ctx.save(
        fig,
        "fig8",
        f"""
        Fig. 8. A against sigma on the path b1 = 3 b2 (crossing domains LR and R of Fig. 3): circles, numerics
        as in Fig. 7 ({s.points} orbits, n = {s.steps}); solid, Eqs. (Aa) and (Ab); dotted, the limit 1/8 of
        Eq. (Ama) with a = 1/3. Dashed vertical: where the path leaves domain LR for R (the left island ceases
        to exist, Eq. lai).
        """,
    )


def _error(rows: list[dict]) -> np.ndarray:
    """Error bars: the robust standard error where the sweep has one, never below the plain one."""
    plain, robust = _columns(rows, "A_stderr", "A_stderr_robust")
    return np.fmax(plain, robust)  # fmax: a NaN robust error (older sweep files) leaves the plain one


def fig9(ctx: Context) -> None:
    s = ctx.settings
    path = paper.FIG9
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.0))

    def closed(b2: float) -> float:  # the paper's solid line: Eq. (Ab) at K = 3, not at the path's K
        return theory.acceleration(point_on(path, b2, K=paper.K3))

    # Both ensembles at the sigma of the paper's (the abscissa the caption's range refers to).
    paper_rows, strip_rows = ctx.sweep("fig9_paper"), ctx.sweep("fig9")
    b2, sigma, a = _columns(paper_rows, "b2", "lyapunov", "A")
    fine, fine_sigma = _dense_along_path(b2, sigma)
    ax.plot(fine_sigma, [closed(v) for v in fine], label="Eq. (Ab) at $K=3$", **SOLID)
    strip_b2, strip_a = _columns(strip_rows, "b2", "A")
    strip_sigma = np.interp(strip_b2, b2, sigma)
    _numeric_points(
        ax,
        strip_sigma,
        strip_a,
        _error(strip_rows),
        r"strip B (FTLE $>10(1+\ln n)/n$), at the same $b_2$",
        color="gray",
        marker="s",
        ms=4,
    )
    _numeric_points(
        ax, sigma, a, _error(paper_rows), rf"torus, FTLE $>(1+\ln n)/n$ (the paper's), $K={path.K}$"
    )
    # Points whose A_n still drifts between n/2 and n, either ensemble (their verdict).
    cross_x, cross_y = [], []
    for rows, x, y in ((paper_rows, sigma, a), (strip_rows, strip_sigma, strip_a)):
        drifting = [r["verdict"] == "drifting" for r in sorted(rows, key=lambda r: r["b2"])]
        cross_x += list(x[drifting])
        cross_y += list(y[drifting])
    if cross_x:
        ax.plot(cross_x, cross_y, "x", color="C3", ms=7, label=r"drifting: $|A_n-A_{n/2}|>3$ se")
    _labels(ax, path, "upper right", rf"$K={path.K}$, $b_1={path.b1}$")
    ctx.save(
        fig,
        "fig9",
        f"""
        Fig. 9. A against sigma at K = {path.K} on the path b1 = {path.b1}. Circles: the paper's
        ensemble, {s.points} initial conditions uniform on the torus, chaotic when the FTLE exceeds
        (1 + ln n)/n, n = {s.steps}; sigma is their mean FTLE, {sigma.min():.4f} to {sigma.max():.4f}
        (the paper: {paper.FIG9_SIGMA[0]} < sigma < {paper.FIG9_SIGMA[1]}). Squares: A of the strip
        ensemble of Figs. 7-8 at the same b2 (it leaves out orbits locked to the normal island, which
        the paper's ensemble counts at A ~ 0). Error bars: the robust standard error (batch means over
        time). Crosses: points whose A still drifts between n/2 and n by more than 3 standard errors
        ({len(cross_x)} of them).
        Solid: the closed form at K = 3, Eq. (Ab) while the right island exists (b2 <
        {fig9_domain_edge(paper.K3):.4f}; the paper says the whole path is in domain R) and A = 0 beyond.
        """,
    )
