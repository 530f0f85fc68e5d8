"""Figs. 10-12: the regions B, B^(1), B^(2) and C = B u MB u M^2 B (Eq. Cs) at K = 3.

Drawn from the membership tests of :mod:`warpratchet.regions` on a pixel grid of the torus.
"""

from __future__ import annotations

import numpy as np

from warpratchet import paper, regions
from warpratchet.params import MapParams

from .canvas import Context, mark_islands, torus_axes

__all__ = ["REGION_COLORS", "regions_vertices", "fig10", "fig11", "fig12"]

REGION_COLORS = {
    "B": (0.20, 0.35, 0.85, 1.0),
    "B1": (0.95, 0.55, 0.10, 1.0),
    "B2": (0.80, 0.15, 0.15, 1.0),
    "overlap": (0.10, 0.60, 0.20, 1.0),
}


def _region_masks(params: MapParams, pixels: int) -> dict[str, np.ndarray]:
    """Membership images of B, B^(1), B^(2) on the torus, each of shape ``(pixels, pixels)``."""
    axis = (np.arange(pixels) + 0.5) / pixels
    x, p = np.meshgrid(axis, axis, indexing="xy")
    return {
        "B": np.asarray(regions.in_strip(params, x, p), dtype=bool),
        "B1": np.asarray(regions.in_B1(params, x, p), dtype=bool),
        "B2": np.asarray(regions.in_B2(params, x, p), dtype=bool),
    }


def regions_vertices(params: MapParams) -> np.ndarray:
    """Vertices of B^(2), shape ``(4, 2)``, from :func:`warpratchet.regions.B2_vertices`."""
    return regions.B2_vertices(params)


def _show_mask(ax, mask: np.ndarray, color) -> None:
    rgba = np.zeros(mask.shape + (4,))
    rgba[mask] = color
    ax.imshow(rgba, origin="lower", extent=(0.0, 1.0, 0.0, 1.0), interpolation="nearest")


def fig10(ctx: Context) -> None:
    params = paper.FIG10
    masks = _region_masks(params, ctx.settings.region_pixels)
    fig, axes = ctx.plt.subplots(3, 1, figsize=(4.0, 11.0))
    titles = {
        "B": r"(a) strip $B$, Eq. (B)",
        "B1": r"(b) $\bar B^{(1)}=\bar M B - B\cap\bar M B$, Eq. (B1e)",
        "B2": r"(c) $B^{(2)}=\bar M\bar B^{(1)}$, Eq. (B2e)",
    }
    for ax, key in zip(axes, ("B", "B1", "B2"), strict=True):
        _show_mask(ax, masks[key], REGION_COLORS[key])
        torus_axes(ax, titles[key])
    # Vertices of B^(2), Eqs. (xj)-(pj): the images of the corners of B^(1) (Appendix C).
    for j, (xv, pv) in enumerate(regions_vertices(params), start=1):
        axes[2].plot([xv], [pv], "k.", ms=5, clip_on=False)
        axes[2].annotate(
            str(j), (xv, pv), xytext=(4, -9 if j < 3 else 3), textcoords="offset points", fontsize=8
        )
    ctx.save(
        fig,
        "fig10",
        f"""
        Fig. 10. K = 3, b1 = {params.b1}, b2 = {params.b2}: (a) the strip B; (b) the parallelogram B^(1) of
        slope 1 (Eq. B1e); (c) B^(2), the parallelogram of slope 2 folded into the torus (Eq. B2e), with its
        vertices j = 1-4 of Eqs. (xj)-(pj); membership tests of warpratchet.regions on a
        {ctx.settings.region_pixels}^2 pixel grid.
        """,
    )


def _region_union(ctx: Context, params: MapParams, name: str, caption: str) -> None:
    masks = _region_masks(params, ctx.settings.region_pixels)
    fig, ax = ctx.plt.subplots(figsize=(7.5, 6.6))
    for key in ("B", "B1", "B2"):
        _show_mask(ax, masks[key], REGION_COLORS[key])
    _show_mask(ax, masks["B"] & masks["B2"], REGION_COLORS["overlap"])
    mark_islands(ax, params, color="black")
    torus_axes(ax, rf"$C=B\cup\bar B^{{(1)}}\cup B^{{(2)}}$, $K=3$, $b_1={params.b1}$, $b_2={params.b2}$")
    from matplotlib.patches import Patch  # matplotlib is optional: imported only when drawing

    labels = {"B": "$B$", "B1": r"$\bar B^{(1)}$", "B2": "$B^{(2)}$", "overlap": r"$B\cap B^{(2)}$"}
    handles = [Patch(facecolor=REGION_COLORS[k], edgecolor="none", label=text) for k, text in labels.items()]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    ctx.save(fig, name, caption)


def fig11(ctx: Context) -> None:
    p = paper.FIG11
    _region_union(
        ctx,
        p,
        "fig11",
        f"""
        Fig. 11. The region C = B u B^(1) u B^(2) (Eq. Cs) for K = 3, b1 = {p.b1}, b2 = {p.b2}; the overlaps B
        n B^(2) in green. Both islands L and R exist (black dots: modes of Eq. xp); white: the islands and the
        normal island between them.
        """,
    )


def fig12(ctx: Context) -> None:
    p = paper.FIG12
    _region_union(
        ctx,
        p,
        "fig12",
        f"Fig. 12. The region C = B u B^(1) u B^(2) for K = 3, b1 = {p.b1}, b2 = {p.b2}, overlaps "
        "B n B^(2) in green. Only the right island R exists (domain R of Fig. 3).",
    )
