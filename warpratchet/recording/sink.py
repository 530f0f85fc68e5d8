"""Recording a run as it goes: :class:`RecordingSink`, an observer of :meth:`Ensemble.run`.

The sink draws a fixed random subsample of the ensemble every ``every`` steps (default
:func:`frame_every`, from a cost model measured by ``benchmarks/recording_overhead.py``) into a
:class:`~warpratchet.recording.stream.PhaseSpaceRecording`, with the ensemble summary of
:func:`~warpratchet.observables.summarize`. Recording never changes the run's results.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..ensemble import STATE_FIELDS, Ensemble, Observer
from ..errors import check_choice, check_count, check_optional
from ..observables import Summary, acceleration, default_lyapunov_threshold, lyapunov, summarize
from .scene import COLOR_BY, require_rerun
from .stream import PhaseSpaceRecording, check_new_file

__all__ = ["DEFAULT_MAX_POINTS", "DEFAULT_MAX_FRAMES", "frame_every", "RecordingSink"]

#: Default subsample size: ~1.2 MB per frame (float32 positions, RGBA colours), dense enough to
#: show the islands as holes in a view of ~10^3 pixels across.
DEFAULT_MAX_POINTS = 100_000
#: Default cap on the number of frames of a run (keeps a default recording below ~150 MB).
DEFAULT_MAX_FRAMES = 100

# Cost model of one frame, measured with benchmarks/recording_overhead.py on the 2-core CPU:
# ~2 ms fixed, ~45 ns per recorded point (gather, FTLE, colours, serialisation) and ~35 ns per
# ensemble point (the full-ensemble summary). At ~9e8 point-steps/s, keeping a frame below 5% of the
# run time between frames (half the 10% budget, for noise and file writing) needs an interval
# of at least 20 x 9e8 x cost point-steps.
_NS_PER_RECORDED_POINT = 45.0
_NS_PER_ENSEMBLE_POINT = 35.0
_FRAME_FIXED_SECONDS = 2.0e-3
_POINT_STEPS_PER_SECOND = 9.0e8
_OVERHEAD_BUDGET = 0.05


def frame_every(
    points: int,
    steps: int,
    max_points: int = DEFAULT_MAX_POINTS,
    max_frames: int = DEFAULT_MAX_FRAMES,
) -> int:
    """Default steps between frames of a live recording.

    The larger of (i) the interval after which one frame (``min(points, max_points)`` recorded
    points plus a summary of all ``points``) costs at most 5% of the CPU run time, from the cost
    model measured by ``benchmarks/recording_overhead.py``, and (ii) ``steps / max_frames``.
    On a GPU the run is faster and the same interval costs relatively more: pass ``every``.

    Parameters
    ----------
    points : int
        Ensemble size.
    steps : int
        Iterations of the run.
    max_points : int
        Points drawn per frame (the subsample size ``M``).
    max_frames : int
        Upper bound on the number of frames (besides the first and the last).

    Returns
    -------
    int
        Steps between frames, ``>= 1``. Examples on 2 CPU cores: 10^4 points x 1.2e5 steps ->
        5041 (25 frames); 10^6 points x 1200 steps -> 748.
    """
    recorded = min(points, max_points)
    frame_seconds = (
        _NS_PER_RECORDED_POINT * 1e-9 * recorded
        + _NS_PER_ENSEMBLE_POINT * 1e-9 * points
        + _FRAME_FIXED_SECONDS
    )
    by_cost = math.ceil(frame_seconds * _POINT_STEPS_PER_SECOND / (_OVERHEAD_BUDGET * points))
    by_count = math.ceil(steps / max_frames) if max_frames > 0 else 1
    return max(1, by_cost, by_count)


class RecordingSink(Observer):
    """An :class:`~warpratchet.ensemble.Observer` recording a run as it goes.

    A frame (the cloud of a fixed subsample plus the ensemble summary of
    :func:`~warpratchet.observables.summarize`) is logged when the run starts, after every chunk
    that reaches the next multiple of ``every`` steps, and when it ends. Frames can only fall on
    chunk boundaries: run with ``chunk_steps=sink.every`` (what ``warpratchet run --rerun``
    does) for frames at exact multiples. Recording never changes the run's results.

    Parameters
    ----------
    path : str or Path, optional
        ``.rrd`` file (must not exist).
    spawn : bool
        Stream to a newly spawned viewer as well (needs a display).
    max_points : int
        Subsample size ``M``: at most this many points are drawn per frame, the same points in
        every frame (chosen once with ``seed``).
    every : int, optional
        Steps between frames; default :func:`frame_every` of the run (set at the first
        :meth:`begin`).
    color_by : {"ftle", "class"}
        See :class:`PhaseSpaceRecording`.
    threshold : float, optional
        Chaos threshold for the summary and the classes (default
        :func:`~warpratchet.observables.default_lyapunov_threshold`).
    seed : int
        Seed of the subsample.
    **options
        Passed to :class:`PhaseSpaceRecording` (``ftle_range``, ``trail``, ``title``, ``info``).

    Attributes
    ----------
    summaries : list of Summary
        The summaries logged, in order (one per frame after step 0).
    frame_seconds : list of float
        Wall time spent in each :meth:`log_frame` (the recording's cost to the run).
    indices : ndarray, shape (M,)
        Indices of the recorded points (set at the first frame).
    """

    def __init__(
        self,
        path: str | Path | None = None,
        *,
        spawn: bool = False,
        max_points: int = DEFAULT_MAX_POINTS,
        every: int | None = None,
        color_by: Literal["ftle", "class"] = "ftle",
        threshold: float | None = None,
        seed: int = 0,
        **options: Any,
    ) -> None:
        self.max_points = check_count("max_points", max_points, 1)
        self.every = check_optional(check_count, "every", every, 1)
        self.color_by = check_choice("color_by", color_by, COLOR_BY)
        if path is None and not spawn:
            raise ValueError("a recording needs a path, spawn=True, or both")
        if path is not None:
            check_new_file(path)  # here as well, so that a bad path fails before the run
        require_rerun()
        self.path = path
        self.spawn = spawn
        self.threshold = threshold
        self.seed = seed
        self.options = options
        self.summaries: list[Summary] = []
        self.frame_seconds: list[float] = []
        self.indices: np.ndarray | None = None
        self.recording: PhaseSpaceRecording | None = None
        self._next_frame = 0

    @property
    def frames(self) -> list[int]:
        """Steps of the frames logged so far."""
        return [] if self.recording is None else list(self.recording.frames)

    def open(self, ensemble: Ensemble) -> None:
        """Open the recording for ``ensemble`` (done by :meth:`begin`; idempotent)."""
        if self.recording is not None:
            if self.recording.closed:
                raise ValueError("this RecordingSink is closed (it records one run): make a new one")
            return
        n = ensemble.points
        if n <= self.max_points:
            self.indices = np.arange(n)
        else:
            # Sorted, so that gathering walks memory forwards.
            rng = np.random.default_rng(self.seed)
            self.indices = np.sort(rng.choice(n, size=self.max_points, replace=False))
        info = {
            "points": f"{n} ({ensemble.sampler}, seed {ensemble.seed})",
            "recorded points": f"{len(self.indices)} (fixed subsample, seed {self.seed})",
            "chaos threshold": "10 (1 + ln n)/n" if self.threshold is None else self.threshold,
        }
        info.update(self.options.pop("info", {}) or {})
        self.recording = PhaseSpaceRecording(
            ensemble.params, self.path, spawn=self.spawn, color_by=self.color_by, info=info, **self.options
        )

    def log_frame(self, ensemble: Ensemble) -> None:
        """Log the cloud and (after step 0) the summary of ``ensemble`` at its current step."""
        start = time.perf_counter()
        self._log_frame(ensemble)
        self.frame_seconds.append(time.perf_counter() - start)

    def _log_frame(self, ensemble: Ensemble) -> None:
        self.open(ensemble)
        assert self.recording is not None and self.indices is not None
        step = ensemble.step
        # Zero-copy views on the CPU; only the subsample and the summary are computed from them.
        state = {name: ensemble.array(name) for name in STATE_FIELDS}
        whole = len(self.indices) == ensemble.points
        sub = state if whole else {k: v[self.indices] for k, v in state.items()}
        if step == 0:
            self.recording.log_cloud(0, sub["x"], sub["q"])
            return
        ftle = lyapunov(sub, step)
        acc = acceleration(sub, step) if self.color_by == "class" else None
        threshold = self.threshold if self.threshold is not None else default_lyapunov_threshold(step)
        self.recording.log_cloud(step, sub["x"], sub["q"], ftle, acc, threshold)
        summary = summarize(state, step, self.threshold)
        self.recording.log_summary(step, summary.as_dict())
        self.summaries.append(summary)

    def close(self) -> None:
        """Flush and close the recording (idempotent)."""
        if self.recording is not None:
            self.recording.close()

    # -- Observer -------------------------------------------------------------------------------
    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        if self.every is None:
            self.every = frame_every(ensemble.points, target_step - ensemble.step, self.max_points)
        if not self.frames or self.frames[-1] != ensemble.step:
            self.log_frame(ensemble)
        self._next_frame = (ensemble.step // self.every + 1) * self.every

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        if ensemble.step >= self._next_frame:
            self.log_frame(ensemble)
            self._next_frame = (ensemble.step // self.every + 1) * self.every

    def end(self, ensemble: Ensemble) -> None:
        if self.frames and self.frames[-1] != ensemble.step:
            self.log_frame(ensemble)
        self.close()
