"""The names of an archive: format and versions, groups, datasets, their units and descriptions.

The one place that names the layout of ``docs/archive.md``. Version 2 (this release) differs
from version 1 (warpratchet 0.1.0, still read) in:

* the file format: HDF5 1.10 object formats (readable by the HDF5 1.10 tools), not "latest";
* ``/settings``: RunSpec's names (``init``, not ``sampler``; a run-dependent default such as the
  threshold or a missing seed is an absent attribute, not NaN or -1);
* the live counters moved from ``/series/n_valid`` and ``/snapshots/n_valid`` to ``/progress``
  (``series_rows``, ``snapshot_rows``), joined by ``target_step``; ``/series`` and
  ``/snapshots`` hold only data, so netCDF readers see their dimensions and no phony ones;
* every dataset has ``units`` and ``long_name``; ``/series/step`` and ``/snapshots/step`` are
  HDF5 dimension scales attached to their groups' datasets, ``/snapshots/indices`` too;
* a closed archive holds exactly its valid rows (trimmed at close);
* ``/@features``: the optional groups present (:data:`KNOWN_FEATURES`).
"""

from __future__ import annotations

from ..errors import FileFormatError, NonFiniteStateError  # NonFiniteStateError: re-exported
from ..observables import SUMMARY_DESCRIPTIONS

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "READABLE_VERSIONS",
    "SERIES_FIELDS",
    "INT_SERIES",
    "SNAPSHOT_FIELDS",
    "SLOTS",
    "COUNTERS",
    "HISTORY_COUNTERS",
    "KNOWN_FEATURES",
    "DESCRIPTIONS",
    "describe",
    "ArchiveError",
    "ArchiveWarning",
    "NonFiniteStateError",
]

#: Format name, root attribute ``format``.
FORMAT = "warpratchet-archive"
#: Layout version written, root attribute ``format_version``.
FORMAT_VERSION = 2
#: Layout versions this release reads (and resumes: a resumed version-1 archive is rebuilt as 2).
READABLE_VERSIONS = (1, 2)

#: Columns of ``/series`` (one row per chunk); ``step`` and ``chaotic_points`` are int64.
SERIES_FIELDS = (
    "step",
    "A",
    "A_stderr",
    "lyapunov",
    "lyapunov_std",
    "lyapunov_min",
    "chaotic_fraction",
    "chaotic_points",
    "threshold",
    "wall_time",
    "unix_time",
)
INT_SERIES = ("step", "chaotic_points")
#: Per-point arrays of ``/snapshots``, each ``(S, M)``.
SNAPSHOT_FIELDS = ("x", "p", "ftle", "A")
#: The two checkpoint slots, ``/checkpoint/a`` and ``/checkpoint/b`` (``current`` = 0 or 1).
SLOTS = ("a", "b")

#: Where each live counter is, by format version: the number of valid series rows and snapshots
#: (the writer raises them after the rows are on disk) and the step the running session aims at.
COUNTERS = {
    1: {"series": "series/n_valid", "snapshots": "snapshots/n_valid"},
    2: {
        "series": "progress/series_rows",
        "snapshots": "progress/snapshot_rows",
        "target": "progress/target_step",
    },
}

#: The live counters of the optional ``/history`` group (feature ``history``): valid rows and
#: valid block records, raised after them like the others.
HISTORY_COUNTERS = {"rows": "progress/history_rows", "blocks": "progress/block_rows"}

#: Optional groups a later release may add without a new major version, as named in the root
#: attribute ``features`` (a comma-separated list, empty for none). A reader ignores groups it
#: does not know and reads a feature only when it is listed; a change that an older reader would
#: misread (a renamed or reinterpreted dataset) bumps ``format_version`` instead.
KNOWN_FEATURES = {
    "history": "/history: log-spaced rows of A_n, its standard error, sigma, the chaotic fraction "
    "and variances, and block gains of a subsample (issue 15)",
    "transport": "/transport: momentum histograms (issue 16)",
}

