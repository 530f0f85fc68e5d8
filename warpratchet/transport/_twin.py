"""The NumPy twin of the transport kernel (:mod:`warpratchet.kernels._transport`), for tests.

:func:`advance` steps :func:`warpratchet.reference.advance` one iteration at a time (the
kernels' orbit, bit for bit) and applies the definitions of docs/transport.md to each step: the gain is
the change of ``winding``, a visit is ``x`` in B (Eq. B) after the step. Slow (a Python loop over
steps), exact: its histograms must equal the kernel's count for count.
"""

from __future__ import annotations

import numpy as np

from ..params import MapParams
from ..reference import advance as advance_map
from ..regions import in_strip
from ._histograms import BINS, CARRY_FIELDS, HISTOGRAMS, bin_of

__all__ = ["initial_carry", "advance"]


def initial_carry(params: MapParams, x: np.ndarray, step: int) -> dict[str, np.ndarray]:
    """The carry state of points at positions ``x`` when counting starts at global ``step``.

    A point in B counts its first return gap from ``step`` (``last_visit = step``); any other
    from its first visit (``-1``: none yet). No flight is in progress (``flight_gain = 0``).
    """
    x = np.asarray(x, dtype=np.float64)
    inside = in_strip(params, x, np.zeros_like(x))
    return {
        "last_visit": np.where(inside, np.int64(step), np.int64(-1)).astype(np.int64),
        "flight_gain": np.zeros(x.shape, dtype=np.int64),
        "flight_start": np.full(x.shape, step, dtype=np.int64),
    }


def advance(
    params: MapParams,
    state: dict[str, np.ndarray],
    carry: dict[str, np.ndarray],
    steps: int,
    step0: int = 0,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], np.ndarray]:
    """Advance ``state`` and ``carry`` by ``steps`` from global ``step0``.

    Returns ``(state, carry, counts)``: the new state and carry (new dicts) and the counts of the
    runs completed meanwhile, shape ``(3, BINS)`` int64, rows in :data:`HISTOGRAMS` order.
    """
    counts = np.zeros((len(HISTOGRAMS), BINS), dtype=np.int64)
    last, gain_run, start = (np.array(carry[name], dtype=np.int64, copy=True) for name in CARRY_FIELDS)
    for s in range(steps):
        n = step0 + s + 1
        after = advance_map(params, state, 1, step0=n - 1)
        gain = after["winding"] - state["winding"]
        visit = in_strip(params, after["x"], after["q"])
        closed = visit & (last >= 0)
        np.add.at(counts[0], bin_of(n - last[closed]), 1)
        last = np.where(visit, n, last)
        ends = gain != gain_run
        for row, sign in ((1, gain_run > 0), (2, gain_run < 0)):
            done = ends & sign
            np.add.at(counts[row], bin_of(n - start[done]), 1)
        gain_run = np.where(ends, gain, gain_run)
        start = np.where(ends, n, start)
        state = after
    return state, {"last_visit": last, "flight_gain": gain_run, "flight_start": start}, counts
