"""What an archive holds, as a test compares it, and the layout docs/archive.md documents."""

from __future__ import annotations

import os
import re
from pathlib import Path

import h5py
import numpy as np

from warpratchet.archive import Archive, ArchiveError

from .runs import same_state

#: The archive's documented layout (its tables are checked against written files).
ARCHIVE_DOC = Path(__file__).resolve().parents[2] / "docs" / "archive.md"


def archive_contents(path) -> tuple[dict, list[str]]:
    """What a reader returns from the archive at ``path`` (raises ArchiveError), and the warnings
    it gave."""
    import warnings

    from warpratchet.archive import ArchiveWarning, open_archive

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(path) as arc:
            got = {
                "series": arc.series,
                "snapshots": arc.snapshots,
                "initial": arc.initial,
                "checkpoint": arc.checkpoint(),
                "meta": (arc.params, arc.settings, arc.versions, arc.created),
            }
    return got, [str(w.message) for w in caught]


def same_contents(a: dict, b: dict) -> bool:
    """Two :func:`archive_contents` equal bit for bit."""
    series = all(np.array_equal(a["series"][k], b["series"][k], equal_nan=True) for k in a["series"])
    snaps = all(
        np.array_equal(getattr(a["snapshots"], k), getattr(b["snapshots"], k))
        for k in ("steps", "indices", "x", "p", "ftle", "finite_time_acceleration")
    )
    return (
        series
        and snaps
        and same_state(a["initial"], b["initial"])
        and same_state(a["checkpoint"][0], b["checkpoint"][0])
        and a["checkpoint"][1] == b["checkpoint"][1]
        and a["meta"] == b["meta"]
    )


def archive_rows(path) -> int:
    """The valid rows of the archive at ``path`` as a concurrent reader sees them (no lock taken);
    0 while it does not exist or cannot be read yet."""
    try:
        with Archive(path, locking=False) as arc:
            return arc.rows
    except (FileNotFoundError, ArchiveError, OSError):
        return 0


def no_temporaries(folder) -> None:
    """No ``*.tmp`` file is left in ``folder`` (a refused or failed write cleans up after itself)."""
    left = [p for p in os.listdir(folder) if p.endswith(".tmp")]
    assert left == [], left


# -- the documented archive layout (test_archive.py, test_transport_cli.py) -------------------------
def documented_names() -> set[str]:
    """The names docs/archive.md's tables list: ``/group/dataset`` and ``/path@attribute``."""
    names = set()
    for line in ARCHIVE_DOC.read_text().splitlines():
        m = re.match(r"\|\s*`(/[^`]*)`\s*\|", line)
        if m:
            names.add(m.group(1))
    return names


#: Attributes every dataset carries (units, description) or that mark HDF5 dimension scales:
#: documented once in prose, checked by test_archive.py's test_every_dataset_describes_itself.
DATASET_ATTRS = {"units", "long_name", "CLASS", "NAME", "REFERENCE_LIST", "DIMENSION_LIST"}


def written_names(path) -> set[str]:
    """The names an HDF5 file holds, as the docs write them (without :data:`DATASET_ATTRS`)."""
    names = set()
    with h5py.File(path, "r") as f:

        def add(name, obj):
            names.add(f"/{name}")
            skip = DATASET_ATTRS if isinstance(obj, h5py.Dataset) else set()
            names.update(f"/{name}@{key}" for key in obj.attrs if key not in skip)

        names.update(f"/@{key}" for key in f.attrs)
        f.visititems(add)
    return names


def documented_optional() -> set[str]:
    """Attributes the table documents as absent for a run-dependent default (RunSpec's rule)."""
    return {
        m.group(1)
        for line in ARCHIVE_DOC.read_text().splitlines()
        if (m := re.match(r"\|\s*`(/[^`]*@[^`]*)`\s*\|.*\babsent\b", line))
    }
