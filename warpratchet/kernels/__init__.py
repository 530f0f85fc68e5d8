"""Every Warp kernel of warpratchet.

The map (Eq. cpem) and its tangent ``DM`` are advanced *inside* one kernel for ``steps``
iterations, so that a launch does real work: on the CPU a Warp launch runs on one thread, and
the ensemble layer shards points over one Python thread per core.

Arithmetic (``warpratchet.reference`` repeats it operation by operation in NumPy, which is what
makes the two bitwise equal):

* force, Eq. (fx): ``f = l1*x`` if ``x <= b1``; ``c - x`` if ``x < 1 - b2``; ``l2*(x - 1)``;
* momentum kept as an integer winding ``w`` plus a fraction ``q`` in ``[0, 1)``:
  ``t = q + K*f``, ``w += floor(t)``, ``q = t - floor(t)``, and a ``q`` that rounds up to
  exactly 1 (``t`` just below an integer) is folded to 0 with ``w += 1``. A float64 momentum
  that grew to 10^4 would lose the digits that ``x' = x + p' mod 1`` needs;
* ``x' = x + q``, minus 1 if that is ``>= 1`` (exact: ``x + q < 2``);
* tangent ``(dx, dp)``: ``dp' = dp + (K*f')*dx``, ``dx' = dx + dp'`` (``det DM = 1``);
* after every global step that is a multiple of ``RENORM_CHECK_EVERY``, a tangent with
  ``|dx| > RENORM_THRESHOLD`` is divided by its norm ``h = sqrt(dx^2 + dp^2)`` and ``log(h)``
  is added to the log-stretch. Checks sit at *global* step numbers, so a run split into any
  chunks (or resumed from an archive) renormalises at the same steps and stays bitwise equal.

Speed: each Warp thread advances ``INTERLEAVE`` points (indices ``tid + k*stride``) held in
small vectors; the lanes are independent and identical, so LLVM vectorises them (SLP) and
the CPU overlaps their dependency chains. The force branch is chosen with ``wp.where``, and
the renormalisation test runs once every 8 steps, keeping the step body branch free.
Measured on 2 cores (AMD EPYC, AVX): ~450 M point-steps/s per thread, against ~270 with one
point per thread and a test every step.
"""

from __future__ import annotations

import ctypes.util
import os

import warp as wp

# The tangent is carried explicitly; Warp's adjoint code would only cost compile time.
wp.set_module_options({"enable_backward": False, "optimization_level": 3})

__all__ = [
    "advance_map",
    "advance_map_indicators",
    "RENORM_THRESHOLD",
    "RENORM_CHECK_EVERY",
    "INTERLEAVE",
    "init_warp",
    "launch_dim",
]

#: Renormalise the tangent when ``|dx|`` passes this. Between two checks (8 steps) a vector
#: grows by at most ``(2 + K max(l1, l2))^8``, below 1e208 for every ``b1, b2 > 1e-25``.
RENORM_THRESHOLD = 1.0e100
#: Steps between two renormalisation checks (a power of two: the test is a bit mask).
RENORM_CHECK_EVERY = 8
#: Points advanced per Warp thread.
INTERLEAVE = 8

_initialised = False


def init_warp() -> None:
    """Initialise Warp once, quietly (module-load lines on only if WARPRATCHET_VERBOSE is set)."""
    global _initialised
    if _initialised:
        return
    if os.environ.get("WARPRATCHET_VERBOSE"):
        wp.init()
    else:
        wp.config.quiet = True
        wp.config.log_level = 30  # logging.WARNING
        if ctypes.util.find_library("cuda") is None:
            # No CUDA driver on this machine: Warp's native "could not load the CUDA driver"
            # line says nothing the user can act on, so fd 2 is muted while Warp starts.
            with _stderr_muted():
                wp.init()
        else:
            wp.init()
    _initialised = True


class _stderr_muted:
    def __enter__(self):
        import sys

        sys.stderr.flush()
        self._saved = os.dup(2)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)

    def __exit__(self, *exc):
        os.dup2(self._saved, 2)
        os.close(self._saved)


def launch_dim(n: int) -> int:
    """Number of Warp threads that advance ``n`` points."""
    return (n + INTERLEAVE - 1) // INTERLEAVE


