"""When an archived run writes: chunk length, checkpoint interval, and advancing to a total step.

Chunk ends are where the run loop calls the sink, so they must land on every snapshot and
checkpoint step; :func:`schedule` picks a chunk length that does, and :func:`run_to` continues a
run to a *total* step count with chunk ends on the same global steps as an uninterrupted run
(:meth:`~warpratchet.ensemble.Ensemble.run` ends chunks at global multiples of ``chunk_steps``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from ..ensemble import Ensemble, Observer, default_chunk_steps
from ..errors import ParameterError, check_count, check_optional

__all__ = ["CHECKPOINT_CHUNKS", "MIN_ARCHIVE_CHUNK_STEPS", "schedule", "run_to"]

#: Checkpoint every this many chunks by default: a checkpoint writes 56 bytes per point (the cost
#: of ~50 point-steps of the kernel) plus two fsyncs, so 8 chunks keep it well under 1% of the
#: kernel time while never losing more than ~8 chunks (a few seconds at the default chunk).
CHECKPOINT_CHUNKS = 8
#: Smallest default chunk while archiving: one series row costs ~25 point-steps per point
#: (the summary of Eq. An and the FTLE), so chunks of >= 1024 steps keep it below ~3%.
MIN_ARCHIVE_CHUNK_STEPS = 1024


def _largest_divisor_at_most(n: int, cap: int) -> int:
    best = 1
    d = 1
    while d * d <= n:
        if n % d == 0:
            for c in (d, n // d):
                if best < c <= cap:
                    best = c
        d += 1
    return best


def schedule(
    points: int,
    chunk_steps: int | None = None,
    snapshot_every: int = 0,
    checkpoint_every: int | None = None,
) -> tuple[int, int]:
    """Chunk length and checkpoint interval whose chunk ends land on every snapshot and checkpoint.

    Parameters
    ----------
    points : int
        Ensemble size.
    chunk_steps : int, optional
        Steps per chunk; must divide ``snapshot_every`` and ``checkpoint_every`` when given.
        Default: the largest divisor of their gcd not above ``max(default_chunk_steps(points),
        MIN_ARCHIVE_CHUNK_STEPS)``.
    snapshot_every : int
        Steps between snapshots (0: none).
    checkpoint_every : int, optional
        Steps between checkpoints; default ``CHECKPOINT_CHUNKS * chunk_steps``.

    Returns
    -------
    (chunk_steps, checkpoint_every) : tuple of int

    Raises
    ------
    ParameterError
        If an explicit ``chunk_steps`` does not divide the intervals, or if the intervals only
        admit chunks so short that the run would crawl.
    """
    points = check_count("points", points, 1)
    snapshot_every = check_count("snapshot_every", snapshot_every, 0)
    checkpoint_every = check_optional(check_count, "checkpoint_every", checkpoint_every, 1)
    intervals = {
        name: v
        for name, v in (("snapshot_every", snapshot_every), ("checkpoint_every", checkpoint_every))
        if v
    }
    if chunk_steps is not None:
        chunk_steps = check_count("chunk_steps", chunk_steps, 1)
        bad = {name: v for name, v in intervals.items() if v % chunk_steps}
        if bad:
            listed = " and ".join(f"{name} = {v}" for name, v in bad.items())
            raise ParameterError(
                f"chunk_steps = {chunk_steps} must divide {listed} (chunk ends must land on them)"
            )
    else:
        cap = max(default_chunk_steps(points), MIN_ARCHIVE_CHUNK_STEPS)
        if intervals:
            g = math.gcd(*intervals.values())
            chunk_steps = _largest_divisor_at_most(g, cap)
            if 16 * chunk_steps < min(g, cap):
                listed = " and ".join(f"{name} = {v}" for name, v in intervals.items())
                raise ParameterError(
                    f"{listed} only allow chunks of {chunk_steps} steps (want about {min(g, cap)}); "
                    "choose intervals with small factors (e.g. multiples of 1000) or pass chunk_steps"
                )
        else:
            chunk_steps = cap
    if checkpoint_every is None:
        checkpoint_every = CHECKPOINT_CHUNKS * chunk_steps
    return chunk_steps, checkpoint_every


def run_to(
    ensemble: Ensemble,
    target_step: int,
    observers: Iterable[Observer] = (),
    chunk_steps: int | None = None,
) -> Ensemble:
    """Advance ``ensemble`` to the global step ``target_step`` (not by it: resume's total).

    :meth:`Ensemble.run` ends chunks at global multiples of ``chunk_steps``, so a resumed run's
    series rows, snapshots and checkpoints land on the same steps as an uninterrupted run's.
    """
    target_step = check_count("target_step", target_step, ensemble.step)
    return ensemble.run(target_step - ensemble.step, observers, chunk_steps)
