"""Rerun recordings of the phase-space cloud: watch an ensemble fill the chaotic region.

One idea per module:

* :mod:`._scene`: what a recording shows (entity paths, colours, classes, the default blueprint);
* :mod:`._stream`: :class:`PhaseSpaceRecording`, one recording written to a file or a viewer;
* :mod:`._plan`: which steps get a frame and how many points it draws (size and time budgets);
* :mod:`._sink`: :class:`RecordingSink`, the observer that records a run as it goes.

rerun-sdk is an optional dependency (``pip install 'warpratchet[rerun]'``), imported only when a
recording is opened. Replays of an archive's snapshots live in ``viz/record.py``.
"""

from ._plan import (
    DEFAULT_MAX_BYTES,
    DEFAULT_MAX_FRAMES,
    DEFAULT_MAX_POINTS,
    Plan,
    frame_every,
    log_spaced,
    plan_frames,
    points_within_budget,
    probe_throughput,
)
from ._scene import (
    CLASSES,
    CLOUD_PATH,
    COLOR_BY,
    RERUN_MISSING,
    SERIES_KEYS,
    THEORY_PATH,
    VIRIDIS,
    blueprint,
    class_ids,
    ftle_colors,
    require_rerun,
    torus_positions,
)
from ._sink import RecordingSink
from ._stream import PhaseSpaceRecording, ViewerUnavailable, check_new_file, display_available

__all__ = [
    "RERUN_MISSING",
    "require_rerun",
    "VIRIDIS",
    "ftle_colors",
    "CLASSES",
    "COLOR_BY",
    "class_ids",
    "torus_positions",
    "blueprint",
    "SERIES_KEYS",
    "THEORY_PATH",
    "CLOUD_PATH",
    "DEFAULT_MAX_POINTS",
    "DEFAULT_MAX_FRAMES",
    "DEFAULT_MAX_BYTES",
    "Plan",
    "frame_every",
    "log_spaced",
    "plan_frames",
    "points_within_budget",
    "probe_throughput",
    "check_new_file",
    "display_available",
    "ViewerUnavailable",
    "PhaseSpaceRecording",
    "RecordingSink",
]
