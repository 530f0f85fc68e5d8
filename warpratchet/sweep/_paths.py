"""Paths and grids through parameter space: the sweeps of the paper's Figs. 5-9.

The maximal path of Eq. (b2max) (Fig. 7), the straight lines ``b1 = b2 / a`` of Eq. (Ama)
(Fig. 8 has ``a = 1/3``), fixed ``b1`` with varying ``b2`` (Fig. 9: ``K = 2.99``,
``b1 = 0.25``), a ``(b1, b2)`` grid optionally masked to an existence domain of Fig. 3
(Figs. 5 and 6) and paths in ``K``. Each returns a list of :class:`MapParams`; any such list is
a sweep. No Warp, no I/O; a sweep's size is checked against the memory it needs
(:func:`check_sweep_size`, the one system query of :mod:`warpratchet.limits`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .. import theory
from ..errors import ParameterError, check_real
from ..force import Force
from ..limits import check_memory
from ..params import MapParams

__all__ = [
    "DOMAINS",
    "SWEEP_BYTES_PER_POINT",
    "check_sweep_size",
    "maximal_path",
    "line_path",
    "fixed_b1_path",
    "grid_points",
    "k_path",
]

#: Host memory of a sweep per point, bytes: its parameters (a MapParams and a row of the parameter
#: table), its summary row (a dict of Python numbers, ~1.3 kB kept), and the transient copies of
#: the rows (the list returned, their JSON text): a sweep's peak grows by ~4.6 kB per point.
#: ``tests/core/test_limits.py`` measures that growth and checks it stays below this.
SWEEP_BYTES_PER_POINT = 8192


def check_sweep_size(count: int, what: str) -> None:
    """ResourceError, before the points are built, if a sweep of ``count`` points does not fit here.

    ``what`` names the request and its size, e.g. ``"--b2 '0:1:1000000000000' (10^12 points)"``.
    """
    check_memory(what, count * SWEEP_BYTES_PER_POINT, f"{SWEEP_BYTES_PER_POINT} B per point")


#: Existence domains of Fig. 3, as returned by :func:`warpratchet.theory.domain`.
DOMAINS: tuple[str, ...] = ("LR", "L", "R", "none")


def _values(name: str, values: Iterable[float] | float) -> np.ndarray:
    array = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if array.ndim != 1:
        raise ParameterError(f"{name} must be a number or a 1-D sequence of numbers; got shape {array.shape}")
    return array


def maximal_path(b2_values: Iterable[float], K: float = 3.0) -> list[MapParams]:
    """Points on the maximal path of Eq. (b2max): ``b1 = b1(b2)`` maximises Eq. (Aa) at fixed b2.

    Parameters
    ----------
    b2_values : sequence of float, shape (n,)
        Right strip widths, each in ``0 < b2 <= 1/6`` (the path ends at ``b1 = b2 = 1/6``).
    K : float
        Kick strength; the path is derived at K = 3 (Fig. 7), other K just reuse its b1(b2).
    """
    return [
        MapParams(K, theory.b1_on_maximal_path(float(b2)), float(b2))
        for b2 in _values("b2_values", b2_values)
    ]


def line_path(a: float, b2_values: Iterable[float], K: float = 3.0) -> list[MapParams]:
    """Points on the straight line ``b1 = b2 / a`` of Eq. (Ama) (Fig. 8: ``a = 1/3``, i.e. b1 = 3 b2)."""
    a = check_real("a", a, 0, low_open=True)
    return [MapParams(K, float(b2) / a, float(b2)) for b2 in _values("b2_values", b2_values)]


def fixed_b1_path(b1: float, b2_values: Iterable[float], K: float) -> list[MapParams]:
    """Points with fixed ``b1`` and varying ``b2`` (Fig. 9: ``K = 2.99``, ``b1 = 0.25``, domain R)."""
    return [MapParams(K, b1, float(b2)) for b2 in _values("b2_values", b2_values)]


def _domain_set(domain: str | Iterable[str] | None) -> frozenset[str] | None:
    if domain is None:
        return None
    wanted = frozenset([domain] if isinstance(domain, str) else domain)
    bad = sorted(wanted - set(DOMAINS))
    if bad or not wanted:
        raise ParameterError(f"domain = {domain!r} must name some of {', '.join(DOMAINS)}")
    return wanted


def grid_points(
    b1_values: Iterable[float],
    b2_values: Iterable[float],
    K: float = 3.0,
    domain: str | Iterable[str] | None = None,
) -> list[MapParams]:
    """Every ``(b1, b2)`` pair of two axes (Figs. 5 and 6), ``b1`` outer and ``b2`` inner.

    Pairs with ``b1 + b2 >= 1`` have no map (Eq. fx) and are skipped. With ``domain`` (a name or
    a set of names among ``"LR", "L", "R", "none"``) only points whose existence domain of
    Fig. 3 (:func:`warpratchet.theory.domain`) is in it are kept, e.g. ``{"LR"}`` for Eq. (Aa).
    """
    wanted = _domain_set(domain)
    b1_axis, b2_axis = _values("b1_values", b1_values), _values("b2_values", b2_values)
    count = b1_axis.size * b2_axis.size
    check_sweep_size(count, f"a grid of {b1_axis.size} x {b2_axis.size} = {count} (b1, b2) points")
    out = []
    for b1 in b1_axis:
        for b2 in b2_axis:
            if b1 + b2 >= 1.0:
                continue
            p = MapParams(K, float(b1), float(b2))
            if wanted is None or theory.domain(p) in wanted:
                out.append(p)
    return out


def k_path(
    K_values: Iterable[float], b1: float | None = None, b2: float | None = None, *, table: Force | None = None
) -> list[MapParams]:
    """Points with fixed ``(b1, b2)``, or another force's ``table``, and varying kick strength
    ``K`` (``0 < K < 4``, Eq. cpem)."""
    if table is not None:
        return [MapParams(float(K), table=table) for K in _values("K_values", K_values)]
    return [MapParams(float(K), b1, b2) for K in _values("K_values", K_values)]
