"""Recording a run as it goes: :class:`RecordingSink`, an observer of :meth:`Ensemble.run`.

The sink draws a fixed random subsample of the ensemble at the frames of a :class:`~._plan.Plan`
(log-spaced steps within a size and a time budget, :mod:`._plan`) into a
:class:`~warpratchet.recording._stream.PhaseSpaceRecording`, with the ensemble summary of
:func:`~warpratchet.observables.summarize`; between frames it adds summary rows to the time
series when they cost under 2% of the kernel time since the last one. It asks the run loop to
stop at its frames (``next_stop``), so frames land on their steps whatever the chunking.
Recording never changes the run's results.
"""

from __future__ import annotations

import bisect
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..ensemble import Ensemble, Observer
from ..errors import check_choice, check_count, check_optional, check_real
from ..observables import (
    THRESHOLD_RULES,
    Summary,
    finite_time_acceleration,
    lyapunov,
    lyapunov_threshold,
    rule_formula,
)
from ._plan import (
    DEFAULT_MAX_BYTES,
    DEFAULT_MAX_FRAMES,
    DEFAULT_MAX_POINTS,
    Plan,
    frame_every,
    frame_seconds,
    plan_frames,
    probe_throughput,
)
from ._scene import COLOR_BY, require_rerun
from ._stream import PhaseSpaceRecording, check_new_file

__all__ = ["DEFAULT_MAX_POINTS", "DEFAULT_MAX_FRAMES", "DEFAULT_MAX_BYTES", "frame_every", "RecordingSink"]

#: Series rows between frames cost at most this share of the kernel time since the last row
#: (modelled from the measured kernel speed, so that the rows do not depend on timing noise).
_SERIES_BUDGET = 0.02
#: Seconds per ensemble point of one summary (FTLE, A_n, mask; benchmarks/recording_overhead.py).
_SUMMARY_SECONDS_PER_POINT = 35e-9


