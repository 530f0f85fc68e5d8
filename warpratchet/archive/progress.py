"""How far an archived run is and when it will be done, from its recorded rows (``inspect``).

Pure NumPy on the series of :class:`~warpratchet.archive.reader.Archive`: the target step is
stored (``/progress/target_step``, format v2), the speed is measured from the kernel wall times
of the most recent rows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["RECENT_ROWS", "estimate"]

#: Rows whose wall times give the speed: recent enough to follow a change of machine or load.
RECENT_ROWS = 16


def estimate(
    series: dict[str, np.ndarray], target: int | None, initial_step: int, checkpoint_step: int | None = None
) -> dict[str, Any]:
    """Target step, fraction done (kept, and written), speed and estimated seconds to the target.

    Parameters
    ----------
    series : dict of ndarray
        ``step`` and ``wall_time`` (kernel seconds) of each row, shape ``(rows,)``.
    target : int or None
        The step the run aims at (None: not recorded, as in format v1).
    initial_step : int
        The archive's first step (the step of ``/initial``).
    checkpoint_step : int, optional
        The verified checkpoint's step: where a rerun continues (default: the newest row's).

    Returns
    -------
    dict
        ``target_step``; ``done``, the fraction of the steps from ``initial_step`` to the target
        that the checkpoint keeps (what a rerun does not do again), and ``latest_done``, the
        fraction the newest row has reached (a live run's progress), both in [0, 1];
        ``steps_per_second`` (kernel speed over the last :data:`RECENT_ROWS` rows) and
        ``eta_seconds`` (kernel time from the newest row to the target at that speed; 0 when
        done); None where unknown.
    """
    out: dict[str, Any] = {
        "target_step": target,
        "done": None,
        "latest_done": None,
        "steps_per_second": None,
        "eta_seconds": None,
    }
    steps = np.asarray(series["step"], dtype=np.int64)
    last = int(steps[-1]) if steps.size else initial_step
    kept = last if checkpoint_step is None else checkpoint_step
    if steps.size:
        gained = np.diff(steps, prepend=initial_step)[-RECENT_ROWS:]
        seconds = float(np.sum(series["wall_time"][-RECENT_ROWS:]))
        if seconds > 0 and np.all(gained > 0):
            out["steps_per_second"] = float(np.sum(gained)) / seconds
    if target is None or target <= initial_step:
        return out

    def fraction(step: int) -> float:
        return min(1.0, max(0.0, (step - initial_step) / (target - initial_step)))

    out["done"], out["latest_done"] = fraction(kept), fraction(last)
    if kept >= target:
        out["eta_seconds"] = 0.0
    elif out["steps_per_second"]:
        # From the newest row (a live run's); a stopped run past its target restarts at the checkpoint.
        out["eta_seconds"] = (target - (last if last < target else kept)) / out["steps_per_second"]
    return out
