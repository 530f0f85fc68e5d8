"""The figures of Dana & Roitberg, "Weak-Chaos Ratchet Accelerator", from warpratchet's own numbers.

``python -m viz figures --all --out figures/`` writes ``fig1.png`` ... ``fig12.png`` (and PDFs):

* Figs. 1, 2, 4: orbits of an ensemble started uniformly in the strip B (Eq. B), accumulated on a
  pixel grid of the torus; the period-1 accelerator modes ``x0 = c - w/K, p0 = 0`` (Eq. xp) of
  :func:`warpratchet.theory.accelerator_modes` mark the L (``w = 1``) and R (``w = -1``) islands.
* Figs. 3, 5: closed forms only (Eq. lai; Eqs. Aa, Ab, b2max).
* Fig. 6: the Lyapunov exponent over a coarse grid of the (b1, b2) plane (a sweep).
* Figs. 7-9: A against sigma along the paper's three paths (sweeps with the paper's settings,
  10^4 initial conditions in B and n = 120000 steps), with the closed forms.
* Figs. 10-12: the regions B, B^(1), B^(2) and C = B u MB u M^2 B (Eq. Cs) from the membership
  tests of :mod:`warpratchet.regions`.

Sweeps are stored as ``<sweeps>/<name>.h5`` (default ``<out>/sweeps``) by
:func:`warpratchet.sweep.run_sweep` and reused when present: a file made with other settings is
an error, never overwritten. ``viz.report`` turns the same files into ``docs/validation.md``.
Figure files that already exist are not replaced unless ``--overwrite`` is given.

matplotlib is an optional dependency (extra ``figures``); it is imported only when figures are drawn.
"""

from __future__ import annotations

import argparse
import math
import sys
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from warpratchet import theory
from warpratchet.ensemble import Ensemble, Observer
from warpratchet.params import MapParams

__all__ = [
    "FIGURES",
    "SWEEP_NAMES",
    "fig9_domain_edge",
    "Settings",
    "settings_for",
    "sweep_points",
    "load_or_run_sweep",
    "main",
]

# -- the paper's parameters ---------------------------------------------------------------------
#: Fig. 1 / Fig. 2 kick strengths from the rotation angle of Eq. (eig): alpha = 2pi/3, 6pi/5, pi(sqrt5-1)/2.
ALPHAS = (
    ("(a)", 2.0 * math.pi / 3.0, r"$\alpha=2\pi/3$"),
    ("(b)", 6.0 * math.pi / 5.0, r"$\alpha=6\pi/5$"),
    ("(c)", math.pi * (math.sqrt(5.0) - 1.0) / 2.0, r"$\alpha=\pi(\sqrt{5}-1)/2$"),
)
FIG1_B = (0.05, 0.02)
FIG2_B = (1e-7, 1e-7)
FIG4_B = (0.226, 0.02)
FIG10_B = (0.1, 0.05)
FIG12_B = (0.3, 0.03)
FIG8_A = 1.0 / 3.0  # b1 = 3 b2 is the line b1 = b2 / a of Eq. (Ama) with a = 1/3
FIG9_K, FIG9_B1 = 2.99, 0.25
#: Plane shown in Figs. 3, 5 and 6: the domains of Fig. 3 end at b = F(0) = 1/2.
PLANE = 0.5

#: Sweep files, in the order they are run (names of ``<sweeps>/<name>.h5``).
SWEEP_NAMES = ("fig7", "fig7_inset", "fig8", "fig9", "fig6")


@dataclass(frozen=True)
class Settings:
    """How much numerics each figure gets (``--quick`` shrinks everything)."""

    quick: bool
    #: Figs. 7-9: initial conditions and steps per sweep point (the paper: 10^4 and 120000).
    points: int
    steps: int
    #: Number of b2 values on each path of Figs. 7-9 (the paper's spacing is 0.005, inset 0.00025).
    path_counts: dict[str, int] = field(default_factory=dict)
    #: Fig. 6: grid side and the (cheaper) ensemble per grid point.
    grid_side: int = 40
    grid_points: int = 2000
    grid_steps: int = 30_000
    #: Figs. 1, 2, 4: orbit ensemble, steps recorded and pixels per side of the torus.
    orbit_points: int = 10_000
    orbit_steps: int = 2000
    pixels: int = 800
    #: Figs. 10-12: pixels per side for the region membership images.
    region_pixels: int = 1000


