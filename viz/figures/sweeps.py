"""How much numerics each figure gets, and the sweep files of Figs. 6-9.

Sweeps are stored as ``<sweeps>/<name>.h5`` by :func:`warpratchet.sweep.run_sweep` and reused
when present: a file made with other settings is an error, never overwritten.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from warpratchet import paper
from warpratchet.params import MapParams
from warpratchet.sweep import SweepSpec, grid_points, run_sweep

from ..paths import path_points

__all__ = ["SWEEP_NAMES", "Settings", "settings_for", "grid_axis", "sweep_points", "load_or_run_sweep"]

#: Sweep files, in the order they are run (names of ``<sweeps>/<name>.h5``). ``fig9`` is the
#: strip ensemble of Figs. 7-8 on Fig. 9's path, ``fig9_paper`` the paper's ensemble there
#: (:data:`warpratchet.paper.FIG9_ENSEMBLE`).
SWEEP_NAMES = ("fig7", "fig7_inset", "fig8", "fig9", "fig9_paper", "fig6")
#: Sweeps on a path of :data:`warpratchet.paper.PATHS` under another name: name -> path name.
PATH_OF = {"fig9_paper": "fig9"}


@dataclass(frozen=True)
class Settings:
    """How much numerics each figure gets (``--quick`` shrinks everything)."""

    quick: bool
    #: Figs. 7-9: initial conditions and steps per sweep point (the paper: 10^4 and 120000).
    points: int
    steps: int
    #: Number of b2 values on each path of Figs. 7-9 (full: the spacing of :data:`warpratchet.paper.PATHS`).
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
    """Full settings (the paper's) or ``--quick`` ones (small ensembles, few sweep points)."""
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
        points=paper.POINTS,
        steps=paper.STEPS,
        path_counts={name: path.count for name, path in paper.PATHS.items()},
    )


def grid_axis(s: Settings) -> np.ndarray:
    """Cell centres of the Fig. 6 grid on ``(0, PLANE_EXTENT)``, shape ``(grid_side,)``."""
    return (np.arange(s.grid_side) + 0.5) * (paper.PLANE_EXTENT / s.grid_side)


def sweep_points(name: str, s: Settings) -> list[MapParams]:
    """Parameter points of one sweep, from the constructors of :mod:`warpratchet.sweep`.

    ``fig7``/``fig7_inset``: the maximal path, Eq. (b2max); ``fig8``: ``b1 = 3 b2``; ``fig9`` and
    ``fig9_paper``: ``K = 2.99, b1 = 0.25``; ``fig6``: the whole grid (every domain, Fig. 6 covers the plane).
    """
    if name in paper.PATHS or name in PATH_OF:
        key = PATH_OF.get(name, name)
        path = paper.PATHS[key]
        return path_points(path, path.b2_values(s.path_counts[key]))
    if name == "fig6":
        axis = grid_axis(s)
        return grid_points(axis, axis, K=paper.K3, domain=None)
    raise ValueError(f"sweep name {name!r} is not one of {', '.join(SWEEP_NAMES)}")


def _sweep_spec(name: str, s: Settings) -> SweepSpec:
    if name == "fig6":
        return SweepSpec(points=s.grid_points, steps=s.grid_steps, init=paper.SAMPLER, seed=0)
    if name == "fig9_paper":
        return SweepSpec(points=s.points, steps=s.steps, seed=0, **paper.FIG9_ENSEMBLE)
    return SweepSpec(points=s.points, steps=s.steps, init=paper.SAMPLER, seed=0)


def load_or_run_sweep(
    name: str, s: Settings, sweeps_dir: Path, progress: bool, client: Any = None
) -> list[dict]:
    """Rows of sweep ``name`` from ``<sweeps_dir>/<name>.h5``, computing whatever the file lacks.

    :func:`warpratchet.sweep.run_sweep` reuses a complete file, resumes a partial one and refuses
    (``ValueError``) a file made for other points or another ensemble: it is never overwritten.
    ``client`` (a ``dask.distributed.Client`` or scheduler address) runs the points on Dask.
    """
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
