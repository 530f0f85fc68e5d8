""":class:`TransportEnsemble`: an ensemble whose runs also count return times and flights.

The kernel variant :mod:`warpratchet.kernels.transport` advances the orbit bitwise as the plain
kernel does and counts, inside the step loop, the completed return gaps to B and flights into
log2-binned histograms (:mod:`.histograms`). This class owns the per-point carry state (runs in
progress, one int64 triple per point, 24 bytes) and the running totals of the histograms.

Exactness. Each launch counts into a histogram array of its own; the totals are int64 sums,
whose result does not depend on the order of the additions, so counts are the same for any
thread count (CPU shards), chunking, or device. The carry makes a run that is still open at the
end of a launch continue in the next one; with the state it is everything a resumed run needs
(:meth:`transport_state`, :meth:`from_state`).
"""

from __future__ import annotations

import threading

import numpy as np
import warp as wp

from ..ensemble import Ensemble
from ..kernels.transport import advance_map_transport
from ..params import MapParams
from .histograms import BINS, CARRY_FIELDS, HISTOGRAMS, Histograms, open_runs
from .twin import initial_carry

__all__ = ["TransportEnsemble"]


class TransportEnsemble(Ensemble):
    """An :class:`~warpratchet.ensemble.Ensemble` that counts return times to B and flights.

    Same constructor, samplers and :meth:`run` as ``Ensemble``; the orbit and tangent are
    bitwise a plain ensemble's. Counting starts at the ensemble's step: a point then in B counts
    its first return gap from that step, any other from its first visit (issue 16).
    """

    _kernel = advance_map_transport

    def __init__(self, params: MapParams, x0, p0, **kwargs) -> None:
        super().__init__(params, x0, p0, **kwargs)
        self._start_counting(None, None)

    def _start_counting(self, carry: dict[str, np.ndarray] | None, counts: np.ndarray | None) -> None:
        if carry is None:
            carry = initial_carry(self.params, self.array("x"), self.step)
        self._carry = {}
        for name in CARRY_FIELDS:
            values = np.ascontiguousarray(carry[name], dtype=np.int64)
            if values.shape != (self.points,):
                raise ValueError(f"carry {name} has shape {values.shape}, expected ({self.points},)")
            self._carry[name] = wp.array(values, dtype=wp.int64, device=self.device)
        self._counts = np.zeros((len(HISTOGRAMS), BINS), dtype=np.int64)
        if counts is not None:
            self._counts += np.asarray(counts, dtype=np.int64).reshape(self._counts.shape)
        self._lock = threading.Lock()

    @classmethod
    def from_state(
        cls,
        params: MapParams,
        state: dict[str, np.ndarray],
        step: int,
        *,
        carry: dict[str, np.ndarray] | None = None,
        counts: np.ndarray | None = None,
        **kwargs,
    ) -> TransportEnsemble:
        """Rebuild an ensemble from :meth:`state` and :meth:`transport_state` output, exactly.

        Without ``carry`` and ``counts``, counting starts afresh at ``step``.
        """
        obj = super().from_state(params, state, step, **kwargs)
        obj._start_counting(carry, counts)
        return obj

    # Ensemble's subclass hooks: the transport kernel, its carry arrays and a histogram array
    # per launch; the chunked, multi-threaded run loop (and observers) are reused unchanged.
    def _extra_arrays(self) -> list[wp.array]:
        return [self._carry[name] for name in CARRY_FIELDS]

    def _launch(self, lo: int, hi: int, step0: int, steps: int) -> None:
        arrays = [self._arrays[name][lo:hi] for name in ("x", "q", "winding", "dx", "dp", "log_stretch")]
        extra = [a[lo:hi] for a in self._extra_arrays()]
        counts = wp.zeros(len(HISTOGRAMS) * BINS, dtype=wp.int64, device=self.device)
        self._kernel.launch(self.device, arrays, [*extra, counts], step0, steps, self.params)
        launched = counts.numpy()  # waits for the launch on a GPU
        with self._lock:
            self._counts += launched.reshape(self._counts.shape)

    # -- results ------------------------------------------------------------------------------
    def transport_state(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Copies of the carry state (keys ``last_visit, flight_gain, flight_start``, shape
        ``(points,)`` int64) and of the counts (``(3, BINS)`` int64), at :attr:`step`."""
        carry = {name: np.array(self._carry[name].numpy(), copy=True) for name in CARRY_FIELDS}
        return carry, self._counts.copy()

    def histograms(self) -> Histograms:
        """The completed runs counted so far (:class:`~warpratchet.transport.histograms.Histograms`)."""
        return Histograms.from_counts(self._counts, self.step)

    def open_runs(self) -> Histograms:
        """The runs still open at :attr:`step`, binned by their length so far."""
        carry, _ = self.transport_state()
        return open_runs(carry, self.step)