@wp.func
def _step(
    x: wp.float64,
    q: wp.float64,
    w: wp.float64,
    dx: wp.float64,
    dp: wp.float64,
    K: wp.float64,
    b1: wp.float64,
    right: wp.float64,
    l1: wp.float64,
    l2: wp.float64,
    c: wp.float64,
):
    """One iteration of Eq. (cpem) and of ``DM`` for one point (arithmetic: module docstring)."""
    one = wp.float64(1.0)
    zero = wp.float64(0.0)
    in_left = x <= b1
    in_middle = x < right
    # Eq. (fx) and its slope; wp.where keeps the step branch free (and vectorisable).
    f = wp.where(in_left, l1 * x, wp.where(in_middle, c - x, l2 * (x - one)))
    slope = wp.where(in_left, l1, wp.where(in_middle, -one, l2))
    t = q + K * f
    fl = wp.floor(t)
    q = t - fl
    # t just below an integer can round t - floor(t) up to exactly 1: fold it back.
    wrap = q >= one
    q = wp.where(wrap, zero, q)
    w = w + fl + wp.where(wrap, one, zero)
    x = x + q
    x = wp.where(x >= one, x - one, x)
    dp = dp + (K * slope) * dx
    dx = dx + dp
    return x, q, w, dx, dp


@wp.func
def _renorm(dx: wp.float64, dp: wp.float64, lsum: wp.float64):
    """Divide a tangent past ``RENORM_THRESHOLD`` by its norm and book the log-stretch."""
    if wp.abs(dx) > wp.float64(RENORM_THRESHOLD):
        h = wp.sqrt(dx * dx + dp * dp)
        lsum = lsum + wp.log(h)
        dx = dx / h
        dp = dp / h
    return dx, dp, lsum


# Per-thread lanes; indexed only with unrolled constants, so LLVM keeps them in registers.
_lanes = wp.types.vector(length=INTERLEAVE, dtype=wp.float64)


@wp.func
def _gather(a: wp.array(dtype=wp.float64), tid: int, stride: int, n: int):
    """Load the lanes ``tid + k*stride`` of ``a``; lanes past ``n`` repeat point ``n - 1``."""
    v = _lanes()
    for k in range(wp.static(INTERLEAVE)):
        v[k] = a[wp.min(tid + k * stride, n - 1)]
    return v


@wp.func
def _scatter(a: wp.array(dtype=wp.float64), v: _lanes, tid: int, stride: int, n: int):
    """Store the lanes that are real points."""
    for k in range(wp.static(INTERLEAVE)):
        i = tid + k * stride
        if i < n:
            a[i] = v[k]


@wp.func
def _add_windings(winding: wp.array(dtype=wp.int64), ws: _lanes, tid: int, stride: int, n: int):
    """Add the whole units counted in float64 (exact below 2^53) to the int64 windings."""
    for k in range(wp.static(INTERLEAVE)):
        i = tid + k * stride
        if i < n:
            winding[i] = winding[i] + wp.int64(ws[k])


@wp.kernel
def advance_map(
    x: wp.array(dtype=wp.float64),
    q: wp.array(dtype=wp.float64),
    winding: wp.array(dtype=wp.int64),
    dx: wp.array(dtype=wp.float64),
    dp: wp.array(dtype=wp.float64),
    lsum: wp.array(dtype=wp.float64),
    n: int,
    step0: int,
    steps: int,
    K: wp.float64,
    b1: wp.float64,
    right: wp.float64,
    l1: wp.float64,
    l2: wp.float64,
    c: wp.float64,
):
    """Advance points ``tid + k*stride`` (``k < INTERLEAVE``) by ``steps`` iterations of
    Eq. (cpem) and of ``DM``, starting at global step ``step0``; ``right = 1 - b2``.

    Lanes past ``n`` compute a copy of point ``n - 1`` and store nothing.
    """
    tid = wp.tid()
    stride = (n + wp.static(INTERLEAVE - 1)) // wp.static(INTERLEAVE)
    xs = _gather(x, tid, stride, n)
    qs = _gather(q, tid, stride, n)
    ws = _lanes()
    dxs = _gather(dx, tid, stride, n)
    dps = _gather(dp, tid, stride, n)
    ss = _gather(lsum, tid, stride, n)
    for _s in range(steps):
        # The lane loops are written out here, not in a wp.func: passing the lane vectors
        # through a function call cost 18% of the throughput.
        for k in range(wp.static(INTERLEAVE)):
            xk, qk, wk, dxk, dpk = _step(xs[k], qs[k], ws[k], dxs[k], dps[k], K, b1, right, l1, l2, c)
            xs[k] = xk
            qs[k] = qk
            ws[k] = wk
            dxs[k] = dxk
            dps[k] = dpk
        if ((step0 + _s + 1) & wp.static(RENORM_CHECK_EVERY - 1)) == 0:
            for k in range(wp.static(INTERLEAVE)):
                dxk, dpk, sk = _renorm(dxs[k], dps[k], ss[k])
                dxs[k] = dxk
                dps[k] = dpk
                ss[k] = sk
    _scatter(x, xs, tid, stride, n)
    _scatter(q, qs, tid, stride, n)
    _scatter(dx, dxs, tid, stride, n)
    _scatter(dp, dps, tid, stride, n)
    _scatter(lsum, ss, tid, stride, n)
    _add_windings(winding, ws, tid, stride, n)


