"""The per-point state of an ensemble: its fields, and what a valid one is.

Pure NumPy, no Warp, no I/O. A point is ``x`` in [0, 1), its momentum as a fraction ``q`` in
[0, 1) plus a whole-unit ``winding`` count (so ``p = winding + q`` keeps every digit however far
it travels), its initial momentum ``p0``, and its tangent ``(dx, dp)`` with the ``log_stretch``
booked at each renormalisation: 56 bytes, the layout of :class:`~warpratchet.ensemble.Ensemble`,
of the kernels' arrays and of the archives' ``/initial`` and ``/checkpoint`` groups.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .errors import ParameterError

__all__ = ["STATE_FIELDS", "check_state", "check_initial", "initial_state"]

#: Per-point state arrays, in the order archives store them.
STATE_FIELDS = ("x", "q", "winding", "p0", "dx", "dp", "log_stretch")


def check_state(state: Mapping) -> None:
    """ParameterError unless ``state`` is one an ensemble can hold: finite, ``x, q`` in [0, 1),
    whole windings, ``|p0| < 2^52`` (what :meth:`Ensemble.state` returns, and checkpoints hold)."""
    for name in STATE_FIELDS:
        values = np.asarray(state[name])
        if values.dtype.kind not in "iuf" or values.dtype.kind == "f" and not np.all(np.isfinite(values)):
            bad = "not numbers" if values.dtype.kind not in "iuf" else "NaN or infinite values"
            raise ParameterError(f"state[{name!r}] holds {bad}; a state must be finite")
    for name in ("x", "q"):
        values = np.asarray(state[name])
        if values.size and not (values.min() >= 0.0 and values.max() < 1.0):
            raise ParameterError(f"state[{name!r}] is outside the allowed range 0 <= {name} < 1")
    winding = np.asarray(state["winding"])
    if winding.dtype.kind == "f" and np.any(winding != np.round(winding)):
        raise ParameterError("state['winding'] holds fractions; windings are whole units of momentum")
    if np.any(np.abs(np.asarray(state["p0"])) >= 2.0**52):
        raise ParameterError("state['p0'] is outside the allowed range |p0| < 2^52 (p0 mod 1 must be exact)")


def check_initial(x0, p0) -> tuple[np.ndarray, np.ndarray]:
    """``x0, p0`` as float64 arrays, or ValueError unless they are 1-D, of one length (at least 1),
    finite, with ``|p0| < 2^52`` (so that ``p0 mod 1`` is exact)."""
    x0 = np.asarray(x0, dtype=np.float64)
    p0 = np.asarray(p0, dtype=np.float64)
    if x0.ndim != 1 or x0.shape != p0.shape:
        raise ValueError(f"x0 and p0 must be 1-D arrays of equal length; got shapes {x0.shape}, {p0.shape}")
    if x0.size == 0:
        raise ValueError("an ensemble needs at least 1 point; got 0")
    if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(p0))):
        raise ValueError("x0 and p0 must be finite")
    if np.any(np.abs(p0) >= 2.0**52):
        raise ValueError("|p0| must be below 2^52 so that p0 mod 1 is exact")
    return x0, p0


def initial_state(x0: np.ndarray, p0: np.ndarray) -> dict:
    """The state at step 0 of points at ``x0`` (taken mod 1) with momenta ``p0``: every field of
    :data:`STATE_FIELDS`, an array of ``x0``'s shape or a scalar for all (the tangent starts at (1, 0))."""
    x = np.mod(x0, 1.0)
    x[x >= 1.0] = 0.0  # mod of a tiny negative number rounds to 1
    return {"x": x, "q": p0 - np.floor(p0), "winding": 0, "p0": p0, "dx": 1.0, "dp": 0.0, "log_stretch": 0.0}
