""":class:`TransportEnsemble`: an ensemble whose runs also count return times and flights.

The kernel variant :mod:`warpratchet.kernels._transport` advances the orbit bitwise as the plain
kernel does and counts, inside the step loop, the completed return gaps to B and flights into
log2-binned histograms (:mod:`._histograms`). This class owns the per-point carry state (runs in
progress, one int64 triple per point, 24 bytes), the running totals of the histograms, and the
spread of the momentum at log-spaced steps (:mod:`._diffusion`, recorded by an observer that
each :meth:`~TransportEnsemble.run` adds) from which the exponent mu is fitted.

Exactness. Each launch counts into a histogram array of its own; the totals are int64 sums,
whose result does not depend on the order of the additions, so counts are the same for any
thread count (CPU shards), chunking, or device. The carry makes a run that is still open at the
end of a launch continue in the next one; with the state it is everything a resumed run needs
(:meth:`transport_state`, :meth:`from_state`).
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..ensemble import Ensemble
from ..errors import check_choice, check_optional, check_real
from ..kernels._transport import advance_map_transport
from ..observables import THRESHOLD_RULES
from ..params import MapParams
from ..runloop import Observer
from ..state import STATE_FIELDS
from ._diffusion import SPREAD_BYTES_PER_POINT, Spread
from ._fits import GROUPS, DiffusionFit, diffusion_fit, pooled_variance
from ._histograms import BINS, CARRY_FIELDS, HISTOGRAMS, Histograms, open_runs
from ._twin import initial_carry

__all__ = ["TransportEnsemble", "TransportState"]


@dataclass(frozen=True)
class TransportState:
    """Everything a transport run adds to the state, at one step (what an archive checkpoints).

    ``carry``: :data:`CARRY_FIELDS`, int64 ``(points,)`` each; ``counts``: ``(3, BINS)`` int64;
    ``spread_steps``: ``(rows,)`` int64 and ``spread``: ``(rows, GROUPS, 3)`` float64, the
    moments of :mod:`._diffusion`.
    """

    carry: dict[str, np.ndarray]
    counts: np.ndarray
    spread_steps: np.ndarray
    spread: np.ndarray


class TransportEnsemble(Ensemble):
    """An :class:`~warpratchet.ensemble.Ensemble` that counts return times to B and flights.

    Same constructor, samplers and :meth:`run` as ``Ensemble``; the orbit and tangent are
    bitwise a plain ensemble's. Counting starts at the ensemble's step: a point then in B counts
    its first return gap from that step, any other from its first visit (docs/transport.md).
    """

    _kernel = advance_map_transport
    #: Chaos threshold on the FTLE for the spread's chaotic points (None: ``threshold_rule``'s
    #: value at each step), the run's (:meth:`classify_with`) so that the spread's points are its
    #: History's.
    threshold: float | None = None
    #: Rule of the threshold when ``threshold`` is None (:func:`~warpratchet.observables.lyapunov_threshold`).
    threshold_rule: str = "strict"
    _known_ftle: tuple[int, np.ndarray] | None = None  # (step, FTLE) of the last spread row

    def __init__(self, params: MapParams, x0, p0, **kwargs) -> None:
        super().__init__(params, x0, p0, **kwargs)
        self._start_counting(None)

    def classify_with(
        self, threshold: float | None = None, threshold_rule: str = "strict"
    ) -> TransportEnsemble:
        """Classify the spread's chaotic points as the run does: FTLE above ``threshold``, or, when it
        is None, above ``threshold_rule``'s value at each step (``"strict"`` or ``"positive"``)."""
        threshold = check_optional(check_real, "threshold", threshold, 0.0)
        self.threshold_rule = check_choice("threshold_rule", threshold_rule, tuple(THRESHOLD_RULES))
        self.threshold = threshold
        return self

    @classmethod
    def bytes_per_point(cls) -> int:
        """Memory per point: the state (56 B), the carry (:data:`CARRY_FIELDS`, int64, 24 B) and a
        spread row's arrays (:data:`~._diffusion.SPREAD_BYTES_PER_POINT`, 17 B). The kernel's
        histogram and scratch arrays are per launch, not per point."""
        return 8 * len(STATE_FIELDS) + 8 * len(CARRY_FIELDS) + SPREAD_BYTES_PER_POINT

    def _start_counting(self, transport: TransportState | None) -> None:
        carry = (
            initial_carry(self.params, self.array("x"), self.step) if transport is None else transport.carry
        )
        self._carry = {}
        for name in CARRY_FIELDS:
            values = np.ascontiguousarray(carry[name], dtype=np.int64)
            if values.shape != (self.points,):
                raise ValueError(f"carry {name} has shape {values.shape}, expected ({self.points},)")
            self._carry[name] = wp.array(values, dtype=wp.int64, device=self.device)
        self._counts = np.zeros((len(HISTOGRAMS), BINS), dtype=np.int64)
        self._spread_steps: list[int] = []
        self._spread: list[np.ndarray] = []
        if transport is not None:
            self._counts += np.asarray(transport.counts, dtype=np.int64).reshape(self._counts.shape)
            self._spread_steps = [int(n) for n in transport.spread_steps]
            self._spread = [np.array(m, dtype=np.float64) for m in transport.spread]
        self._lock = threading.Lock()

    @classmethod
    def from_state(cls, *args, transport: TransportState | None = None, **kwargs) -> TransportEnsemble:
        """Rebuild an ensemble from :meth:`state` and :meth:`transport_state` output, exactly.

        The arguments of :meth:`Ensemble.from_state <warpratchet.ensemble.Ensemble.from_state>`
        (``params, state, step``, ...), passed on as given, and ``transport``; without it,
        counting starts afresh at ``step``.
        """
        obj = super().from_state(*args, **kwargs)
        obj._start_counting(transport)
        return obj

    def run(
        self,
        steps: int,
        observers: Sequence[Observer] | Iterable[Observer] = (),
        chunk_steps: int | None = None,
        **kwargs,
    ) -> TransportEnsemble:
        """:meth:`Ensemble.run <warpratchet.ensemble.Ensemble.run>`, recording the spread too."""
        return super().run(steps, [Spread(self), *observers], chunk_steps, **kwargs)

    def record_spread(self, step: int, moments: np.ndarray, ftle: np.ndarray | None = None) -> None:
        """Append a row of :mod:`._diffusion` (called by its observer at its steps); ``ftle``, the
        points' FTLE at ``step`` computed for it, is kept until the next chunk (:meth:`known_ftle`)."""
        self._known_ftle = None if ftle is None else (int(step), ftle)
        if self._spread_steps and step <= self._spread_steps[-1]:
            return  # already recorded (a run continued from an archive records nothing twice)
        self._spread_steps.append(int(step))
        self._spread.append(np.asarray(moments, dtype=np.float64).reshape(GROUPS, 3))

    def known_ftle(self, step: int) -> np.ndarray | None:
        """Every point's FTLE at ``step`` if this chunk end's spread row computed it, else None.

        :meth:`summary` (a History row at the same step) takes it instead of computing the same
        values again (the costly part of a summary).
        """
        known = self._known_ftle
        return known[1] if known is not None and known[0] == step == self.step else None

    # Ensemble's subclass hooks: the transport kernel, its carry arrays and a histogram array
    # per launch; the chunked, multi-threaded run loop (and observers) are reused unchanged.
    def _advance(self, steps: int, pool) -> None:
        self._known_ftle = None  # the state moves on; freed before the kernel runs
        super()._advance(steps, pool)

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
    def transport_state(self) -> TransportState:
        """A copy of the transport state at :attr:`step` (:class:`TransportState`)."""
        carry = {name: np.array(self._carry[name].numpy(), copy=True) for name in CARRY_FIELDS}
        return TransportState(
            carry=carry,
            counts=self._counts.copy(),
            spread_steps=np.array(self._spread_steps, dtype=np.int64),
            spread=np.array(self._spread, dtype=np.float64).reshape(len(self._spread), GROUPS, 3),
        )

    def spread(self) -> tuple[np.ndarray, np.ndarray]:
        """``(steps, var)``: the recorded steps and ``V(n)``, the variance of ``p_n - p_0`` over the
        chaotic points (History's ``var_dp_chaotic``), momentum units squared."""
        var = np.array([pooled_variance(m) for m in self._spread], dtype=np.float64)
        return np.array(self._spread_steps, dtype=np.int64), var

    def diffusion(self, decades: float | None = None) -> DiffusionFit:
        """The exponent mu of ``V(n) ~ n^mu`` with its jackknife error (:func:`._fits.diffusion_fit`)."""
        steps, var = self.spread()
        moments = np.array(self._spread).reshape(len(self._spread), GROUPS, 3).transpose(1, 0, 2)
        kwargs = {} if decades is None else {"decades": decades}
        return diffusion_fit(steps, var, moments if len(self._spread) else None, **kwargs)

    def histograms(self) -> Histograms:
        """The completed runs counted so far (:class:`~warpratchet.transport._histograms.Histograms`)."""
        return Histograms.from_counts(self._counts, self.step)

    def report(self) -> dict:
        """The ``"transport"`` object of ``run --json`` (:func:`._report.transport_report`)."""
        from ._report import transport_report

        return transport_report(self.histograms(), self.open_runs(), self.diffusion())

    def open_runs(self) -> Histograms:
        """The runs still open at :attr:`step`, binned by their length so far."""
        return open_runs(self.transport_state().carry, self.step)
