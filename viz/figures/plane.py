"""Figs. 3, 5 and 6: the (b1, b2) plane at K = 3.

Fig. 3, the existence domains of the period-1 islands (Eq. lai), and Fig. 5, |A| (Eqs. Aa, Ab,
b2max), from closed forms only; Fig. 6, the Lyapunov exponent over a coarse grid (a sweep).
"""

from __future__ import annotations

import math

import numpy as np

from warpratchet import paper, theory
from warpratchet.params import MapParams

from .canvas import Context, plane_axes
from .sweeps import grid_axis

__all__ = ["abs_acceleration_grid", "fig3", "fig5", "fig6"]


def _domain_curve(K: float = paper.K3, samples: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """``b2 = F(b1)`` of Eq. (lai) for ``0 <= b1 <= b_*`` where ``F(b_*) = 0``."""
    # K b^2 + (1 - 2K) b + K - 2 = 0, smaller root: where the curve meets the b1 axis.
    disc = (1.0 - 2.0 * K) ** 2 - 4.0 * K * (K - 2.0)
    b_star = ((2.0 * K - 1.0) - math.sqrt(disc)) / (2.0 * K)
    b1 = np.linspace(0.0, b_star, samples)
    return b1, np.array([theory.F(b, K) for b in b1])


#: A point inside each domain of Fig. 3 (``theory.domain`` places it there), where its name is written.
DOMAIN_LABELS = {"LR": (0.08, 0.08), "L": (0.05, 0.3), "R": (0.3, 0.05)}


def _draw_domain_lines(ax, color: str = "black", lw: float = 1.0, named: bool = False) -> None:
    """The domain lines of Fig. 3 (Eq. lai); ``named``: with a legend entry and each domain's name."""
    b1, b2 = _domain_curve()
    label = "domain lines of Fig. 3, Eq. (lai)" if named else None
    ax.plot(b1, b2, color=color, lw=lw, label=label)
    ax.plot(b2, b1, color=color, lw=lw)
    if named:
        from matplotlib.patheffects import withStroke

        outline = [withStroke(linewidth=2, foreground="black")]  # readable on light and dark cells
        for text, (x, y) in DOMAIN_LABELS.items():
            ax.text(x, y, text, fontsize=12, ha="center", va="center", color=color, path_effects=outline)
        style = {"ha": "center", "va": "center", "color": color, "path_effects": outline}
        ax.text(0.38, 0.38, "no islands", fontsize=9, **style)


def _maximal_path_curve(samples: int = 400) -> tuple[np.ndarray, np.ndarray]:
    b2 = np.linspace(1e-7, paper.MAXIMAL_PATH_END, samples)
    return np.array([theory.b1_on_maximal_path(v) for v in b2]), b2


def fig3(ctx: Context) -> None:
    fig, ax = ctx.plt.subplots(figsize=(5.5, 6.2))
    b1, b2 = _domain_curve()
    ax.plot(b1, b2, color="C0", lw=1.5, label=r"$b_2=F(b_1)$ (left island boundary)")
    ax.plot(b2, b1, color="C3", lw=1.5, label=r"$b_1=F(b_2)$ (right island boundary)")
    # Label each domain at a point that theory.domain places in it.
    for text, (x, y) in DOMAIN_LABELS.items():
        assert theory.domain(MapParams(paper.K3, x, y)) == text
        ax.text(x, y, text, ha="center", va="center", fontsize=14)
    ax.text(0.38, 0.38, "no islands", ha="center", va="center", fontsize=10)
    plane_axes(ax, "$K=3$: existence domains of the period-1 islands", legend_size=8)
    ctx.save(
        fig,
        "fig3",
        "Fig. 3. The curves b2 = F(b1) and b1 = F(b2), Eq. (lai) at K = 3. Domain LR: both islands "
        "(Eq. ca); L or R: only that island (Eq. cb); elsewhere none (Eq. cc).",
    )


def abs_acceleration_grid(samples: int) -> tuple[np.ndarray, np.ndarray]:
    """|A| of Eqs. (Aa)/(Ab) (and A(b2,b1) = -A(b1,b2)) on a ``samples^2`` grid of cell centres."""
    axis = (np.arange(samples) + 0.5) * (paper.PLANE_EXTENT / samples)
    values = np.array([[abs(theory.acceleration(MapParams(paper.K3, b1, b2))) for b1 in axis] for b2 in axis])
    return axis, values


def _colour_map(ax, fig, edges: np.ndarray, values: np.ndarray, cmap: str, label: str, **kwargs) -> None:
    """``values[b2, b1]`` over the plane, cells bounded by ``edges`` on both axes, with a colour bar."""
    mesh = ax.pcolormesh(edges, edges, values, cmap=cmap, shading="flat", **kwargs)
    fig.colorbar(mesh, ax=ax, shrink=0.8, label=label)


def fig5(ctx: Context) -> None:
    axis, values = abs_acceleration_grid(120 if ctx.settings.quick else 300)
    fig, ax = ctx.plt.subplots(figsize=(6.0, 6.4))
    h = paper.PLANE_EXTENT / axis.size
    edges = np.append(axis - h / 2, paper.PLANE_EXTENT)
    _colour_map(ax, fig, edges, values, "viridis", r"$|A|$ (momentum per kick)", rasterized=True)
    _draw_domain_lines(ax, color="white", lw=0.8)
    b1, b2 = _maximal_path_curve()
    ax.plot(b1, b2, color="red", lw=2.5, label=r"maximal path $b_1(b_2)$, Eq. (b2max), $A>0$")
    ax.plot(b2, b1, color="red", lw=2.0, ls="--", label=r"mirror path $b_2(b_1)$, $A<0$")
    plane_axes(ax, "$K=3$: $|A|$ from the closed forms", legend_size=7)
    ctx.save(
        fig,
        "fig5",
        """
        Fig. 5. |A| over the (b1, b2) plane at K = 3 from Eqs. (Aa), (Ab) and A(b2, b1) = -A(b1, b2); A = 0
        where no island exists. White: the domain lines of Fig. 3. Thick red: the maximal path b1(b2), Eq.
        (b2max); dashed: its mirror b2(b1), on which A < 0.
        """,
    )


def fig6(ctx: Context) -> None:
    s = ctx.settings
    rows = ctx.sweep("fig6")
    axis = grid_axis(s)
    sigma = np.full((axis.size, axis.size), np.nan)
    index = {round(v, 12): i for i, v in enumerate(axis)}
    for r in rows:
        sigma[index[round(float(r["b2"]), 12)], index[round(float(r["b1"]), 12)]] = r["lyapunov"]
    # Relative standard error of each grid value: FTLE spread over orbits / sqrt(orbits).
    worst = max(r["lyapunov_std"] / math.sqrt(r["chaotic_points"]) / r["lyapunov"] for r in rows)
    fig, ax = ctx.plt.subplots(figsize=(6.0, 6.4))
    edges = np.linspace(0.0, paper.PLANE_EXTENT, axis.size + 1)
    _colour_map(ax, fig, edges, np.ma.masked_invalid(sigma), "magma", r"$\sigma$ (per kick)")
    _draw_domain_lines(ax, color="cyan", lw=0.8, named=True)
    plane_axes(ax, r"$K=3$: Lyapunov exponent $\sigma$ of the chaotic region", legend_size=7)
    ctx.save(
        fig,
        "fig6",
        f"""
        Fig. 6. Lyapunov exponent sigma (mean finite-time exponent of the chaotic orbits) on a {s.grid_side} x
        {s.grid_side} grid of cell centres, each from {s.grid_points} orbits started in B and {s.grid_steps}
        steps (fewer than the paper's 10^4 x 120000, to fit the time budget; the standard error of each sigma
        is below {100 * worst:.2f}% of sigma). Cyan: domain lines of Fig. 3 and the domains' names (LR: both
        islands; L, R: one; none beyond). sigma -> 0 as b1, b2 -> 0.
        """,
    )
