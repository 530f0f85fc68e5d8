"""The ``/snapshots`` group: phase-space snapshots of a fixed random subsample of points.

The subsample (:func:`snapshot_indices`) is drawn once, from the run's seed and a salt of its
own, and stored with the archive; every snapshot (:func:`snapshot_row`) holds those points'
``x``, ``p`` mod 1, FTLE and ``A_n`` (Eqs. cpem, An); :func:`read_snapshots` returns the valid
rows as :class:`Snapshots`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np

from ..ensemble import STATE_FIELDS
from ..observables import finite_time_acceleration, lyapunov
from ..sampling import salted_subsample
from .checks import check_extent, reading, valid_rows
from .checks import refresh as _refresh
from .names import SNAPSHOT_FIELDS, ArchiveError

__all__ = ["Snapshots", "read_snapshots", "snapshot_indices", "snapshot_row"]

#: Salt of the snapshot subsample's generator, so it differs from the sampler's stream.
_SNAPSHOT_SALT = 0x5A4E


@dataclass(frozen=True)
class Snapshots:
    """Phase-space snapshots of a fixed random subsample of ``M`` points.

    Attributes
    ----------
    steps : ndarray, shape (S,), int64
        Iteration numbers of the snapshots.
    indices : ndarray, shape (M,), int64
        Indices of the sampled points in the ensemble (sorted).
    x, p : ndarray, shape (S, M)
        Position and momentum mod 1, both in ``[0, 1)`` (Eq. cpem on the torus).
    ftle : ndarray, shape (S, M)
        Finite-time Lyapunov exponent per iteration.
    A : ndarray, shape (S, M)
        Mean acceleration ``A_n`` of Eq. (An), per iteration.
    """

    steps: np.ndarray
    indices: np.ndarray
    x: np.ndarray
    p: np.ndarray
    ftle: np.ndarray
    A: np.ndarray

    def __len__(self) -> int:
        return int(self.steps.size)


def snapshot_indices(points: int, m: int, seed: int | None) -> np.ndarray:
    """The sorted int64 indices of ``m`` of ``points`` points, fixed by ``seed`` (None as 0)."""
    return salted_subsample(points, seed, m, _SNAPSHOT_SALT)


def snapshot_row(live: dict[str, np.ndarray], indices: np.ndarray, step: int) -> dict[str, Any]:
    """The snapshot at ``step`` of the points ``indices`` of the state ``live``."""
    sub = {name: live[name][indices] for name in STATE_FIELDS}
    return {
        "step": step,
        "x": sub["x"],
        "p": sub["q"],  # p mod 1 is exactly q
        "ftle": lyapunov(sub, step),
        "A": finite_time_acceleration(sub, step),
    }


def read_snapshots(path: str, f: h5py.File, n: int) -> Snapshots:
    """The first ``n`` (valid) snapshots of the archive ``f`` at ``path``."""
    with reading(path, "/snapshots"):
        g = f["snapshots"]
        indices = _refresh(g["indices"])[:]
        check_extent(path, g["indices"])
    fields = {"steps": valid_rows(path, g, "step", n), "indices": indices}
    for name in SNAPSHOT_FIELDS:
        rows = valid_rows(path, g, name, n)
        if n and rows.shape[1] != indices.size:
            raise ArchiveError(f"{path}: /snapshots/{name} has shape {rows.shape}, expected ({n}, M)")
        fields[name] = rows.reshape(n, indices.size)
    return Snapshots(**fields)