def settings_for(quick: bool) -> Settings:
    """Full settings (the paper's, about 10-15 min on 2 cores) or ``--quick`` ones (well under 1 min)."""
    if quick:
        return Settings(
            quick=True,
            points=1000,
            steps=4000,
            path_counts={"fig7": 5, "fig7_inset": 3, "fig8": 4, "fig9": 4},
            grid_side=6,
            grid_points=400,
            grid_steps=2000,
            orbit_points=400,
            orbit_steps=200,
            pixels=300,
            region_pixels=300,
        )
    return Settings(
        quick=False,
        points=10_000,
        steps=120_000,
        # The paper's spacings: 0.005 on [0.005, 0.165], 0.00025 on [0.00025, 0.00475], ...
        path_counts={"fig7": 33, "fig7_inset": 19, "fig8": 20, "fig9": 28},
    )


def _b2_values(name: str, s: Settings) -> np.ndarray:
    lo, hi = {
        "fig7": (0.005, 0.165),
        "fig7_inset": (0.00025, 0.00475),
        "fig8": (0.005, 0.1),
        "fig9": (0.005, 0.14),
    }[name]
    return np.linspace(lo, hi, s.path_counts[name])


def grid_axis(s: Settings) -> np.ndarray:
    """Cell centres of the Fig. 6 grid on ``(0, PLANE)``, shape ``(grid_side,)``."""
    return (np.arange(s.grid_side) + 0.5) * (PLANE / s.grid_side)


def sweep_points(name: str, s: Settings) -> list:
    """Parameter points of one sweep, from the constructors of :mod:`warpratchet.sweep`.

    ``fig7``/``fig7_inset``: the maximal path, Eq. (b2max); ``fig8``: ``b1 = 3 b2``; ``fig9``:
    ``K = 2.99, b1 = 0.25``; ``fig6``: the whole grid (every domain, Fig. 6 covers the plane).
    """
    from warpratchet import sweep

    if name in ("fig7", "fig7_inset"):
        return sweep.maximal_path(_b2_values(name, s), K=3.0)
    if name == "fig8":
        return sweep.line_path(FIG8_A, _b2_values(name, s), K=3.0)
    if name == "fig9":
        return sweep.fixed_b1_path(FIG9_B1, _b2_values(name, s), K=FIG9_K)
    if name == "fig6":
        axis = grid_axis(s)
        return sweep.grid_points(axis, axis, K=3.0, domain=None)
    raise ValueError(f"sweep name {name!r} is not one of {', '.join(SWEEP_NAMES)}")


def _sweep_spec(name: str, s: Settings):
    from warpratchet.sweep import SweepSpec

    if name == "fig6":
        return SweepSpec(points=s.grid_points, steps=s.grid_steps, init="strip", seed=0)
    return SweepSpec(points=s.points, steps=s.steps, init="strip", seed=0)


def load_or_run_sweep(
    name: str, s: Settings, sweeps_dir: Path, progress: bool, client: Any = None
) -> list[dict]:
    """Rows of sweep ``name`` from ``<sweeps_dir>/<name>.h5``, computing whatever the file lacks.

    :func:`warpratchet.sweep.run_sweep` reuses a complete file, resumes a partial one and refuses
    (``ValueError``) a file made for other points or another ensemble: it is never overwritten.
    ``client`` (a ``dask.distributed.Client`` or scheduler address) runs the points on Dask.
    """
    from warpratchet.sweep import run_sweep

    sweeps_dir.mkdir(parents=True, exist_ok=True)
    path = sweeps_dir / f"{name}.h5"
    existed = path.exists()
    try:
        return run_sweep(
            sweep_points(name, s), _sweep_spec(name, s), out=path, client=client, progress=progress
        )
    except ValueError as exc:
        if not existed:
            raise
        # run_sweep names its own --force; here the way out is another directory.
        raise ValueError(
            f"{exc.args[0].split(';')[0]}; use another --sweeps directory or remove it"
        ) from None


# -- orbits on the torus (Figs. 1, 2, 4) --------------------------------------------------------
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
    ensemble = Ensemble.sample(params, s.orbit_points, init="strip", seed=seed)
    observer = OccupancyObserver(s.pixels)
    ensemble.run(s.orbit_steps, observers=[observer], chunk_steps=1)
    return observer.image()