@wp.kernel
def advance_map_indicators(
    x: wp.array(dtype=wp.float64),
    q: wp.array(dtype=wp.float64),
    winding: wp.array(dtype=wp.int64),
    dx: wp.array(dtype=wp.float64),
    dp: wp.array(dtype=wp.float64),
    lsum: wp.array(dtype=wp.float64),
    fli: wp.array(dtype=wp.float64),
    megno_lsum: wp.array(dtype=wp.float64),
    megno_ysum: wp.array(dtype=wp.float64),
    n: int,
    step0: int,
    steps: int,
    K: wp.float64,
    b1: wp.float64,
    right: wp.float64,
    l1: wp.float64,
    l2: wp.float64,
    c: wp.float64,
):
    """:func:`advance_map` plus two chaos indicators of the same tangent vector.

    The orbit, tangent and log-stretch are bitwise those of :func:`advance_map` (the same
    ``_step`` and ``_renorm`` calls in the same order). At every global step ``8 j`` that is a
    multiple of ``RENORM_CHECK_EVERY``, after the renormalisation check, with
    ``L_j = ln|v_8j|`` (log-stretch included; ``L_0 = 0`` since ``|v_0| = 1``):

    * ``fli = max(fli, L_j)``: the fast Lyapunov indicator of ``M^8`` (Froeschle et al.);
    * MEGNO of ``M^8`` (Cincotta & Simo 2000), ``Y(j) = (2/j) sum_{i<=j} i (L_i - L_{i-1})``,
      summed by parts to ``Y(j) = 2 L_j - (2/j) sum_{i<j} L_i``: ``megno_lsum`` carries
      ``sum_{i<j} L_i`` and ``megno_ysum`` carries ``sum_{i<=j} Y(i)``, so that the mean MEGNO
      is ``<Y>(j) = megno_ysum / j``.

    Sampling every 8 steps makes these the indicators of the map ``M^8``, which has the same
    chaotic and regular orbits as ``M`` and costs one logarithm per 8 steps instead of one per
    step. Checkpoints sit at global step numbers, so chunking does not change the result; the
    accumulators must start at zero at global step 0.
    """
    tid = wp.tid()
    stride = (n + wp.static(INTERLEAVE - 1)) // wp.static(INTERLEAVE)
    xs = _gather(x, tid, stride, n)
    qs = _gather(q, tid, stride, n)
    ws = _lanes()
    dxs = _gather(dx, tid, stride, n)
    dps = _gather(dp, tid, stride, n)
    ss = _gather(lsum, tid, stride, n)
    fs = _gather(fli, tid, stride, n)
    ls = _gather(megno_lsum, tid, stride, n)
    ys = _gather(megno_ysum, tid, stride, n)
    half = wp.float64(0.5)
    two = wp.float64(2.0)
    for _s in range(steps):
        # Same lane loops as advance_map (written out for speed, see there).
        for k in range(wp.static(INTERLEAVE)):
            xk, qk, wk, dxk, dpk = _step(xs[k], qs[k], ws[k], dxs[k], dps[k], K, b1, right, l1, l2, c)
            xs[k] = xk
            qs[k] = qk
            ws[k] = wk
            dxs[k] = dxk
            dps[k] = dpk
        global_step = step0 + _s + 1
        if (global_step & wp.static(RENORM_CHECK_EVERY - 1)) == 0:
            j = wp.float64(global_step // wp.static(RENORM_CHECK_EVERY))
            for k in range(wp.static(INTERLEAVE)):
                dxk, dpk, sk = _renorm(dxs[k], dps[k], ss[k])
                dxs[k] = dxk
                dps[k] = dpk
                ss[k] = sk
                big_l = sk + half * wp.log(dxk * dxk + dpk * dpk)
                fs[k] = wp.max(fs[k], big_l)
                ys[k] = ys[k] + two * big_l - two * ls[k] / j
                ls[k] = ls[k] + big_l
    _scatter(x, xs, tid, stride, n)
    _scatter(q, qs, tid, stride, n)
    _scatter(dx, dxs, tid, stride, n)
    _scatter(dp, dps, tid, stride, n)
    _scatter(lsum, ss, tid, stride, n)
    _scatter(fli, fs, tid, stride, n)
    _scatter(megno_lsum, ls, tid, stride, n)
    _scatter(megno_ysum, ys, tid, stride, n)
    _add_windings(winding, ws, tid, stride, n)
