"""The merge of the spread of the momentum: column sums carried from shard to shard.

The spread of the momentum (:func:`~warpratchet.transport._diffusion.spread_moments`) sums each
group's column row after row: a chain of tasks, shard after shard (:func:`_spread_link`),
carries the column sums on (:func:`_fold`), once for the means and once for the squared
deviations.
"""

from __future__ import annotations

import numpy as np

from ._passes import _point_state
from ._shard import ShardRecord


def _fold_into(acc: np.ndarray, started: np.ndarray, columns: slice, values: np.ndarray) -> None:
    """One row of NumPy's column sum: ``acc + values`` where a column has begun, else ``values``."""
    acc[columns] = np.where(started[columns], acc[columns] + values, values)
    started[columns] = True


def _fold(acc: np.ndarray, started: np.ndarray, values: np.ndarray, lo: int, tail: int | None) -> None:
    """Continue the column sums ``acc`` (:func:`~warpratchet.transport._diffusion.spread_moments`'
    ``np.add.reduce(..., axis=0)`` of the points laid out ``(points / G, G)``) with points
    ``lo, lo + 1, ...`` (``values``): NumPy adds row after row there, so the sums of a shard go on
    from those of the shards before it, one elementwise addition per point as on one machine.
    ``tail``: with the last shard, the ensemble's size, whose last row is padded with +0.0."""
    groups = acc.shape[0]
    i = 0
    off = lo % groups
    if off and len(values):
        i = min(groups - off, len(values))
        _fold_into(acc, started, slice(off, off + i), values[:i])
    full = (len(values) - i) // groups
    if full:
        block = values[i : i + full * groups].reshape(full, groups)
        if not started.all():
            _fold_into(acc, started, slice(0, groups), block[0])
            block = block[1:]
        if len(block):
            acc[:] = np.add.reduce(np.concatenate([acc[None], block]), axis=0)
        i += full * groups
    if i < len(values):
        _fold_into(acc, started, slice(0, len(values) - i), values[i:])
    if tail is not None and tail % groups:
        _fold_into(acc, started, slice(tail % groups, groups), np.zeros(groups - tail % groups))


def _spread_link(record: ShardRecord, rows: list, carried: tuple | None, points: int, means) -> tuple:
    """A Dask task, one link of a chain over the shards in order: the spread's column sums at each
    ``(k, step, limit)`` of ``rows`` carried on over ``record``'s points: with ``means`` None the
    chaotic points' counts and gains, else their squared deviations from ``means`` (shape
    ``(rows, G)``), by :func:`~warpratchet.transport._diffusion.spread_moments`' own elementwise code."""
    from ..transport._diffusion import _chaotic_gains
    from ..transport._fits import GROUPS

    if carried is None:
        carried = (np.zeros((len(rows), GROUPS)), np.zeros((len(rows), GROUPS), bool),
                   np.zeros((len(rows), GROUPS), np.int64))  # fmt: skip
    acc, started, counts = (x.copy() for x in carried)
    m = record.hi - record.lo
    columns = (record.lo + np.arange(m)) % GROUPS
    for j, (k, step, limit) in enumerate(rows):
        gain, stretch = record.row(k)
        gains, mask = np.zeros(m), np.zeros(m, dtype=bool)
        _chaotic_gains(_point_state(gain, stretch), step, limit, gains, mask, None, 0, m)
        if means is None:
            counts[j] += np.bincount(columns[mask], minlength=GROUPS)
        else:
            np.copyto(gains, (gains - means[j][columns]) ** 2, where=mask)
        _fold(acc[j], started[j], gains, record.lo, points if record.hi == points else None)
    return acc, started, counts
