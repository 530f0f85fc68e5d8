"""NumPy reference of the kernel arithmetic (tests and benchmarks).

:func:`advance` repeats :mod:`warpratchet.kernels` operation by operation, in the same order
and with the same float64 roundings, so that the two agree bit for bit. It is vectorised over
points and loops over steps in Python: the honest NumPy baseline of ``benchmarks/``. Two
logarithms appear: the ``log`` of a renormalisation is the C library's, as in the kernels, and the
chaos indicators' is :func:`fdlog`, the project's own (:mod:`warpratchet.kernels._logarithm`).
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import INDICATOR_FIELDS, RENORM_CHECK_EVERY, RENORM_THRESHOLD
from .kernels._logarithm import LG1, LG2, LG3, LG4, LG5, LG6, LG7, LN2_HI, LN2_LO, REDUCE_ABOVE
from .params import MapParams

__all__ = ["advance", "advance_indicators", "advance_renormalising_every_step", "fdlog", "INDICATOR_FIELDS"]


def _step(p: MapParams, x, q, w, dx, dp):
    f, slope = p.table.evaluate(x)  # the force's piece table, as the kernels evaluate it
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


def fdlog(x: np.ndarray) -> np.ndarray:
    """Natural logarithm, bitwise that of the kernels' ``fdlog`` (:mod:`warpratchet.kernels._logarithm`).

    fdlibm's algorithm, operation by operation as the kernels evaluate it; ``x`` any shape.
    """
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(all="ignore"):  # special arguments compute garbage, replaced at the end
        mantissa, exponent = np.frexp(x)  # x = mantissa 2^exponent exactly, mantissa in [1/2, 1)
        low = mantissa < REDUCE_ABOVE / 2.0  # bring 1 + f into [T/2, T)
        m = np.where(low, 2.0 * mantissa, mantissa)
        k = np.where(low, exponent - 1, exponent).astype(np.float64)
        f = m - 1.0
        s = f / (2.0 + f)
        z = s * s
        w = z * z
        t1 = w * (LG2 + w * (LG4 + w * LG6))
        t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)))
        r = t2 + t1
        hfsq = 0.5 * f * f
        result = k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f)
    special = np.where(x == 0.0, -np.inf, np.where(x == np.inf, np.inf, np.nan))
    return np.where((x > 0.0) & (x < np.inf), result, special)


def advance_indicators(
    p: MapParams,
    state: dict[str, np.ndarray],
    indicators: dict[str, np.ndarray],
    steps: int,
    step0: int = 0,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """:func:`advance` plus the accumulators of ``advance_map_indicators`` (keys ``fli,
    megno_lsum, megno_ysum``), its bitwise twin (see :mod:`warpratchet.kernels._indicators`).

    At every global step ``8 j``, after the renormalisation check: ``L = log_stretch +
    0.5 fdlog(dx^2 + dp^2)``, ``fli = max(fli, L)``, ``megno_ysum += 2 L - 2 megno_lsum / j``,
    ``megno_lsum += L``. Returns new dicts ``(state, indicators)``.
    """
    state = {name: np.array(values, copy=True) for name, values in state.items()}
    acc = {name: np.array(indicators[name], dtype=np.float64, copy=True) for name in INDICATOR_FIELDS}
    done = 0
    while done < steps:
        global_step = step0 + done
        todo = min(steps - done, RENORM_CHECK_EVERY - global_step % RENORM_CHECK_EVERY)
        state.update(advance(p, state, todo, step0=global_step))
        done += todo
        if (global_step + todo) % RENORM_CHECK_EVERY == 0:
            j = float((global_step + todo) // RENORM_CHECK_EVERY)
            dx, dp = state["dx"], state["dp"]
            big_l = state["log_stretch"] + 0.5 * fdlog(dx * dx + dp * dp)
            fli = acc["fli"]
            # the kernels' max: keeps fli where big_l is NaN
            acc["fli"] = np.where(fli >= big_l, fli, np.where(big_l == big_l, big_l, fli))
            acc["megno_ysum"] = acc["megno_ysum"] + 2.0 * big_l - 2.0 * acc["megno_lsum"] / j
            acc["megno_lsum"] = acc["megno_lsum"] + big_l
    return state, acc