# -- drawing helpers ----------------------------------------------------------------------------
def _pyplot():
    """Import matplotlib (non-interactive backend) or fail with a one-line hint."""
    try:
        import matplotlib
    except ImportError:
        raise ValueError("matplotlib is needed for the figures: pip install 'warpratchet[figures]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@dataclass
class Context:
    """What every figure function needs."""

    plt: Any
    settings: Settings
    out: Path
    sweeps: Path
    formats: tuple[str, ...]
    dpi: int
    progress: bool
    client: Any = None
    written: list[Path] = field(default_factory=list)

    def sweep(self, name: str) -> list[dict]:
        return load_or_run_sweep(name, self.settings, self.sweeps, self.progress, self.client)

    def save(self, fig, name: str, caption: str) -> None:
        """Add the caption under the axes and write ``<out>/<name>.<fmt>`` for each format."""
        # About 16 characters of 7-pt text per inch; 0.12 inch per line.
        wrapped = "\n".join(textwrap.wrap(caption, width=int(fig.get_figwidth() * 16)))
        fig.text(0.01, 0.005, wrapped, ha="left", va="bottom", fontsize=7)
        caption_height = (wrapped.count("\n") + 1.5) * 0.12 / fig.get_figheight()
        fig.tight_layout(rect=(0.0, caption_height, 1.0, 1.0))
        for fmt in self.formats:
            path = self.out / f"{name}.{fmt}"
            meta = {"Title": f"{name}: Dana & Roitberg, Weak-Chaos Ratchet Accelerator"}
            meta["Description" if fmt == "png" else "Subject"] = caption
            fig.savefig(path, dpi=self.dpi, metadata=meta)
            self.written.append(path)
        self.plt.close(fig)


def _mark_islands(ax, params: MapParams, color: str = "red") -> None:
    """Mark the period-1 accelerator modes (Eq. xp): L for w = 1, R for w = -1, at p = 0 and p = 1."""
    for w, x0 in theory.accelerator_modes(params):
        label = "L" if w == 1 else "R"
        ax.plot([x0, x0], [0.0, 1.0], ls="none", marker="o", ms=4, color=color, clip_on=False, zorder=5)
        ax.annotate(
            label,
            (x0, 0.0),
            xytext=(0, 6),
            textcoords="offset points",
            ha="center",
            color=color,
            fontsize=10,
            fontweight="bold",
            zorder=6,
        )


def _torus_axes(ax, title: str) -> None:
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ (position, unit period)")
    ax.set_ylabel(r"$p$ mod 1 (momentum)")
    ax.set_title(title, fontsize=9)


def _show_orbits(ax, image: np.ndarray) -> None:
    # Visited / not visited: the dots of the paper's figures, one pixel each.
    ax.imshow(
        image > 0,
        origin="lower",
        extent=(0.0, 1.0, 0.0, 1.0),
        cmap="gray_r",
        vmin=0,
        vmax=1,
        interpolation="nearest",
    )


def _orbit_panels(ctx: Context, b: tuple[float, float], name: str, caption: str) -> None:
    s = ctx.settings
    fig, axes = ctx.plt.subplots(3, 1, figsize=(4.0, 11.0))
    for ax, (tag, alpha, alpha_tex) in zip(axes, ALPHAS, strict=True):
        params = MapParams(theory.K_from_alpha(alpha), *b)
        _show_orbits(ax, orbit_image(params, s))
        _mark_islands(ax, params)
        _torus_axes(ax, f"{tag} {alpha_tex}, $K={params.K:.4g}$")
    ctx.save(fig, name, caption)


def fig1(ctx: Context) -> None:
    s = ctx.settings
    b1, b2 = FIG1_B
    _orbit_panels(
        ctx,
        FIG1_B,
        "fig1",
        f"Fig. 1. Global chaotic regions for b1 = {b1}, b2 = {b2}: {s.orbit_points} orbits started uniformly "
        f"in the strip B (Eq. B), every iterate of {s.orbit_steps} steps shown on a {s.pixels}^2 pixel "
        "grid. K = 2 - 2 cos(alpha) (Eq. eig). Red dots: period-1 accelerator modes x0 = c - w/K, p0 = 0 "
        "(Eq. xp); L (w = 1) and R (w = -1) label their islands.",
    )


def fig2(ctx: Context) -> None:
    s = ctx.settings
    _orbit_panels(
        ctx,
        FIG2_B,
        "fig2",
        f"Fig. 2. Elliptic-sawtooth limit: the map with b1 = b2 = 1e-7 for the same alpha as Fig. 1; "
        f"{s.orbit_points} orbits started uniformly in B (Eq. B), {s.orbit_steps} steps, {s.pixels}^2 "
        "pixels. (a) K = 3: separatrix lines; (b), (c): pseudochaotic regions. L and R islands marked "
        "as in Fig. 1.",
    )


def fig4(ctx: Context) -> None:
    s = ctx.settings
    b1, b2 = FIG4_B
    params = MapParams(3.0, b1, b2)
    fig, ax = ctx.plt.subplots(figsize=(5.5, 6.2))
    _show_orbits(ax, orbit_image(params, s))
    _mark_islands(ax, params)
    _torus_axes(ax, f"$K=3$, $b_1={b1}$, $b_2={b2}$ (domain {theory.domain(params)})")
    ctx.save(
        fig,
        "fig4",
        f"Fig. 4. Global chaotic region for K = 3, b1 = {b1}, b2 = {b2} ({s.orbit_points} orbits from B, "
        f"{s.orbit_steps} steps). Only the right period-1 island R exists here (domain R of Fig. 3).",
    )


# -- the parameter plane (Figs. 3, 5, 6) --------------------------------------------------------
def _domain_curve(K: float = 3.0, samples: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """``b2 = F(b1)`` of Eq. (lai) for ``0 <= b1 <= b_*`` where ``F(b_*) = 0``."""
    # K b^2 + (1 - 2K) b + K - 2 = 0, smaller root: where the curve meets the b1 axis.
    disc = (1.0 - 2.0 * K) ** 2 - 4.0 * K * (K - 2.0)
    b_star = ((2.0 * K - 1.0) - math.sqrt(disc)) / (2.0 * K)
    b1 = np.linspace(0.0, b_star, samples)
    return b1, np.array([theory.F(b, K) for b in b1])


def _draw_domain_lines(ax, color: str = "black", lw: float = 1.0) -> None:
    b1, b2 = _domain_curve()
    ax.plot(b1, b2, color=color, lw=lw)
    ax.plot(b2, b1, color=color, lw=lw)


def _plane_axes(ax) -> None:
    ax.set_xlim(0.0, PLANE)
    ax.set_ylim(0.0, PLANE)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$b_1$ (width of the left hyperbolic strip)")
    ax.set_ylabel(r"$b_2$ (width of the right hyperbolic strip)")


def _maximal_path_curve(samples: int = 400) -> tuple[np.ndarray, np.ndarray]:
    b2 = np.linspace(1e-7, 1.0 / 6.0, samples)
    return np.array([theory.b1_on_maximal_path(v) for v in b2]), b2


def fig3(ctx: Context) -> None:
    fig, ax = ctx.plt.subplots(figsize=(5.5, 6.2))
    b1, b2 = _domain_curve()
    ax.plot(b1, b2, color="C0", lw=1.5, label=r"$b_2=F(b_1)$ (left island boundary)")
    ax.plot(b2, b1, color="C3", lw=1.5, label=r"$b_1=F(b_2)$ (right island boundary)")
    # Label each domain at a point that theory.domain places in it.
    for text, (x, y) in {"LR": (0.08, 0.08), "L": (0.05, 0.3), "R": (0.3, 0.05)}.items():
        assert theory.domain(MapParams(3.0, x, y)) == text
        ax.text(x, y, text, ha="center", va="center", fontsize=14)
    ax.text(0.38, 0.38, "no islands", ha="center", va="center", fontsize=10)
    _plane_axes(ax)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("$K=3$: existence domains of the period-1 islands", fontsize=9)
    ctx.save(
        fig,
        "fig3",
        "Fig. 3. The curves b2 = F(b1) and b1 = F(b2), Eq. (lai) at K = 3. Domain LR: both islands "
        "(Eq. ca); L or R: only that island (Eq. cb); elsewhere none (Eq. cc).",
    )


def abs_acceleration_grid(samples: int) -> tuple[np.ndarray, np.ndarray]:
    """|A| of Eqs. (Aa)/(Ab) (and A(b2,b1) = -A(b1,b2)) on a ``samples^2`` grid of cell centres."""
    axis = (np.arange(samples) + 0.5) * (PLANE / samples)
    values = np.array([[abs(theory.acceleration(MapParams(3.0, b1, b2))) for b1 in axis] for b2 in axis])
    return axis, values


def fig5(ctx: Context) -> None:
    axis, values = abs_acceleration_grid(120 if ctx.settings.quick else 300)
    fig, ax = ctx.plt.subplots(figsize=(6.0, 6.4))
    h = PLANE / axis.size
    mesh = ax.pcolormesh(
        np.append(axis - h / 2, PLANE),
        np.append(axis - h / 2, PLANE),
        values,
        cmap="viridis",
        shading="flat",
        rasterized=True,
    )
    fig.colorbar(mesh, ax=ax, shrink=0.8, label=r"$|A|$ (momentum per kick)")
    _draw_domain_lines(ax, color="white", lw=0.8)
    b1, b2 = _maximal_path_curve()
    ax.plot(b1, b2, color="red", lw=2.5, label=r"maximal path $b_1(b_2)$, Eq. (b2max), $A>0$")
    ax.plot(b2, b1, color="red", lw=2.0, ls="--", label=r"mirror path $b_2(b_1)$, $A<0$")
    _plane_axes(ax)
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title("$K=3$: $|A|$ from the closed forms", fontsize=9)
    ctx.save(
        fig,
        "fig5",
        "Fig. 5. |A| over the (b1, b2) plane at K = 3 from Eqs. (Aa), (Ab) and A(b2, b1) = -A(b1, b2); "
        "A = 0 where no island exists. White: the domain lines of Fig. 3. Thick red: the maximal path "
        "b1(b2), Eq. (b2max); dashed: its mirror b2(b1), on which A < 0.",
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
    edges = np.linspace(0.0, PLANE, axis.size + 1)
    mesh = ax.pcolormesh(edges, edges, np.ma.masked_invalid(sigma), cmap="magma", shading="flat")
    fig.colorbar(mesh, ax=ax, shrink=0.8, label=r"$\sigma$ (per kick)")
    _draw_domain_lines(ax, color="cyan", lw=0.8)
    _plane_axes(ax)
    ax.set_title(r"$K=3$: Lyapunov exponent $\sigma$ of the chaotic region", fontsize=9)
    ctx.save(
        fig,
        "fig6",
        f"Fig. 6. Lyapunov exponent sigma (mean finite-time exponent of the chaotic orbits) on a "
        f"{s.grid_side} x {s.grid_side} grid of cell centres, each from {s.grid_points} orbits started in B "
        f"and {s.grid_steps} steps (fewer than the paper's 10^4 x 120000, to fit the time budget; the "
        f"standard error of each sigma is below {100 * worst:.2f}% of sigma). Cyan: domain lines of Fig. 3. "
        "sigma -> 0 as b1, b2 -> 0.",
    )


# -- A against sigma (Figs. 7-9) ----------------------------------------------------------------
def _columns(rows: list[dict], *keys: str) -> list[np.ndarray]:
    order = np.argsort([float(r["b2"]) for r in rows])
    return [np.array([float(rows[i][k]) for i in order]) for k in keys]


def _dense_along_path(b2: np.ndarray, sigma: np.ndarray, samples: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """A fine b2 grid on the path and sigma interpolated linearly in b2 (the abscissa of the curves)."""
    fine = np.linspace(b2.min(), b2.max(), samples)
    return fine, np.interp(fine, b2, sigma)


def _a_sigma_axes(ax) -> None:
    ax.set_xlabel(r"Lyapunov exponent $\sigma$ (per kick)")
    ax.set_ylabel(r"ratchet acceleration $A$ (momentum per kick)")


def _numeric_points(ax, sigma, a, err, label: str = r"numerics, $\langle (p_n-p_0)/n\rangle$") -> None:
    ax.errorbar(
        sigma,
        a,
        yerr=err,
        fmt="o",
        mfc="none",
        mec="black",
        ecolor="black",
        ms=5,
        lw=0.8,
        label=label,
        zorder=3,
    )


def fig7(ctx: Context) -> None:
    s = ctx.settings
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.3))
    inset = ax.inset_axes([0.5, 0.5, 0.46, 0.44])
    for axes, name in ((ax, "fig7"), (inset, "fig7_inset")):
        b2, sigma, a, err = _columns(ctx.sweep(name), "b2", "lyapunov", "A", "A_stderr")
        fine, fine_sigma = _dense_along_path(b2, sigma)
        corrected = [theory.acceleration_on_maximal_path(v) for v in fine]
        printed = [theory.acceleration_on_maximal_path_as_printed(v) for v in fine]
        axes.plot(fine_sigma, corrected, color="C0", lw=1.5, label="Eq. (Amax), corrected")
        axes.plot(fine_sigma, printed, color="C1", lw=1.2, ls="--", label="Eq. (Amax) as printed")
        _numeric_points(axes, sigma, a, err)
    inset.axhline(theory.LIMIT_MAXIMAL_PATH, color="gray", lw=0.8, ls=":")
    inset.tick_params(labelsize=7)
    inset.set_title(r"inset: $0.00025\leq b_2\leq 0.00475$", fontsize=7)
    _a_sigma_axes(ax)
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(r"$K=3$, maximal path $b_1(b_2)$, $0.005\leq b_2\leq 0.165$", fontsize=9)
    ctx.save(
        fig,
        "fig7",
        f"Fig. 7. A against sigma on the maximal path, Eq. (b2max): circles, <(p_n - p_0)/n> over the "
        f"chaotic orbits of {s.points} initial conditions in B, n = {s.steps} (error bars: standard "
        "errors, smaller than the circles); sigma on the curves is interpolated between the numerical "
        "points. Solid: A of Eq. (Aa) on the path, i.e. the corrected Eq. (Amax) "
        "(5-6r)^2 / (20(5-4b2-2r)), r = [5b2(1-b2)]^(1/2). Dashed: Eq. (Amax) as printed in the paper "
        "(r instead of 2r in the denominator), which the numerics rule out. Inset: small b2, where A "
        "approaches 1/4 (dotted, Eq. Am).",
    )


def fig8(ctx: Context) -> None:
    s = ctx.settings
    rows = ctx.sweep("fig8")
    b2, sigma, a, err = _columns(rows, "b2", "lyapunov", "A", "A_stderr")
    fine, fine_sigma = _dense_along_path(b2, sigma)
    closed = [theory.acceleration(MapParams(3.0, v / FIG8_A, v)) for v in fine]
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.0))
    ax.plot(fine_sigma, closed, color="C0", lw=1.5, label="Eqs. (Aa) (domain LR), (Ab) (domain R)")
    limit = theory.limit_on_line(FIG8_A)
    ax.axhline(limit, color="gray", lw=0.8, ls=":", label=f"limit $b_2\\to 0$: {limit:g}, Eq. (Ama)")
    _numeric_points(ax, sigma, a, err)
    # Where the path leaves domain LR (the left island disappears, Eq. lai) and enters R.
    lo, hi = b2.min(), b2.max()
    if theory.domain(MapParams(3.0, hi / FIG8_A, hi)) != "LR":
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if theory.domain(MapParams(3.0, mid / FIG8_A, mid)) == "LR" else (lo, mid)
        edge = float(np.interp(lo, b2, sigma))
        ax.axvline(edge, color="gray", lw=0.8, ls="--")
        ax.annotate(
            rf"LR $\leftarrow$ | $\rightarrow$ R ($b_2={lo:.4f}$)",
            (edge, 0.5),
            xycoords=("data", "axes fraction"),
            ha="center",
            fontsize=8,
            backgroundcolor="white",
        )
    _a_sigma_axes(ax)
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(r"$K=3$, path $b_1=3b_2$, $0.005\leq b_2\leq 0.1$", fontsize=9)
    ctx.save(
        fig,
        "fig8",
        f"Fig. 8. A against sigma on the path b1 = 3 b2 (crossing domains LR and R of Fig. 3): circles, "
        f"numerics as in Fig. 7 ({s.points} orbits, n = {s.steps}); solid, Eqs. (Aa) and (Ab); dotted, "
        "the limit 1/8 of Eq. (Ama) with a = 1/3. Dashed vertical: where the path leaves domain LR for R "
        "(the left island ceases to exist, Eq. lai).",
    )


