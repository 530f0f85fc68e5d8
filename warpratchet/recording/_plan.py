"""Which steps of a run get a frame, and how many points a frame draws: the size and time budgets.

A recording is meant to show the spreading of the cloud, which is over within a few hundred
steps, and then the slow settling of ``A_n`` (Eq. An) onto the theory. So by default frames are
*log-spaced* in the step (dense early, sparse late), and their number and size obey two budgets:

* **size**: the file stays below ``max_bytes`` (default 10 MB). A frame of ``M`` points costs
  :data:`BYTES_PER_POINT` bytes per point (float32 ``x, p`` and an RGBA colour)
  plus :data:`BYTES_PER_FRAME`; when ``frames x M`` does not fit, fewer points are drawn (down to
  what two frames allow), and with a fixed ``every`` the interval is widened instead.
* **time**: frames cost at most :data:`OVERHEAD_BUDGET` of the run's kernel time (or
  :data:`MIN_FRAME_SECONDS`, whichever is more). A frame's cost
  is CPU work (gather, FTLE, colours, serialisation, the ensemble summary), modelled in
  :func:`frame_seconds` from ``benchmarks/recording_overhead.py``; the kernel's time comes from
  its *measured* speed (:func:`probe_throughput`), so a faster kernel or a GPU gets fewer frames,
  never a slower run.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import check_count

__all__ = [
    "DEFAULT_MAX_BYTES",
    "DEFAULT_MAX_POINTS",
    "DEFAULT_MAX_FRAMES",
    "BYTES_PER_POINT",
    "BYTES_PER_FRAME",
    "BYTES_FIXED",
    "OVERHEAD_BUDGET",
    "MIN_FRAME_SECONDS",
    "Plan",
    "frame_seconds",
    "frame_every",
    "log_spaced",
    "probe_throughput",
    "points_within_budget",
    "plan_frames",
]

#: Default size budget of one recording, bytes (``--rerun-max-mb 10``).
DEFAULT_MAX_BYTES = 10_000_000
#: Default points per frame: 20000 show the islands as holes in a view ~10^3 pixels across, and
#: leave room for ~40 frames in the default budget.
DEFAULT_MAX_POINTS = 20_000
#: Most frames of a run by default (besides the first).
DEFAULT_MAX_FRAMES = 100
#: Bytes per recorded point and frame (float32 x, p and an RGBA colour: 12 B raw).
BYTES_PER_POINT = 12
#: Bytes per frame besides the points (the series row, time stamps; an upper bound).
BYTES_PER_FRAME = 4096
#: Bytes of a recording besides its frames (blueprint, parameters, styles; an upper bound).
BYTES_FIXED = 65_536
#: Share of the size budget kept for the series rows logged between frames.
SERIES_SHARE = 0.05
#: Bytes of one series row between frames (six scalars; an upper bound).
BYTES_PER_SERIES_ROW = 512
#: Largest share of the run's kernel time spent on frames (half of 10%, for noise and I/O)...
OVERHEAD_BUDGET = 0.05
#: ... or this many seconds, whichever is more: a short run still gets a few early frames
#: (~9 of 10^4 points), at a cost no one waits for.
MIN_FRAME_SECONDS = 0.02

# Cost model of one frame on the CPU, fitted to benchmarks/recording_overhead.py (benchmarks/README.md):
# a fixed cost, a cost per recorded point (gather, FTLE, colours, serialisation) and one per
# ensemble point (the full-ensemble summary). It does not depend on the kernel.
_NS_PER_RECORDED_POINT = 45.0
_NS_PER_ENSEMBLE_POINT = 35.0
_FRAME_FIXED_SECONDS = 2.0e-3
# Only frame_every (a fixed cadence) assumes a kernel speed.
_POINT_STEPS_PER_SECOND = 9.0e8


def frame_seconds(recorded: int, points: int) -> float:
    """Modelled seconds of one frame: ``recorded`` points drawn, a summary over ``points``."""
    return _FRAME_FIXED_SECONDS + 1e-9 * (_NS_PER_RECORDED_POINT * recorded + _NS_PER_ENSEMBLE_POINT * points)


def frame_every(
    points: int,
    steps: int,
    max_points: int = DEFAULT_MAX_POINTS,
    max_frames: int = DEFAULT_MAX_FRAMES,
) -> int:
    """A fixed interval between frames: the larger of the cost interval and ``steps / max_frames``.

    The cost interval keeps a frame below 5% of the run time between frames at an assumed 9e8
    point-steps/s; :func:`plan_frames` measures the speed instead. Returns ``>= 1``.
    """
    frame = frame_seconds(min(points, max_points), points)
    by_cost = math.ceil(frame * _POINT_STEPS_PER_SECOND / (OVERHEAD_BUDGET * points))
    by_count = math.ceil(steps / max_frames) if max_frames > 0 else 1
    return max(1, by_cost, by_count)


def log_spaced(n: int, count: int) -> list[int]:
    """``count`` strictly increasing integers in ``[1, n]``, ending at ``n``, as log-spaced as whole
    numbers allow (consecutive at first, where ``n^(k/count)`` grows by less than 1 per frame)."""
    n, count = int(n), min(int(count), int(n))
    out: list[int] = []
    for k in range(1, count + 1):
        ideal = round(n ** (k / count))
        out.append(min(max(out[-1] + 1 if out else 1, ideal), n - (count - k)))
    return out


def probe_throughput(ensemble: Any, point_steps: float = 1.0e7) -> float:
    """The ensemble's kernel speed, point-steps per second, measured on a copy of its first points.

    A copy (same class, device and threads) of at most 65536 points (2^20 on a GPU, which needs
    many points to be busy) is advanced by ``point_steps`` in one chunk.
    The ensemble itself is not touched.
    """
    from ..ensemble import STATE_FIELDS

    cap = 1 << 16 if str(ensemble.device).startswith("cpu") else 1 << 20
    m = min(ensemble.points, cap)
    state = {name: np.array(ensemble.array(name)[:m]) for name in STATE_FIELDS}
    copy = type(ensemble).from_state(
        ensemble.params, state, ensemble.step, device=ensemble.device, threads=ensemble.threads
    )
    steps = max(8, int(point_steps // m))
    start = time.perf_counter()
    copy.run(steps, chunk_steps=steps)
    return m * steps / max(time.perf_counter() - start, 1e-9)


def points_within_budget(frames: int, points: int, max_points: int, max_bytes: int) -> int:
    """Most points per frame (at most ``min(points, max_points)``) for which ``frames`` frames fit
    in ``max_bytes`` (:data:`BYTES_PER_POINT` each, plus :data:`BYTES_PER_FRAME` per frame and
    :data:`BYTES_FIXED`, with :data:`SERIES_SHARE` of the budget left for series rows).

    Raises
    ------
    ValueError
        If not even one point per frame fits.
    """
    frames_bytes = max_bytes * (1.0 - SERIES_SHARE) - BYTES_FIXED
    m = int((frames_bytes / max(frames, 1) - BYTES_PER_FRAME) // BYTES_PER_POINT)
    if m < 1:
        need = (frames * (BYTES_PER_POINT + BYTES_PER_FRAME) + BYTES_FIXED) / (1.0 - SERIES_SHARE)
        raise ValueError(
            f"max_bytes = {max_bytes} is outside the allowed range for {frames} frames: >= {math.ceil(need)}"
        )
    return min(points, max_points, m)


@dataclass(frozen=True)
class Plan:
    """What a recording of one run draws.

    Attributes
    ----------
    points : int
        Points per frame ``M``.
    steps : tuple of int
        Global steps of the frames, increasing, from the run's start to its target.
    series_rows : int
        Most series rows logged between frames (their share of the size budget).
    reason : str
        Which budget set the frame count (for the recording's parameters document).
    seconds : float or None
        The time budget of all frames (None: no time budget).
    """

    points: int
    steps: tuple[int, ...]
    series_rows: int
    reason: str
    seconds: float | None = None

    def thinned(self, after: int, spent: float, frame_cost: float, seconds: float | None = None) -> Plan:
        """This plan with the frames after step ``after`` thinned to what the time budget
        (``seconds``, default :attr:`seconds`) still pays for at ``frame_cost`` seconds a frame,
        ``spent`` being used already; the last frame is always kept.

        The sink calls this with the *measured* cost of its frames and speed of the kernel: on a
        loaded machine a frame costs more than the model says, and the run must not pay for it.
        """
        seconds = self.seconds if seconds is None else min(seconds, self.seconds or seconds)
        if seconds is None:
            return self
        done = [s for s in self.steps if s <= after]
        todo = [s for s in self.steps if s > after]
        afford = max(1, int((seconds - spent) // frame_cost))
        if afford >= len(todo):
            return self
        picks = np.unique(np.round(np.linspace(len(todo) - 1, 0, afford)).astype(int))
        steps = (*done, *(todo[i] for i in picks))
        return Plan(self.points, steps, self.series_rows, self.reason + ", thinned", self.seconds)


def plan_frames(
    start: int,
    target: int,
    points: int,
    *,
    max_points: int = DEFAULT_MAX_POINTS,
    max_bytes: int = DEFAULT_MAX_BYTES,
    every: int | None = None,
    throughput: float | None = None,
    max_frames: int = DEFAULT_MAX_FRAMES,
) -> Plan:
    """The frames of a run from ``start`` to ``target`` of an ensemble of ``points`` points.

    Parameters
    ----------
    start, target : int
        First and last step of the run (both get a frame).
    points : int
        Ensemble size ``N``.
    max_points : int
        Most points per frame.
    max_bytes : int
        Size budget of the file, bytes.
    every : int, optional
        Frames at the global multiples of ``every`` (widened to fit the size budget) instead of
        log-spaced ones; the time budget is then the caller's.
    throughput : float, optional
        Kernel point-steps per second (:func:`probe_throughput`) for the time budget; None: no
        time budget (e.g. frames logged by hand).
    max_frames : int
        Most frames besides the first.

    Raises
    ------
    ValueError
        A budget too small for two frames of one point.
    """
    n = check_count("steps", target - start, 0)
    m = min(points, max_points)
    frames_bytes = max_bytes * (1.0 - SERIES_SHARE) - BYTES_FIXED
    fit = int(frames_bytes // (m * BYTES_PER_POINT + BYTES_PER_FRAME))
    if fit < 2:  # fewer points, so that at least the first and the last frame fit
        m, fit = points_within_budget(2, points, max_points, max_bytes), 2
    rows = int(max_bytes * SERIES_SHARE // BYTES_PER_SERIES_ROW)
    if n == 0:
        return Plan(m, (start,), rows, "no steps")
    if every is not None:
        every = check_count("every", every, 1)
        needed = len(range(start // every + 1, -(-target // every))) + 2  # start, multiples, target
        every *= max(1, math.ceil((needed - 2) / max(fit - 2, 1))) if needed > fit else 1
        inner = range((start // every + 1) * every, target, every)
        return Plan(m, (start, *inner, target), rows, f"every {every} steps")
    count, reason = min(fit - 1, max_frames), "size budget" if fit - 1 <= max_frames else "frame cap"
    allowed = None
    if throughput is not None:
        allowed = max(OVERHEAD_BUDGET * n * points / throughput, MIN_FRAME_SECONDS)
        by_time = int(allowed / frame_seconds(m, points))
        if by_time < count:
            count, reason = max(1, by_time), "time budget"
    steps = (start, *(start + offset for offset in log_spaced(n, count)))
    return Plan(m, steps, rows, f"{len(steps)} log-spaced frames ({reason})", allowed)
