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

Minor version 1 of version 2 (root attribute ``format_minor``; absent: 0) only adds what older
readers ignore: CF global attributes (``Conventions``, ``title``, ``history``, ``source``,
``references``) with the map's parameters and the theory's ``A_theory`` at the root and on
``/series``; string attributes as variable-length UTF-8 (h5py reads them as ``str``); the
netCDF dimensions ``point`` (``/initial``, ``/checkpoint``) and ``counter`` (the ``(1,)``
counters), so that no dataset has an unnamed dimension.
"""

from __future__ import annotations

from .. import glossary
from ..errors import FileFormatError, NonFiniteStateError  # NonFiniteStateError: re-exported

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "FORMAT_MINOR",
    "READABLE_VERSIONS",
    "SERIES_FIELDS",
    "INT_SERIES",
    "SNAPSHOT_FIELDS",
    "SLOTS",
    "COUNTERS",
    "HISTORY_COUNTERS",
    "KNOWN_FEATURES",
    "describe",
    "ArchiveError",
    "ArchiveWarning",
    "NonFiniteStateError",
]

#: Format name, root attribute ``format``.
FORMAT = "warpratchet-archive"
#: Layout version written, root attribute ``format_version``.
FORMAT_VERSION = 2
#: Additions within version 2 that older readers ignore, root attribute ``format_minor``
#: (absent: 0; module docstring).
FORMAT_MINOR = 1
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
    "and variances, and block gains of a subsample",
    "transport": "/transport: momentum histograms",
}


def describe(group: str, name: str) -> tuple[str, str]:
    """``(units, long_name)`` of dataset ``name`` of ``group`` (``"initial"``, ``"checkpoint/a"``, ...).

    Worded in :mod:`warpratchet.glossary`, with the sweep files' columns.
    """
    if group.startswith("checkpoint/"):
        group = "checkpoint"  # both slots hold the same datasets
    return glossary.describe(group, name)


class ArchiveError(FileFormatError):
    """An archive that cannot be used: missing, truncated, corrupted, incompatible or in use."""


class ArchiveWarning(UserWarning):
    """Something was recovered, e.g. an older checkpoint because the newest one is damaged."""