def fig9_domain_edge(K: float) -> float:
    """The b2 beyond which the right island of the Fig. 9 path (b1 = 0.25) no longer exists, Eq. (lai)."""
    lo, hi = 1e-6, 0.5
    if not theory.island_exists(MapParams(K, FIG9_B1, lo), "R"):
        return lo
    for _ in range(60):  # bisection on the existence test of Eq. (cam), to ~1e-18
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if theory.island_exists(MapParams(K, FIG9_B1, mid), "R") else (lo, mid)
    return lo


def fig9(ctx: Context) -> None:
    s = ctx.settings
    rows = ctx.sweep("fig9")
    b2, sigma, a, err = _columns(rows, "b2", "lyapunov", "A", "A_stderr")
    fine, fine_sigma = _dense_along_path(b2, sigma)
    closed = [theory.acceleration(MapParams(3.0, FIG9_B1, v)) for v in fine]
    fig, ax = ctx.plt.subplots(figsize=(6.5, 6.0))
    ax.plot(fine_sigma, closed, color="C0", lw=1.5, label="Eq. (Ab) at $K=3$")
    _numeric_points(ax, sigma, a, err, label=r"numerics at $K=2.99$")
    _a_sigma_axes(ax)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(rf"$K={FIG9_K}$, $b_1={FIG9_B1}$, $0.005\leq b_2\leq 0.14$", fontsize=9)
    ctx.save(
        fig,
        "fig9",
        f"Fig. 9. A against sigma at K = {FIG9_K} on the path b1 = {FIG9_B1}: circles, numerics as in Fig. 7 "
        f"({s.points} orbits, n = {s.steps}); solid, the closed form at K = 3: Eq. (Ab) while the right "
        "island "
        f"exists (b2 < {fig9_domain_edge(3.0):.4f}; the paper says the whole path is in domain R) and A = "
        "0 beyond. "
        "Measured sigma "
        f"range: {sigma.min():.4f} to {sigma.max():.4f} (the paper: 0.4787 < sigma < 0.8326).",
    )


