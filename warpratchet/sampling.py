"""Initial conditions of an ensemble: the named samplers of :data:`warpratchet.spec.SAMPLERS`.

Pure NumPy, no Warp, no I/O. ``strip`` is uniform in the hyperbolic strip B of Eq. (B) (the
ensemble of Figs. 2 and 7-8), ``torus`` uniform on the unit torus (the paper's Fig. 9 ensemble,
:data:`warpratchet.paper.FIG9_ENSEMBLE`), ``grid`` a lattice with irrational offsets (the census
of :mod:`warpratchet.sumrule`). :func:`sampled_chunks` yields the same points chunk by chunk, so
:meth:`warpratchet.ensemble.Ensemble.sample` builds 10^8 points without full-size temporaries.
:func:`salted_subsample` picks the fixed subsamples of points a run follows (snapshots, blocks).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ParameterError, check_count
from .params import MapParams
from .spec import SAMPLERS

__all__ = [
    "GRID_OFFSET",
    "GRID_P_OFFSET",
    "sample_strip",
    "sample_torus",
    "sample_grid",
    "grid_nodes",
    "sampled_chunks",
    "salted_subsample",
]

#: Grid offsets in units of the spacing. The golden-ratio fraction on the x axis keeps nodes
#: off the kinks x = b1 and x = 1 - b2 for any b1, b2 with small denominators. The p axis has
#: a different irrational offset: with one offset on both axes p - x is a multiple of the
#: spacing, and nodes then sit exactly on the slope-1 edges p = x - b1 + k of Eq. (B1e)
#: (0.1% of the nodes at b1 = 0.1, G = 450).
GRID_OFFSET = (math.sqrt(5.0) - 1.0) / 2.0
GRID_P_OFFSET = math.sqrt(2.0) - 1.0


def sample_strip(params: MapParams, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniform in the hyperbolic strip B of Eq. (B).

    B is ``-b2 <= x <= b1`` (mod 1), ``0 <= p < 1``: the ensemble of Figs. 2 and 7-9.
    Returns ``(x, p)``, each of shape ``(n,)``, in ``[0, 1)``.
    """
    return _strip_x(params, rng.random(n)), rng.random(n)


def _strip_x(params: MapParams, u: np.ndarray) -> np.ndarray:
    """Positions in B from uniform ``u`` in [0, 1); for another force, in its strip (the pieces
    with ``f' > 0``, :meth:`~warpratchet.force.Force.strip_interval`) when that is one interval."""
    if params.is_paper:
        return np.mod(-params.b2 + params.b * u, 1.0)
    interval = params.table.strip_interval()
    if interval is None:
        raise ParameterError(
            "init = 'strip' samples one interval of positive slope f' > 0; the force with "
            f"{params.table.describe()} has none or several (use init 'torus' or 'grid')"
        )
    start, width = interval
    return np.mod(start + width * u, 1.0)


def sample_torus(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniform on the unit torus ``[0, 1)^2``."""
    return rng.random(n), rng.random(n)


def grid_nodes(side: int) -> tuple[np.ndarray, np.ndarray]:
    """A ``side x side`` lattice on the torus, shape ``(side^2,)`` each.

    Nodes sit at ``((i + o_x)/G, (j + o_p)/G)`` with the irrational offsets :data:`GRID_OFFSET`
    and :data:`GRID_P_OFFSET`, so no node lands on a kink of the force or on the sloped edges of
    the regions of Appendix B. Row-major in ``p``: node ``(i, j)`` is element ``j * G + i``.
    """
    side = check_count("grid", side, 1)
    x, p = np.meshgrid(*_grid_axes(side), indexing="xy")
    return x.ravel(), p.ravel()


def _grid_axes(side: int) -> tuple[np.ndarray, np.ndarray]:
    return (np.arange(side) + GRID_OFFSET) / side, (np.arange(side) + GRID_P_OFFSET) / side


def sample_grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The :func:`grid_nodes` lattice with ``G = isqrt(n)`` (so ``G^2 <= n`` points)."""
    side = math.isqrt(n)
    if side < 1:
        raise ValueError(f"points = {n!r} is too few for a grid (need at least 1)")
    return grid_nodes(side)


#: Points built at a time: an ensemble's temporaries stay a few MB whatever its size.
_BUILD_CHUNK = 1 << 18


def sampled_chunks(params: MapParams, init: str, points: int, seed: int, lo: int = 0, hi: int | None = None):
    """``(n, chunks)``: the ``n`` points of a named sampler as consecutive ``(lo, x, p)`` chunks.

    Bitwise the points of :func:`sample_strip`, :func:`sample_torus` (``default_rng(seed)``) and
    :func:`sample_grid`, without their full-size arrays: x takes the generator's first ``points``
    doubles and p the next ``points``, so p comes from a second generator advanced by ``points``
    draws (one 64-bit draw per double); grid nodes are looked up on their axes.

    ``lo``, ``hi``: only points ``lo <= i < hi`` of the ``n`` (a shard of
    :mod:`warpratchet.cluster`), each the same double as in the whole ensemble (both generators
    advanced by ``lo`` more draws); chunks then start at ``i - lo``.
    """
    if init == "grid":
        side = math.isqrt(points)
        if side < 1:
            raise ValueError(f"points = {points!r} is too few for a grid (need at least 1)")
        x_axis, p_axis = _grid_axes(side)
        n = side * side

        end = n if hi is None else hi

        def grid():
            for start in range(lo, end, _BUILD_CHUNK):
                node = np.arange(start, min(end, start + _BUILD_CHUNK))
                yield start - lo, x_axis[node % side], p_axis[node // side]

        return n, grid()
    if init not in SAMPLERS:
        raise ValueError(f"init = {init!r} is not one of {', '.join(SAMPLERS)}")
    if init == "strip" and isinstance(params, MapParams):  # (the ensemble refuses a non-MapParams)
        _strip_x(params, np.zeros(0))  # refuses a force without one strip interval, before any work
    rng_x = np.random.default_rng(seed)
    rng_p = np.random.default_rng(seed)
    rng_x.bit_generator.advance(lo)
    rng_p.bit_generator.advance(points + lo)
    end = points if hi is None else hi

    def uniform():
        for start in range(lo, end, _BUILD_CHUNK):
            u = rng_x.random(min(_BUILD_CHUNK, end - start))
            yield start - lo, (_strip_x(params, u) if init == "strip" else u), rng_p.random(u.size)

    return points, uniform()


def salted_subsample(points: int, seed: int | None, size: int, salt: int) -> np.ndarray:
    """Sorted indices, shape ``(size,)`` int64, of ``size`` of ``points`` points drawn without
    replacement, fixed by the run's ``seed`` (None as 0) and a ``salt`` of the caller's own.

    The salt keeps each subsample's stream apart from the sampler's (``default_rng(seed)``) and
    from the other subsamples', and makes a resumed run draw the same points. Archived runs store
    these indices, so the draw must never change: ``default_rng([salt, seed]).choice``, sorted.
    """
    rng = np.random.default_rng([salt, 0 if seed is None else int(seed)])
    return np.sort(rng.choice(points, size=size, replace=False)).astype(np.int64)
