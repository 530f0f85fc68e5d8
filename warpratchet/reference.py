"""NumPy reference of the kernel arithmetic (tests and benchmarks).

:func:`advance` repeats :mod:`warpratchet.kernels` operation by operation, in the same order
and with the same float64 roundings, so that the two agree bit for bit. It is vectorised over
points and loops over steps in Python: the honest NumPy baseline of ``benchmarks/``. The one
transcendental function, the ``log`` of a renormalisation, is the C library's, as in the kernels.
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import RENORM_CHECK_EVERY, RENORM_THRESHOLD
from .params import MapParams

__all__ = ["advance", "advance_renormalising_every_step"]


def _step(p: MapParams, x, q, w, dx, dp):
    in_left = x <= p.b1
    in_middle = x < 1.0 - p.b2
    f = np.where(in_left, p.l1 * x, np.where(in_middle, p.c - x, p.l2 * (x - 1.0)))
    slope = np.where(in_left, p.l1, np.where(in_middle, -1.0, p.l2))
    t = q + p.K * f
    fl = np.floor(t)
    q = t - fl
    wrap = q >= 1.0
    q = np.where(wrap, 0.0, q)
    w = w + fl + np.where(wrap, 1.0, 0.0)
    x = x + q
    x = np.where(x >= 1.0, x - 1.0, x)
    dp = dp + (p.K * slope) * dx
    dx = dx + dp
    return x, q, w, dx, dp


def _renorm(dx, dp, lsum):
    big = np.abs(dx) > RENORM_THRESHOLD
    h = np.sqrt(dx * dx + dp * dp)
    # The kernels call the C library's log; NumPy's own (SIMD) log differs from it in the last
    # bit for a few arguments per million, so the renormalised lanes use math.log (the C one).
    log_h = np.zeros_like(h)
    log_h[big] = [math.log(value) for value in h[big]]
    return (
        np.where(big, dx / h, dx),
        np.where(big, dp / h, dp),
        np.where(big, lsum + log_h, lsum),
    )


def advance(
    p: MapParams,
    state: dict[str, np.ndarray],
    steps: int,
    step0: int = 0,
) -> dict[str, np.ndarray]:
    """Advance ``state`` (keys ``x, q, winding, dx, dp, log_stretch``; shape ``(n,)``) by
    ``steps`` iterations of Eq. (cpem) and ``DM``, from global step ``step0``.

    Returns a new dict; the kernel's bitwise twin.
    """
    x, q = state["x"].copy(), state["q"].copy()
    dx, dp, lsum = state["dx"].copy(), state["dp"].copy(), state["log_stretch"].copy()
    w = np.zeros_like(x)
    for s in range(steps):
        x, q, w, dx, dp = _step(p, x, q, w, dx, dp)
        if (step0 + s + 1) % RENORM_CHECK_EVERY == 0:
            dx, dp, lsum = _renorm(dx, dp, lsum)
    winding = state["winding"] + w.astype(np.int64)
    return {"x": x, "q": q, "winding": winding, "dx": dx, "dp": dp, "log_stretch": lsum}


def advance_renormalising_every_step(
    p: MapParams, state: dict[str, np.ndarray], steps: int
) -> dict[str, np.ndarray]:
    """Like :func:`advance`, but the tangent is normalised after *every* step.

    The textbook FTLE bookkeeping, used to check that threshold renormalisation changes the
    exponent only at the ~1e-15 relative level.
    """
    x, q = state["x"].copy(), state["q"].copy()
    dx, dp, lsum = state["dx"].copy(), state["dp"].copy(), state["log_stretch"].copy()
    w = np.zeros_like(x)
    for _ in range(steps):
        x, q, w, dx, dp = _step(p, x, q, w, dx, dp)
        h = np.hypot(dx, dp)
        lsum = lsum + np.log(h)
        dx, dp = dx / h, dp / h
    winding = state["winding"] + w.astype(np.int64)
    return {"x": x, "q": q, "winding": winding, "dx": dx, "dp": dp, "log_stretch": lsum}