# -- regions (Figs. 10-12) ----------------------------------------------------------------------
def _region_masks(params: MapParams, pixels: int) -> dict[str, np.ndarray]:
    """Membership images of B, B^(1), B^(2) on the torus, each of shape ``(pixels, pixels)``."""
    from warpratchet import regions

    axis = (np.arange(pixels) + 0.5) / pixels
    x, p = np.meshgrid(axis, axis, indexing="xy")
    return {
        "B": np.asarray(regions.in_strip(params, x, p), dtype=bool),
        "B1": np.asarray(regions.in_B1(params, x, p), dtype=bool),
        "B2": np.asarray(regions.in_B2(params, x, p), dtype=bool),
    }


def regions_vertices(params: MapParams) -> np.ndarray:
    """Vertices of B^(2), shape ``(4, 2)``, from :func:`warpratchet.regions.B2_vertices`."""
    from warpratchet import regions

    return regions.B2_vertices(params)


def _show_mask(ax, mask: np.ndarray, color) -> None:
    rgba = np.zeros(mask.shape + (4,))
    rgba[mask] = color
    ax.imshow(rgba, origin="lower", extent=(0.0, 1.0, 0.0, 1.0), interpolation="nearest")


REGION_COLORS = {
    "B": (0.20, 0.35, 0.85, 1.0),
    "B1": (0.95, 0.55, 0.10, 1.0),
    "B2": (0.80, 0.15, 0.15, 1.0),
    "overlap": (0.10, 0.60, 0.20, 1.0),
}


