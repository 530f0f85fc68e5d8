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

__all__ = ["STATE_FIELDS", "check_state"]

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
