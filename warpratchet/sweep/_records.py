"""The records of a sweep file: format name and versions, the columns of a row, their units.

A row is one finished sweep point (:func:`warpratchet.sweep.run_point`); :data:`ROW_DTYPE` is its
HDF5 compound type, :data:`ROW_DESCRIPTIONS` the units and description of each column. The layout
of the file is in :mod:`warpratchet.sweep._file`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..glossary import describe

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "READABLE_VERSIONS",
    "ROW_DTYPE",
    "ROW_FIELDS",
    "TIMING_FIELDS",
    "ROW_DESCRIPTIONS",
    "ADDED_COLUMNS",
    "to_record",
    "from_record",
]

FORMAT = "warpratchet-sweep"
#: Layout version written; :data:`READABLE_VERSIONS` are read (and resumed: rebuilt as this one).
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)

#: Columns of a sweep row, in order, with their HDF5 types.
ROW_DTYPE = np.dtype(
    [
        ("index", "<i8"),  # position of the point in the sweep
        ("K", "<f8"),
        ("b1", "<f8"),
        ("b2", "<f8"),
        ("domain", "S4"),  # "LR", "L", "R" or "none" (Fig. 3)
        ("A_theory", "<f8"),  # Eq. (Aa)/(Ab) at K = 3; NaN elsewhere
        ("A", "<f8"),  # mean A_n over chaotic points, per iteration (Eq. An)
        ("A_stderr", "<f8"),
        ("lyapunov", "<f8"),  # mean FTLE over chaotic points, per iteration
        ("lyapunov_std", "<f8"),
        ("lyapunov_min", "<f8"),
        ("chaotic_fraction", "<f8"),
        ("chaotic_points", "<i8"),
        ("points", "<i8"),  # ensemble size actually run (a grid rounds down to a square)
        ("steps", "<i8"),
        ("seed", "<i8"),  # the point's own seed, point_seed(spec.seed, index)
        ("init", "S8"),
        ("threshold", "<f8"),  # FTLE threshold used for the chaotic mask
        ("threshold_rule", "S8"),  # the rule of a default threshold: strict or positive
        ("A_stderr_robust", "<f8"),  # robust standard error of A (warpratchet.convergence)
        ("drift", "<f8"),  # A_n - A_{n/2}
        ("drift_z", "<f8"),  # the drift in units of its standard error
        ("verdict", "S10"),  # converged, drifting, too short, undefined ("" in older files)
        ("diffusion_exponent", "<f8"),  # mu of Var(gain over T) ~ T^mu, from the block gains
        ("seconds", "<f8"),  # wall time of the ensemble run on whichever machine ran it
    ]
)
ROW_FIELDS: tuple[str, ...] = tuple(ROW_DTYPE.names)
#: Columns added after format version 2 first shipped, and their value in rows of files written
#: before (read as such; a resumed file is rebuilt with them). Not a new version: the rows of
#: these files read with the first v2 release too (it picks the columns it knows).
ADDED_COLUMNS: dict[str, Any] = {
    "threshold_rule": "strict",
    "A_stderr_robust": float("nan"),
    "drift": float("nan"),
    "drift_z": float("nan"),
    "verdict": "",
    "diffusion_exponent": float("nan"),
}
#: Row fields that depend on the machine, not on (params, spec, index): leave them out when
#: comparing rows from different runs or executors.
TIMING_FIELDS: tuple[str, ...] = ("seconds",)

#: ``(units, long_name)`` of each column, stored as the ``column_units`` and ``column_long_names``
#: attributes of ``rows`` (a compound dataset has one ``units`` attribute, so it says where to look);
#: worded in :mod:`warpratchet.glossary`, as the archives' datasets of the same name.
ROW_DESCRIPTIONS: dict[str, tuple[str, str]] = {name: describe("rows", name) for name in ROW_FIELDS}

_STRING_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "S")
_INT_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "i")


def to_record(row: dict[str, Any]) -> np.ndarray:
    record = np.zeros((), dtype=ROW_DTYPE)
    for name in ROW_FIELDS:
        value = row[name] if name in row or name not in ADDED_COLUMNS else ADDED_COLUMNS[name]
        record[name] = value.encode("ascii") if name in _STRING_FIELDS else value
    return record


def from_record(record: np.void) -> dict[str, Any]:
    """A row of a stored record; a column the file predates takes its :data:`ADDED_COLUMNS` value."""
    row: dict[str, Any] = {}
    stored = record.dtype.names
    for name in ROW_FIELDS:
        if name not in stored:
            row[name] = ADDED_COLUMNS[name]
            continue
        value = record[name]
        if name in _STRING_FIELDS:
            row[name] = bytes(value).decode("ascii")
        elif name in _INT_FIELDS:
            row[name] = int(value)
        else:
            row[name] = float(value)
    return row