def fig10(ctx: Context) -> None:
    b1, b2 = FIG10_B
    params = MapParams(3.0, b1, b2)
    masks = _region_masks(params, ctx.settings.region_pixels)
    fig, axes = ctx.plt.subplots(3, 1, figsize=(4.0, 11.0))
    titles = {
        "B": r"(a) strip $B$, Eq. (B)",
        "B1": r"(b) $\bar B^{(1)}=\bar M B - B\cap\bar M B$, Eq. (B1e)",
        "B2": r"(c) $B^{(2)}=\bar M\bar B^{(1)}$, Eq. (B2e)",
    }
    for ax, key in zip(axes, ("B", "B1", "B2"), strict=True):
        _show_mask(ax, masks[key], REGION_COLORS[key])
        _torus_axes(ax, titles[key])
    # Vertices of B^(2), Eqs. (xj)-(pj): the images of the corners of B^(1) (Appendix C).
    for j, (xv, pv) in enumerate(regions_vertices(params), start=1):
        axes[2].plot([xv], [pv], "k.", ms=5, clip_on=False)
        axes[2].annotate(
            str(j), (xv, pv), xytext=(4, -9 if j < 3 else 3), textcoords="offset points", fontsize=8
        )
    ctx.save(
        fig,
        "fig10",
        f"Fig. 10. K = 3, b1 = {b1}, b2 = {b2}: (a) the strip B; (b) the parallelogram B^(1) of slope 1 "
        "(Eq. B1e); (c) B^(2), the parallelogram of slope 2 folded into the torus (Eq. B2e), with its "
        "vertices j = 1-4 of Eqs. (xj)-(pj); membership "
        f"tests of warpratchet.regions on a {ctx.settings.region_pixels}^2 pixel grid.",
    )