class RecordingSink(Observer):
    """An :class:`~warpratchet.ensemble.Observer` recording a run as it goes.

    A frame (the cloud of a fixed subsample plus the ensemble summary of
    :func:`~warpratchet.observables.summarize`) is logged when the run starts, at the steps of
    its plan (log-spaced by default, or the multiples of ``every``; :func:`~._plan.plan_frames`),
    and when the run ends (also when it is interrupted). Recording never changes the results.

    Parameters
    ----------
    path : str or Path, optional
        ``.rrd`` file (must not exist).
    spawn : bool
        Stream to a newly spawned viewer as well (needs a display).
    max_points : int
        Subsample size ``M``: at most this many points are drawn per frame, the same points in
        every frame (chosen once with ``seed``); fewer if the size budget needs it.
    every : int, optional
        Frames at the multiples of ``every`` steps (widened to fit ``max_bytes``) instead of
        log-spaced frames within the size and time budgets.
    max_bytes : int
        Size budget of the file (default 10 MB): frames and points are planned to stay below it.
    color_by : {"ftle", "class"}
        See :class:`PhaseSpaceRecording`.
    threshold : float, optional
        Chaos threshold for the summary and the classes (default: the value of ``threshold_rule``
        at each step, :func:`~warpratchet.observables.lyapunov_threshold`).
    threshold_rule : {"strict", "positive"}
        Rule of the threshold when ``threshold`` is None: the run's (``--threshold-rule``).
    seed : int
        Seed of the subsample.
    **options
        Passed to :class:`PhaseSpaceRecording` (``ftle_range``, ``trail``, ``title``, ``info``).

    Attributes
    ----------
    summaries : list of Summary
        The summaries logged, in order (one per frame after step 0, and the series rows between).
    plan : Plan or None
        The frames of the run (set by :meth:`begin`).
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
        max_bytes: int = DEFAULT_MAX_BYTES,
        color_by: Literal["ftle", "class"] = "ftle",
        threshold: float | None = None,
        threshold_rule: str = "strict",
        seed: int = 0,
        **options: Any,
    ) -> None:
        self.max_points = check_count("max_points", max_points, 1)
        self.every = check_optional(check_count, "every", every, 1)
        self.max_bytes = check_count("max_bytes", max_bytes, 1)
        self.color_by = check_choice("color_by", color_by, COLOR_BY)
        if path is None and not spawn:
            raise ValueError("a recording needs a path, spawn=True, or both")
        if path is not None:
            check_new_file(path)  # here as well, so that a bad path fails before the run
        require_rerun()
        self.path = path
        self.spawn = spawn
        self.threshold = check_optional(check_real, "threshold", threshold, low=0.0)
        self.threshold_rule = check_choice("threshold_rule", threshold_rule, tuple(THRESHOLD_RULES))
        self.seed = seed
        self.options = options
        self.summaries: list[Summary] = []
        self.frame_seconds: list[float] = []
        self.indices: np.ndarray | None = None
        self.recording: PhaseSpaceRecording | None = None
        self.plan: Plan | None = None
        self._throughput: float | None = None
        self._setup_seconds = 0.0  # the probe and opening the recording, paid from the time budget
        self._kernel_seconds = 0.0  # kernel time and steps seen so far: the kernel's real speed
        self._steps_seen = 0
        self._last_row = 0
        self._rows_between = 0

    @property
    def frames(self) -> list[int]:
        """Steps of the frames logged so far."""
        return [] if self.recording is None else list(self.recording.frames)

    def open(self, ensemble: Ensemble, points: int | None = None) -> None:
        """Open the recording for ``ensemble``, drawing ``points`` (default ``max_points``) per frame.

        Done by :meth:`begin` (or the first :meth:`log_frame`); idempotent.
        """
        if self.recording is not None:
            if self.recording.closed:
                raise ValueError("this RecordingSink is closed (it records one run): make a new one")
            return
        n = ensemble.points
        m = min(n, self.max_points if points is None else points)
        if n <= m:
            self.indices = np.arange(n)
        else:
            # Sorted, so that gathering walks memory forwards.
            rng = np.random.default_rng(self.seed)
            self.indices = np.sort(rng.choice(n, size=m, replace=False))
        rule = rule_formula(self.threshold_rule)
        info = {
            "points": f"{n} ({ensemble.init}, seed {ensemble.seed})",
            "recorded points": f"{len(self.indices)} (fixed subsample, seed {self.seed})",
            "chaos threshold": rule if self.threshold is None else self.threshold,
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
        if self.plan is not None and len(self.frame_seconds) >= 2:
            # Frames after the first (which has no summary) cost what was measured, at least
            # what the model says: the rest of the plan shrinks if the budget cannot pay for it.
            cost = max(
                float(np.mean(self.frame_seconds[1:])), frame_seconds(len(self.indices), ensemble.points)
            )
            self.plan = self.plan.thinned(ensemble.step, sum(self.frame_seconds), cost)

    def _log_frame(self, ensemble: Ensemble) -> None:
        self.open(ensemble)
        assert self.recording is not None and self.indices is not None
        step = ensemble.step
        # Zero-copy views on the CPU; only the subsample and the summary are computed from them.
        state = ensemble.views()
        whole = len(self.indices) == ensemble.points
        sub = state if whole else {k: v[self.indices] for k, v in state.items()}
        if step == 0:
            self.recording.log_cloud(0, sub["x"], sub["q"])
            return
        ftle = lyapunov(sub, step)
        acc = finite_time_acceleration(sub, step) if self.color_by == "class" else None
        threshold = self.threshold
        if threshold is None:
            threshold = lyapunov_threshold(step, self.threshold_rule)
        self.recording.log_cloud(step, sub["x"], sub["q"], ftle, acc, threshold)
        self._log_summary(ensemble)

    def _log_summary(self, ensemble: Ensemble) -> None:
        assert self.recording is not None
        step = ensemble.step
        summary = ensemble.summary(self.threshold, self.threshold_rule, warn=False)
        self.recording.log_summary(step, summary.as_dict())
        self.summaries.append(summary)
        self._last_row = step

    def close(self) -> None:
        """Flush and close the recording (idempotent)."""
        if self.recording is not None:
            self.recording.close()

    # -- Observer -------------------------------------------------------------------------------
    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        if self.recording is not None and self.recording.closed:
            raise ValueError("this RecordingSink is closed (it records one run): make a new one")
        setup = time.perf_counter()
        # The time budget needs the kernel's real speed (CPU, GPU, a faster kernel): measured.
        # With a fixed `every` the cadence is the caller's, and the series has the frames only.
        self._throughput = None if self.every is not None else probe_throughput(ensemble)
        self.plan = plan_frames(
            ensemble.step,
            target_step,
            ensemble.points,
            max_points=self.max_points,
            max_bytes=self.max_bytes,
            every=self.every,
            throughput=self._throughput,
        )
        self.options["info"] = {**(self.options.get("info") or {}), "frames": self.plan.reason}
        self.options.setdefault("steps", target_step - ensemble.step)
        self.open(ensemble, self.plan.points)
        self._setup_seconds = time.perf_counter() - setup
        if not self.frames or self.frames[-1] != ensemble.step:
            self.log_frame(ensemble)

    def next_stop(self, step: int) -> int | None:
        """The first planned frame after ``step`` (the run loop ends a chunk there)."""
        if self.plan is None:
            return None
        i = bisect.bisect_right(self.plan.steps, step)
        return self.plan.steps[i] if i < len(self.plan.steps) else None

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        step = ensemble.step
        self._kernel_seconds += seconds
        self._steps_seen = step - (self.plan.steps[0] if self.plan else 0)
        if self.plan is not None and step in self.plan.steps:
            self.log_frame(ensemble)
        elif (
            self._throughput is not None
            and self._rows_between < self.plan.series_rows
            # the kernel time since the last row, at the measured speed, pays for this one
            and _SUMMARY_SECONDS_PER_POINT * self._throughput <= _SERIES_BUDGET * (step - self._last_row)
        ):
            # A row of the time series between frames: A_n settling, at a cost under 2%.
            self.open(ensemble)
            self._log_summary(ensemble)
            self._rows_between += 1

    def end(self, ensemble: Ensemble) -> None:
        try:
            if self.frames and self.frames[-1] != ensemble.step:
                self.log_frame(ensemble)  # also where an interrupted run stopped
        finally:
            self.close()