_STATE = {
    "x": ("1", "position x in [0, 1)"),
    "q": ("1", "fractional momentum p mod 1, in [0, 1)"),
    "winding": ("1", "whole units of momentum gained since step 0"),
    "p0": ("1", "initial momentum; p_n = floor(p0) + winding + q"),
    "dx": ("1", "tangent vector, x component"),
    "dp": ("1", "tangent vector, p component"),
    "log_stretch": ("1", "natural log of the tangent norm removed by renormalisation"),
}
#: ``(units, long_name)`` of every dataset, by its name inside its group (``"series/A"``) or, for
#: the per-point state of ``/initial`` and the checkpoint slots, by field name. Momentum and
#: position are in units of the map's period (dimensionless, "1"); rates are per iteration.
DESCRIPTIONS: dict[str, tuple[str, str]] = {
    **_STATE,
    "series/step": ("iteration", "step at the end of the chunk"),
    "series/A": ("1/iteration", "mean acceleration A_n of Eq. (An) over chaotic points"),
    "series/A_stderr": ("1/iteration", "standard error of A: std / sqrt(chaotic points)"),
    "series/lyapunov": ("1/iteration", "mean finite-time Lyapunov exponent of chaotic points"),
    **{f"series/{name}": description for name, description in SUMMARY_DESCRIPTIONS.items()},
    "series/threshold": ("1/iteration", "FTLE threshold used for the row"),
    "series/wall_time": ("s", "kernel seconds of the chunk"),
    "series/unix_time": ("seconds since 1970-01-01 00:00:00 UTC", "when the row was written"),
    "snapshots/step": ("iteration", "step of the snapshot"),
    "snapshots/indices": ("1", "sorted indices of the subsample's points in the ensemble"),
    "snapshots/x": ("1", "position x in [0, 1)"),
    "snapshots/p": ("1", "momentum p mod 1, in [0, 1)"),
    "snapshots/ftle": ("1/iteration", "finite-time Lyapunov exponent of each point"),
    "snapshots/A": ("1/iteration", "A_n of Eq. (An) of each point"),
    "progress/series_rows": ("1", "valid rows of /series (raised after they are on disk)"),
    "progress/snapshot_rows": ("1", "valid snapshots of /snapshots (raised after they are on disk)"),
    "progress/target_step": ("iteration", "step the last run session aims at; -1 before the first"),
    "progress/history_rows": ("1", "valid rows of /history (raised after they are on disk)"),
    "progress/block_rows": ("1", "valid block records of /history (raised after they are on disk)"),
    "history/step": ("iteration", "step n of the history row"),
    "history/A": ("1/iteration", "mean acceleration A_n of Eq. (An) over chaotic points at n"),
    "history/A_stderr": ("1/iteration", "standard error of A: std / sqrt(chaotic points)"),
    "history/sigma": ("1/iteration", "mean finite-time Lyapunov exponent of chaotic points at n"),
    "history/chaotic_fraction": ("1", "fraction of points chaotic at n"),
    "history/chaotic_points": ("1", "number of points chaotic at n"),
    "history/var_dp_all": ("1", "variance of p_n - p_0 over all points"),
    "history/var_dp_chaotic": ("1", "variance of p_n - p_0 over the chaotic points"),
    "history/block_step": ("iteration", "end of a time block, floor(target j / blocks)"),
    "history/block_indices": ("1", "sorted indices of the block subsample's points in the ensemble"),
    "history/block_gain": ("1", "p_n - p_0 of each subsample point at the block end"),
    "history/block_ftle": ("1/iteration", "finite-time Lyapunov exponent of each subsample point"),
    "checkpoint/current": ("1", "slot of the newest complete checkpoint: 0 = a, 1 = b, -1 none"),
    "checkpoint/step": ("iteration", "step of the state in this slot; -1 while written or unused"),
}


def describe(group: str, name: str) -> tuple[str, str]:
    """``(units, long_name)`` of dataset ``name`` of ``group`` (``"initial"``, ``"checkpoint/a"``, ...)."""
    if group.startswith("checkpoint/") and name == "step":
        return DESCRIPTIONS["checkpoint/step"]
    return DESCRIPTIONS.get(f"{group}/{name}") or DESCRIPTIONS[name]


class ArchiveError(FileFormatError):
    """An archive that cannot be used: missing, truncated, corrupted, incompatible or in use."""


class ArchiveWarning(UserWarning):
    """Something was recovered, e.g. an older checkpoint because the newest one is damaged."""
