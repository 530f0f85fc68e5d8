"""Figs. 1, 2 and 4: orbits of an ensemble started uniformly in the strip B, on the torus.

The orbits are accumulated on a pixel grid of the torus; the period-1 accelerator modes
``x0 = c - w/K, p0 = 0`` (Eq. xp) of :func:`warpratchet.theory.accelerator_modes` mark the L
(``w = 1``) and R (``w = -1``) islands.
"""

from __future__ import annotations

import numpy as np

from warpratchet import paper, theory
from warpratchet.ensemble import Ensemble, Observer
from warpratchet.params import MapParams

from .canvas import Context, mark_islands, torus_axes
from .sweeps import Settings

__all__ = ["OccupancyObserver", "orbit_image", "fig1", "fig2", "fig4"]


class OccupancyObserver(Observer):
    """Counts the visits of the ensemble to the pixels of the torus ``[0,1)^2`` after each chunk.

    Run with ``chunk_steps=1`` so that every iterate is recorded. ``counts`` has shape
    ``(pixels, pixels)``, indexed ``[p_pixel, x_pixel]`` (image orientation, p upward).
    """

    def __init__(self, pixels: int) -> None:
        self.pixels = pixels
        self.counts = np.zeros(pixels * pixels, dtype=np.int64)

    def _add(self, ensemble: Ensemble) -> None:
        n = self.pixels
        ix = np.minimum((ensemble.array("x") * n).astype(np.int64), n - 1)
        # q is p mod 1, the torus coordinate of the momentum.
        iy = np.minimum((ensemble.array("q") * n).astype(np.int64), n - 1)
        self.counts += np.bincount(iy * n + ix, minlength=n * n)

    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        self._add(ensemble)

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        self._add(ensemble)

    def image(self) -> np.ndarray:
        return self.counts.reshape(self.pixels, self.pixels)


def orbit_image(params: MapParams, s: Settings, seed: int = 0) -> np.ndarray:
    """Visit counts, shape ``(pixels, pixels)``, of ``orbit_points`` orbits started uniformly in B.

    Every orbit of the chaotic region enters B (Sec. IV), so the union of these orbits traces the
    global chaotic region; at K = 3 after three steps it is already C = B u MB u M^2 B (Eq. Cs).
    """
    ensemble = Ensemble.sample(params, s.orbit_points, init=paper.SAMPLER, seed=seed)
    observer = OccupancyObserver(s.pixels)
    ensemble.run(s.orbit_steps, observers=[observer], chunk_steps=1)
    return observer.image()


def _orbits(ax, ctx: Context, params: MapParams, title: str) -> None:
    """One torus panel: the visited pixels (the dots of the paper's figures) and the islands."""
    ax.imshow(
        orbit_image(params, ctx.settings) > 0,
        origin="lower",
        extent=(0.0, 1.0, 0.0, 1.0),
        cmap="gray_r",
        vmin=0,
        vmax=1,
        interpolation="nearest",
    )
    mark_islands(ax, params)
    torus_axes(ax, title)


def _three_rotations(ctx: Context, maps: tuple[MapParams, ...], name: str, caption: str) -> None:
    """Figs. 1 and 2: one panel per rotation angle of Eq. (eig), (a) to (c) from the top."""
    fig, axes = ctx.plt.subplots(3, 1, figsize=(4.0, 11.0))
    for ax, rotation, params in zip(axes, paper.ROTATIONS, maps, strict=True):
        _orbits(ax, ctx, params, f"({rotation.panel}) {rotation.tex}, $K={params.K:.4g}$")
    ctx.save(fig, name, caption)


def fig1(ctx: Context) -> None:
    s = ctx.settings
    b1, b2 = paper.FIG1_WIDTHS
    _three_rotations(
        ctx,
        paper.FIG1,
        "fig1",
        f"""
        Fig. 1. Global chaotic regions for b1 = {b1}, b2 = {b2}: {s.orbit_points} orbits started uniformly in
        the strip B (Eq. B), every iterate of {s.orbit_steps} steps shown on a {s.pixels}^2 pixel grid. K = 2
        - 2 cos(alpha) (Eq. eig). Red dots: period-1 accelerator modes x0 = c - w/K, p0 = 0 (Eq. xp); L (w =
        1) and R (w = -1) label their islands.
        """,
    )


def fig2(ctx: Context) -> None:
    s = ctx.settings
    _three_rotations(
        ctx,
        paper.FIG2,
        "fig2",
        f"""
        Fig. 2. Elliptic-sawtooth limit: the map with b1 = b2 = 1e-7 for the same alpha as Fig. 1;
        {s.orbit_points} orbits started uniformly in B (Eq. B), {s.orbit_steps} steps, {s.pixels}^2 pixels.
        (a) K = 3: separatrix lines; (b), (c): pseudochaotic regions. L and R islands marked as in Fig. 1.
        """,
    )


def fig4(ctx: Context) -> None:
    s = ctx.settings
    params = paper.FIG4
    fig, ax = ctx.plt.subplots(figsize=(5.5, 6.2))
    _orbits(
        ax,
        ctx,
        params,
        f"$K={params.K:g}$, $b_1={params.b1}$, $b_2={params.b2}$ (domain {theory.domain(params)})",
    )
    ctx.save(
        fig,
        "fig4",
        f"""
        Fig. 4. Global chaotic region for K = {params.K:g}, b1 = {params.b1}, b2 = {params.b2}
        ({s.orbit_points} orbits from B, {s.orbit_steps} steps). Only the right period-1 island R exists here
        (domain R of Fig. 3).
        """,
    )