def _region_union(ctx: Context, b: tuple[float, float], name: str, caption: str) -> None:
    params = MapParams(3.0, *b)
    masks = _region_masks(params, ctx.settings.region_pixels)
    fig, ax = ctx.plt.subplots(figsize=(7.5, 6.6))
    for key in ("B", "B1", "B2"):
        _show_mask(ax, masks[key], REGION_COLORS[key])
    _show_mask(ax, masks["B"] & masks["B2"], REGION_COLORS["overlap"])
    _mark_islands(ax, params, color="black")
    _torus_axes(ax, rf"$C=B\cup\bar B^{{(1)}}\cup B^{{(2)}}$, $K=3$, $b_1={b[0]}$, $b_2={b[1]}$")
    handles = [
        _patch(REGION_COLORS[k], label)
        for k, label in (
            ("B", "$B$"),
            ("B1", r"$\bar B^{(1)}$"),
            ("B2", "$B^{(2)}$"),
            ("overlap", r"$B\cap B^{(2)}$"),
        )
    ]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    ctx.save(fig, name, caption)


def _patch(color, label: str):
    """A legend entry for a filled region."""
    from matplotlib.patches import Patch

    return Patch(facecolor=color, edgecolor="none", label=label)


def fig11(ctx: Context) -> None:
    b1, b2 = FIG10_B
    _region_union(
        ctx,
        FIG10_B,
        "fig11",
        f"Fig. 11. The region C = B u B^(1) u B^(2) (Eq. Cs) for K = 3, b1 = {b1}, b2 = {b2}; the overlaps "
        "B n B^(2) in green. Both islands L and R exist (black dots: modes of Eq. xp); white: the islands "
        "and the normal island between them.",
    )


