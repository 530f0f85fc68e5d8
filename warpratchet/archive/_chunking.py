"""When an archived run writes: chunk length, checkpoint interval, and advancing to a total step.

Chunk ends are where the run loop calls the sink, so they must land on every snapshot and
checkpoint step; :func:`schedule` picks a chunk length that does, and :func:`run_to` continues a
run to a *total* step count with chunk ends on the same global steps as an uninterrupted run
(:meth:`~warpratchet.ensemble.Ensemble.run` ends chunks at global multiples of ``chunk_steps``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable

from ..ensemble import STATE_FIELDS, Ensemble, Observer, default_chunk_steps
from ..errors import ParameterError, check_count, check_optional
from ..limits import MAX_STEP
from ..observables import summarize
from ..spec import CHECKPOINT_SECONDS

__all__ = [
    "CHECKPOINT_CHUNKS",
    "CHECKPOINT_SECONDS",
    "MIN_ARCHIVE_CHUNK_STEPS",
    "ARCHIVE_CHUNK_POINT_STEPS",
    "ROW_SHARE",
    "schedule",
    "sink_min_chunk_steps",
    "sink_schedule",
    "run_to",
]

#: Checkpoint every this many chunks by default: a checkpoint writes 56 bytes per point (the cost
#: of ~50 point-steps of the kernel) plus two fsyncs, so 8 chunks keep it well under 1% of the
#: kernel time while never losing more than ~8 chunks.
CHECKPOINT_CHUNKS = 8
#: Smallest default chunk while archiving when nothing is measured: one series row costs some
#: tens of point-steps per point (the summary of Eq. An and the FTLE), so chunks of >= 1024 steps
#: keep it to a few percent. :func:`sink_min_chunk_steps` measures instead.
MIN_ARCHIVE_CHUNK_STEPS = 1024
#: Point-steps of an archive's default chunk (:func:`schedule`): a quarter of a plain run's, so
#: that the series has rows at a finer cadence and a checkpoint (every :data:`CHECKPOINT_CHUNKS`
#: chunks) is never far behind, and a kill -9 loses little.
ARCHIVE_CHUNK_POINT_STEPS = 250_000_000
#: Largest share of the kernel time a series row may cost at the default chunk length: 0.5%,
#: so that the kernel may get several times faster before the archive costs more than a 5%
#: budget (benchmarks/archive_overhead.py).
ROW_SHARE = 0.005
#: Seconds of HDF5 work per series row besides the summary (eleven row writes, two flushes).
ROW_IO_SECONDS = 1e-3
#: Points and steps of the probe that measures the kernel against the summary.
_PROBE_POINTS, _PROBE_STEPS = 1 << 12, 64


def _nice_at_least(value: float) -> int:
    """The smallest of 1, 2, 5, 10, 20, 50, ... that is >= ``value`` (row steps people can read)."""
    decade = 10 ** max(0, math.floor(math.log10(max(value, 1.0))))
    for mantissa in (1, 2, 5, 10):
        if mantissa * decade >= value:
            return int(mantissa * decade)
    raise AssertionError("unreachable")  # pragma: no cover


def _best_seconds(work, repeat: int = 3) -> float:
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        best = min(best, time.perf_counter() - start)
    return best


def sink_min_chunk_steps(ensemble: Ensemble) -> int:
    """The shortest chunk whose series row costs at most :data:`ROW_SHARE` of its kernel time, measured.

    A row costs a summary of every point (Eqs. An and the FTLE, NumPy on one core) plus
    :data:`ROW_IO_SECONDS` of HDF5 work; a chunk costs ``points * chunk_steps`` kernel
    point-steps on ``ensemble.threads`` threads. Both speeds are measured on one thread, once per
    process, kind of ensemble, device and map (:func:`_seconds_per_point`, on a copy of up
    to 4096 of the ensemble's points; the kernel's time is then shared by the threads), so the
    chunk follows the kernel: a 3x faster kernel gets 3x longer default chunks instead of a 3x
    larger archive overhead. Rounded up to 1, 2 or 5 times a power of ten. The ensemble is not
    advanced.
    """
    summary, kernel = _seconds_per_point(ensemble)
    threads = max(1, min(ensemble.threads, ensemble.points))
    row = summary * ensemble.points + ROW_IO_SECONDS
    chunk_seconds_per_step = kernel * ensemble.points / threads
    return _nice_at_least(row / (ROW_SHARE * chunk_seconds_per_step))


def sink_schedule(
    ensemble: Ensemble, chunk_steps: int | None, snapshot_every: int, checkpoint_every: int | None
) -> tuple[int, int]:
    """:func:`schedule` for an archive of ``ensemble``: bad values refused before any measuring,
    then the default chunk no shorter than :func:`sink_min_chunk_steps`."""
    if chunk_steps is not None:
        return schedule(ensemble.points, chunk_steps, snapshot_every, checkpoint_every)
    schedule(ensemble.points, None, snapshot_every, checkpoint_every)  # bad values: no measuring
    floor = sink_min_chunk_steps(ensemble)
    return schedule(ensemble.points, None, snapshot_every, checkpoint_every, min_chunk_steps=floor)


_MEASURED: dict[tuple, tuple[float, float]] = {}


def _seconds_per_point(ensemble: Ensemble) -> tuple[float, float]:
    """``(summary seconds per point, kernel seconds per point-step on one thread)``, cached."""
    key = (type(ensemble), ensemble.device, ensemble.params)
    if key not in _MEASURED:
        n = min(ensemble.points, _PROBE_POINTS)
        state = {name: ensemble.array(name)[:n].copy() for name in STATE_FIELDS}
        probe = Ensemble.from_state(ensemble.params, state, ensemble.step, device=ensemble.device, threads=1)
        probe.run(_PROBE_STEPS, chunk_steps=_PROBE_STEPS)  # loads the kernel before timing it
        run = _best_seconds(lambda: probe.run(_PROBE_STEPS, chunk_steps=_PROBE_STEPS))
        sample = probe.state()
        step = max(probe.step, 1)
        summary = _best_seconds(lambda: _quiet_summary(sample, step)) / n
        _MEASURED[key] = (summary, run / (n * _PROBE_STEPS))
    return _MEASURED[key]


def _quiet_summary(state, step) -> None:
    try:
        summarize(state, step)
    except FloatingPointError:  # the probe only times it
        pass


def _largest_divisor_at_most(n: int, cap: int) -> int:
    """The largest divisor of ``n`` not above ``cap``: divisors pair up as ``d * (n // d)``, so
    ``d`` up to ``min(cap, sqrt(n))`` finds each one at most ``cap`` (a few 10^5 trials at most,
    whatever ``n``; not up to sqrt(n), which for n near 2^63 is 3e9)."""
    best = 1
    for d in range(1, min(cap, math.isqrt(n)) + 1):
        if n % d == 0:
            best = max(best, d, n // d if n // d <= cap else 1)
    return best


def schedule(
    points: int,
    chunk_steps: int | None = None,
    snapshot_every: int = 0,
    checkpoint_every: int | None = None,
    *,
    min_chunk_steps: int = MIN_ARCHIVE_CHUNK_STEPS,
) -> tuple[int, int]:
    """Chunk length and checkpoint interval whose chunk ends land on every snapshot and checkpoint.

    Parameters
    ----------
    points : int
        Ensemble size.
    chunk_steps : int, optional
        Steps per chunk; must divide ``snapshot_every`` and ``checkpoint_every`` when given.
        Default: the largest divisor of their gcd not above ``max(default_chunk_steps(points,
        ARCHIVE_CHUNK_POINT_STEPS), min_chunk_steps)``.
    snapshot_every : int
        Steps between snapshots (0: none).
    checkpoint_every : int, optional
        Steps between checkpoints; default ``CHECKPOINT_CHUNKS * chunk_steps``.
    min_chunk_steps : int
        The default chunk is at least this long (where the intervals allow it):
        :func:`sink_min_chunk_steps` measured, or :data:`MIN_ARCHIVE_CHUNK_STEPS`.

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
    snapshot_every = check_count("snapshot_every", snapshot_every, 0, MAX_STEP)
    checkpoint_every = check_optional(check_count, "checkpoint_every", checkpoint_every, 1, MAX_STEP)
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
        own = default_chunk_steps(points, ARCHIVE_CHUNK_POINT_STEPS)
        cap = max(own, check_count("min_chunk_steps", min_chunk_steps, 1))
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
