"""Log2-binned histograms of return times and flights, and the runs still open (pure NumPy).

Bin ``k`` holds lengths ``L`` with ``2^k <= L < 2^(k+1)`` (:data:`BINS` bins cover every int64
length). The kernel variant :mod:`warpratchet.kernels._transport` counts completed runs; a run
still open when the ensemble is read (a return gap not yet closed by a visit to B, a flight still
in progress) is not in those counts, and :func:`open_runs` bins those from the carry state, so
that a fit can see how many long runs the finite run length has cut off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BINS", "HISTOGRAMS", "CARRY_FIELDS", "bin_of", "edges", "Histograms", "open_runs"]

#: Number of bins; the kernel's (kept equal by tests/analyses/test_transport.py, without importing Warp here).
BINS = 64
#: Histogram names, in the kernel's order.
HISTOGRAMS = ("return_times", "flights_plus", "flights_minus")
#: Per-point carry state, int64 arrays (:mod:`warpratchet.kernels._transport`).
CARRY_FIELDS = ("last_visit", "flight_gain", "flight_start")


def bin_of(lengths: np.ndarray) -> np.ndarray:
    """``floor(log2 L)`` of positive integer lengths, exactly (int64 bit lengths, no float log)."""
    lengths = np.asarray(lengths, dtype=np.int64)
    if np.any(lengths < 1):
        raise ValueError("lengths must be >= 1")
    out = np.zeros(lengths.shape, dtype=np.int64)
    v = lengths.copy()
    for width in (32, 16, 8, 4, 2, 1):
        big = (v >> width) != 0
        v = np.where(big, v >> width, v)
        out += np.where(big, width, 0)
    return out


def edges(bins: int) -> list[int]:
    """Bin edges ``[1, 2, 4, ..., 2^bins]`` of the first ``bins`` bins (steps)."""
    return [1 << k for k in range(bins + 1)]


@dataclass(frozen=True)
class Histograms:
    """Counts of completed runs, shape ``(BINS,)`` int64 each; ``step``: the global step they reach.

    ``return_times``: gaps between consecutive visits to B (Eq. B); ``flights_plus`` /
    ``flights_minus``: flights of positive / negative whole-unit gain per step.
    """

    step: int
    return_times: np.ndarray
    flights_plus: np.ndarray
    flights_minus: np.ndarray

    @classmethod
    def from_counts(cls, counts: np.ndarray, step: int) -> Histograms:
        """From the kernel's ``(3, BINS)`` count array (rows in :data:`HISTOGRAMS` order)."""
        counts = np.asarray(counts, dtype=np.int64).reshape(len(HISTOGRAMS), BINS)
        return cls(int(step), *(np.array(row, copy=True) for row in counts))

    def counts(self) -> np.ndarray:
        """The ``(3, BINS)`` int64 array (rows in :data:`HISTOGRAMS` order)."""
        return np.stack([self.return_times, self.flights_plus, self.flights_minus])

    def used_bins(self) -> int:
        """Bins up to the last non-empty one of any histogram (at least 1)."""
        nonzero = np.flatnonzero(self.counts().any(axis=0))
        return int(nonzero[-1]) + 1 if nonzero.size else 1

    def as_dict(self, bins: int | None = None) -> dict:
        """``{"return_times": {"edges", "counts"}, "flights": {"edges", "counts_plus", "counts_minus"}}``.

        Edges in steps, ``bins + 1`` of them (default: up to the last non-empty bin).
        """
        bins = self.used_bins() if bins is None else bins
        e = edges(bins)
        return {
            "return_times": {"edges": e, "counts": self.return_times[:bins].tolist()},
            "flights": {
                "edges": e,
                "counts_plus": self.flights_plus[:bins].tolist(),
                "counts_minus": self.flights_minus[:bins].tolist(),
            },
        }


def open_runs(carry: dict[str, np.ndarray], step: int) -> Histograms:
    """Runs still open at ``step``, binned by their length so far (lower bounds of their lengths).

    A point whose last visit to B was at step ``m`` has a gap of at least ``step - m + 1`` open
    (its next visit is at ``step + 1`` or later); a flight that started at ``s`` has lasted
    ``step - s + 1`` steps. Points that never visited B and zero-gain runs are not counted.
    """
    last, gain, start = (np.asarray(carry[name], dtype=np.int64) for name in CARRY_FIELDS)
    counts = np.zeros((len(HISTOGRAMS), BINS), dtype=np.int64)
    visited = last >= 0
    np.add.at(counts[0], bin_of(step - last[visited] + 1), 1)
    for row, sign in ((1, gain > 0), (2, gain < 0)):
        np.add.at(counts[row], bin_of(step - start[sign] + 1), 1)
    return Histograms.from_counts(counts, step)