def fig12(ctx: Context) -> None:
    b1, b2 = FIG12_B
    _region_union(
        ctx,
        FIG12_B,
        "fig12",
        f"Fig. 12. The region C = B u B^(1) u B^(2) for K = 3, b1 = {b1}, b2 = {b2}, overlaps B n B^(2) in "
        "green. Only the right island R exists (domain R of Fig. 3).",
    )


#: Figure name -> function drawing it.
FIGURES: dict[str, Callable[[Context], None]] = {
    "fig1": fig1,
    "fig2": fig2,
    "fig3": fig3,
    "fig4": fig4,
    "fig5": fig5,
    "fig6": fig6,
    "fig7": fig7,
    "fig8": fig8,
    "fig9": fig9,
    "fig10": fig10,
    "fig11": fig11,
    "fig12": fig12,
}


# -- command line -------------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line on stderr, exit 2
        print(f"{self.prog}: {message}", file=sys.stderr)
        raise SystemExit(2)


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="python -m viz figures",
        description="Regenerate the paper's figures (PNG and PDF) from warpratchet's own computations.",
    )
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--all", action="store_true", help="every figure, fig1 ... fig12")
    which.add_argument("--only", metavar="LIST", help="comma-separated figure names, e.g. fig7,fig8")
    parser.add_argument("--out", required=True, type=Path, help="output directory")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="small ensembles and few sweep points (well under a minute) instead of the "
        "paper's settings (10^4 orbits x 120000 steps)",
    )
    parser.add_argument(
        "--sweeps",
        type=Path,
        default=None,
        help="directory of sweep files to reuse or create (default: OUT/sweeps)",
    )
    parser.add_argument("--formats", default="png,pdf", help="comma-separated, from png,pdf (default both)")
    parser.add_argument("--dpi", type=int, default=150, help="PNG resolution (default 150)")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run the sweep points on a Dask cluster, e.g. tcp://host:8786",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace figure files that already exist")
    parser.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    return parser


def _selected(args) -> list[str]:
    if args.all:
        return list(FIGURES)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    bad = [n for n in names if n not in FIGURES]
    if bad or not names:
        raise ValueError(
            f"--only {args.only!r}: unknown figure {', '.join(bad) or '(none)'}; "
            f"allowed: {', '.join(FIGURES)}"
        )
    return names


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m viz figures``; returns the exit status (2 on bad input)."""
    args = _build_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        names = _selected(args)
        formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
        if not formats or any(f not in ("png", "pdf") for f in formats):
            raise ValueError(f"--formats {args.formats!r}: allowed formats are png, pdf")
        if not 20 <= args.dpi <= 1200:
            raise ValueError(f"--dpi {args.dpi}: outside the allowed range 20-1200")
        if args.out.exists() and not args.out.is_dir():
            raise ValueError(f"--out {args.out}: exists and is not a directory")
        existing = [args.out / f"{n}.{f}" for n in names for f in formats if (args.out / f"{n}.{f}").exists()]
        if existing and not args.overwrite:
            raise ValueError(
                f"{existing[0]} already exists ({len(existing)} figure files would be replaced); "
                "pass --overwrite or choose another --out"
            )
        plt = _pyplot()
        args.out.mkdir(parents=True, exist_ok=True)
        ctx = Context(
            plt=plt,
            settings=settings_for(args.quick),
            out=args.out,
            sweeps=args.sweeps if args.sweeps is not None else args.out / "sweeps",
            formats=formats,
            dpi=args.dpi,
            progress=not args.quiet,
            client=args.scheduler,
        )
        for name in names:
            start = time.perf_counter()
            FIGURES[name](ctx)
            if not args.quiet:
                print(f"{name}: {time.perf_counter() - start:.1f} s", file=sys.stderr)
    except (ValueError, OSError) as exc:
        print(f"python -m viz figures: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        print("\n".join(str(p) for p in ctx.written))
    return 0


if __name__ == "__main__":
    sys.exit(main())
