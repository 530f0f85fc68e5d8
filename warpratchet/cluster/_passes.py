"""The merge's passes over the shards' records: the summary and the history's variances.

The summary (Eq. An's mean over the chaotic points and its standard error) and the history's
variances are two-pass reductions (means first, then deviations from them) over the
:data:`~warpratchet.observables.SUMMARY_CHUNK` blocks of the ensemble: NumPy's pairwise sum
within a block, then the blocks' sums in order. The merge runs two rounds of tasks where the
records are: each shard reduces the blocks that lie wholly in it (:func:`_shard_pass`,
:func:`~warpratchet.observables.chunk_sums`), a block that two shards share is reduced by a task
handed the records of its points alone (:func:`_raw`, :func:`_boundary_pass`); the client adds
the blocks' sums in order as :func:`~warpratchet.observables.summarize` does, sends the means
back, and the second round sums the deviations (:func:`~warpratchet.observables.chunk_squares`).
The FTLE is ``stretch / n`` and ``A_n`` is ``gain / n``, the very operations of
:func:`~warpratchet.observables.lyapunov` and
:func:`~warpratchet.observables.finite_time_acceleration` (:func:`_point_state`).
"""

from __future__ import annotations

import numpy as np

from .. import observables as _obs
from ..observables import momentum_gain
from ._shard import ShardRecord


def _point_state(gain: np.ndarray, stretch: np.ndarray) -> dict[str, np.ndarray]:
    """A state whose :func:`~warpratchet.observables.momentum_gain` is ``gain`` and whose
    :func:`~warpratchet.observables.lyapunov` at ``n`` is ``stretch / n``, bit for bit.

    ``gain + (0.0 - (0.0 - 0.0))`` is ``gain`` and ``stretch + log(hypot(1, 0))`` is ``stretch``;
    the constant fields are broadcast views, no memory.
    """
    zero = np.broadcast_to(0.0, gain.shape)
    one = np.broadcast_to(1.0, gain.shape)
    return {"winding": gain, "q": zero, "p0": zero, "dx": one, "dp": zero, "log_stretch": stretch}


def _chunk_values(gain: np.ndarray, stretch: np.ndarray, step: int):
    """FTLE, ``A_n`` and ``p_n - p_0`` of a chunk's points from their records, by the single
    machine's own functions (:func:`_point_state`)."""
    state = _point_state(gain, stretch)
    ftle, acc = _obs._per_point(state, step, 0, len(gain))
    return ftle, acc, momentum_gain(state)


def _chunk_pass(gain, stretch, step: int, limit: float, means) -> tuple:
    """One chunk's part of a row: pass 1 (``means`` None) the summary's :func:`chunk_sums
    <warpratchet.observables.chunk_sums>` and the gains' sum; pass 2 the :func:`chunk_squares
    <warpratchet.observables.chunk_squares>` and the gains' squared deviations (History's
    ``var_dp_all``, :func:`warpratchet.history._variance`)."""
    ftle, acc, dp = _chunk_values(gain, stretch, step)
    if means is None:
        return (*_obs.chunk_sums(ftle, acc, limit), float(np.add.reduce(dp)))
    a_mean, ftle_mean, dp_mean = means
    d = dp - dp_mean
    return (*_obs.chunk_squares(ftle, acc, limit, a_mean, ftle_mean), float(np.add.reduce(d * d)))


def _shard_pass(record: ShardRecord, rows: list, chunks: list, means: dict | None) -> dict:
    """A Dask task: the :func:`_chunk_pass` of every ``(index, lo, hi)`` of ``chunks`` (chunks wholly
    in ``record``'s points) at every ``(k, step, limit)`` of ``rows``; keys ``(k, index)``."""
    parts = {}
    for k, step, limit in rows:
        gain, stretch = record.row(k)
        for c, lo, hi in chunks:
            a, b = lo - record.lo, hi - record.lo
            parts[k, c] = _chunk_pass(
                gain[a:b], stretch[a:b], step, limit, None if means is None else means[k]
            )
    return parts


def _raw(record: ShardRecord, rows: list, lo: int, hi: int) -> list:
    """A Dask task: the records of points ``lo <= i < hi`` (within ``record``) at each of ``rows``."""
    out = []
    for k, _, _ in rows:
        gain, stretch = record.row(k)
        out.append(
            (gain[lo - record.lo : hi - record.lo].copy(), stretch[lo - record.lo : hi - record.lo].copy())
        )
    return out


def _boundary_pass(rows: list, c: int, means: dict | None, *pieces: list) -> dict:
    """A Dask task: :func:`_chunk_pass` of chunk ``c``, whose points lie in several shards
    (``pieces``: their :func:`_raw` records, in order)."""
    parts = {}
    for j, (k, step, limit) in enumerate(rows):
        gain = np.concatenate([p[j][0] for p in pieces])
        stretch = np.concatenate([p[j][1] for p in pieces])
        parts[k, c] = _chunk_pass(gain, stretch, step, limit, None if means is None else means[k])
    return parts
