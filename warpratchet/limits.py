"""What the code and the machine can carry: count ceilings, the kernels' range of the map, memory.

Every limit is checked once, before any work, with one line naming the
value and what would be needed:

* **Counts** the code can carry: :data:`MAX_POINTS` (the kernels index points with 32-bit ints),
  :data:`MAX_STEP` (the global step is a 64-bit int; archives and sweep columns store int64).
* **The kernels' arithmetic** (:func:`check_kernel_range`): the map of Eq. (fx) is exact for any
  ``b1, b2 > 0`` (``MapParams`` and the theory accept them), but the kernels carry the tangent
  ``DM`` in float64. Between two renormalisation checks (:data:`RENORM_CHECK_EVERY` steps,
  ``|dx| <= RENORM_THRESHOLD`` after each) a tangent grows by at most ``g^8`` with
  ``g = 2 + K max(l1, l2)`` (the row-sum norm of ``DM``, Eq. fx), so it stays representable while
  ``RENORM_THRESHOLD g^8 <= FLOAT64_MAX``: ``g <= 1.08e26``, i.e. ``b1, b2 >~ 1.9e-26 K/4``. Below
  that a run of the strip B overflows within a few steps (``b1 = b2 = 1e-150``: 843 of 1000
  tangents); such parameters are refused up front with their allowed range (by ``RunSpec`` and
  ``Ensemble``, not by ``MapParams``, whose theory and orbits handle tiny ``b`` exactly). Within
  the range an overflow is still possible in principle (the renormalisation squares the norm;
  a point must stay in B for most of 8 steps) and is never silent: a non-finite state is refused
  by :func:`warpratchet.observables.summarize`, archives and the census.
* **Memory** (:func:`check_memory`): an allocation is estimated before it is made and refused
  with :class:`~warpratchet.errors.ResourceError` naming the size needed and the memory this
  machine has available (``MemAvailable`` of ``/proc/meminfo``, within the cgroup's limit;
  ``os.sysconf`` elsewhere; no check where neither exists).

No Warp. The one system query is the machine's available memory (:func:`available_memory`).
"""

from __future__ import annotations

import math
import os
import sys
from fractions import Fraction

from .errors import ParameterError, ResourceError
from .params import MapParams

__all__ = [
    "MAX_POINTS",
    "MAX_STEP",
    "FLOAT64_MAX",
    "RENORM_THRESHOLD",
    "RENORM_CHECK_EVERY",
    "MAX_TANGENT_GROWTH",
    "kernel_range_error",
    "check_kernel_range",
    "smallest_width",
    "available_memory",
    "format_bytes",
    "check_memory",
]

#: Most points of an ensemble (and of a census or a grid): Warp arrays have 32-bit shapes, and the
#: kernels compute point indices up to ``n + INTERLEAVE - 1`` in 32-bit ints (the strided CUDA
#: layout), so that must fit an int32 for any ``INTERLEAVE <= 64``. ``tests/core/test_limits.py``
#: checks it against the kernels.
MAX_POINTS = 2**31 - 64
#: Largest global step: the kernels' step counter and every stored step are int64.
MAX_STEP = 2**63 - 1
FLOAT64_MAX = sys.float_info.max
#: The kernels' renormalisation threshold and check interval (``warpratchet.kernels``: the kernels
#: import Warp and this module must not; ``tests/core/test_limits.py`` checks that the values agree).
RENORM_THRESHOLD = 1.0e100
RENORM_CHECK_EVERY = 8
#: Largest growth factor per step ``g = 2 + K max |f'|`` (``2 + K max(l1, l2)`` for Eq. fx) whose
#: ``g^8`` from the threshold stays below the float64 maximum:
#: ``(FLOAT64_MAX / RENORM_THRESHOLD)^(1/8) = 1.076e26``.
MAX_TANGENT_GROWTH = (FLOAT64_MAX / RENORM_THRESHOLD) ** (1.0 / RENORM_CHECK_EVERY)


def _growth(K: float, slope: float) -> float:
    return 2.0 + K * slope


def smallest_width(name: str, params) -> float:
    """The smallest ``b1`` (``name="b1"``) or ``b2`` the kernels carry at ``params``' other two values.

    Rounded *up* to two significant digits (so the stated bound is itself accepted): the slope
    ``l1`` (``l2``) of Eq. (mmc) falls as its width grows, so the bound is found by bisection on
    the width's logarithm, then rounded.
    """
    from .params import MapParams

    other = params.b2 if name == "b1" else params.b1

    def carried(width: float) -> bool:
        b1, b2 = (width, other) if name == "b1" else (other, width)
        p = MapParams(params.K, b1, b2)
        return _growth(p.K, p.l1 if name == "b1" else p.l2) <= MAX_TANGENT_GROWTH

    # At half the room left by the other width the slope is below 1: always carried.
    lo, hi = math.log(5e-324), math.log(0.5 * (1.0 - other))
    if not carried(math.exp(hi)):  # pragma: no cover - only for K far beyond 4
        return math.inf
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if carried(math.exp(mid)) else (mid, hi)
    bound = math.exp(hi)
    mantissa, exponent = f"{bound:.1e}".split("e")  # in text: 10**310 would overflow
    rounded = float(f"{mantissa}e{exponent}")
    if rounded < bound:
        rounded = float(f"{float(mantissa) + 0.1:.1f}e{exponent}")
    return rounded if carried(rounded) else bound


#: Largest ``max |K f|`` the kernels carry: a step then drops ``k = floor(q + K f)`` in
#: ``{-2, ..., 2}``, which the transport's gain codes and the orbits' symbol alphabet encode
#: (the paper's family has ``max |f| < 1/2``, so every ``K < 4`` is inside).
MAX_KICK = 2


def kernel_range_error(params) -> str | None:
    """Why the kernels cannot carry ``params`` (a ``MapParams``), or None if they can."""
    if not params.is_paper:
        table = params.table
        kick = Fraction(params.K) * table.max_value
        growth = _growth(params.K, float(table.max_slope))
        if not kick < MAX_KICK:
            return (
                f"max |K f| = {float(kick):.6g} is outside the range the kernels can carry: max |K f| < "
                f"{MAX_KICK} (K < {float(MAX_KICK / table.max_value):.6g} for this force)"
            )
        if not growth <= MAX_TANGENT_GROWTH:
            return (
                f"max |f'| = {float(table.max_slope):.6g} is outside the range the kernels can carry at "
                f"K = {params.K!r}: 2 + K max |f'| <= {MAX_TANGENT_GROWTH:.3g} (a tangent would overflow "
                "float64 between renormalisations)"
            )
        return None
    for name, slope in (("b1", params.l1), ("b2", params.l2)):
        growth = _growth(params.K, slope)
        if not growth <= MAX_TANGENT_GROWTH:  # also an infinite slope (a subnormal width)
            value = getattr(params, name)
            bound = smallest_width(name, params)
            return (
                f"{name} = {value!r} is outside the range the kernels can carry at K = {params.K!r}: "
                f"{name} >= {bound:.2g} (a tangent would overflow float64 between renormalisations)"
            )
    return None


def check_kernel_range(params: object) -> MapParams:
    """``params`` if it is a MapParams the kernels can carry, else :class:`ParameterError`
    (module docstring)."""
    if not isinstance(params, MapParams):
        raise ParameterError(f"params = {params!r} is not a MapParams (e.g. MapParams(K=3, b1=0.1, b2=0.01))")
    message = kernel_range_error(params)
    if message is not None:
        raise ParameterError(message)
    return params


# -- memory -------------------------------------------------------------------------------------
def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_available() -> int | None:
    """What the cgroup (v2) of this process may still use, if it has a limit."""
    try:
        with open("/proc/self/cgroup") as fh:
            path = next((line.strip().split("::", 1)[1] for line in fh if line.startswith("0::")), None)
        if path is None:
            return None
        folder = os.path.join("/sys/fs/cgroup", path.lstrip("/"))
        with open(os.path.join(folder, "memory.max")) as fh:
            limit = fh.read().strip()
        if limit == "max":
            return None
        with open(os.path.join(folder, "memory.current")) as fh:
            used = int(fh.read().strip())
        return max(0, int(limit) - used)
    except (OSError, ValueError, StopIteration):
        return None


def available_memory() -> int | None:
    """Bytes of memory this process can still allocate without swapping, or None if unknown.

    ``MemAvailable`` of ``/proc/meminfo`` (Linux), at most what the cgroup's limit leaves;
    elsewhere ``os.sysconf``'s available physical pages.
    """
    known = [v for v in (_meminfo_available(), _cgroup_available()) if v is not None]
    if not known:
        try:
            known = [os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")]
        except (ValueError, OSError, AttributeError):
            return None
    return min(known)


def format_bytes(n: float) -> str:
    """``"74.5 GiB"``: binary units, three significant digits."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    raise AssertionError("unreachable")  # pragma: no cover


def check_memory(what: str, needed: float, detail: str = "", available: int | None = None) -> None:
    """:class:`ResourceError` if ``needed`` bytes exceed the memory available (:func:`available_memory`).

    Parameters
    ----------
    what : str
        The request, as the user gave it, e.g. ``"points = 10000000000"``.
    needed : float
        Bytes the request would allocate.
    detail : str
        How ``needed`` is made up, e.g. ``"136 B per point"``.
    available : int, optional
        Bytes available (default: this machine's, now). Unknown: no check.
    """
    if available is None:
        available = available_memory()
    if available is None or needed <= available:
        return
    how = f" ({detail})" if detail else ""
    raise ResourceError(
        f"{what} needs {format_bytes(needed)} of memory{how}; this machine has "
        f"{format_bytes(available)} available"
    )
