"""The sweep file: one HDF5 file per sweep, one row per finished point, resumable.

Layout (format ``warpratchet-sweep``, version :data:`FORMAT_VERSION`)::

    attrs   format = "warpratchet-sweep", format_version = 1, warpratchet_version,
            spec = JSON of SweepSpec.as_dict()   (RunSpec's names: points, steps, init, seed, threshold)
    parameters   float64 (n, 3): K, b1, b2 of every point, in sweep order
    rows         compound (m,), resizable: one record per finished point, in completion order
    rows_valid   int64 scalar: how many records of ``rows`` are complete

Each record is written and flushed before ``rows_valid`` is raised and flushed again, so a
process killed at any moment leaves a file whose first ``rows_valid`` records are complete;
running the same sweep with the same file resumes it and computes only the missing points.
The columns (:data:`ROW_FIELDS`) carry RunSpec's names for its settings (``K, b1, b2, points,
steps, seed, init, threshold``); ``threshold`` is the value used, the default resolved.
"""

from __future__ import annotations

import json
import os
from typing import Any

import h5py
import numpy as np

from ..errors import FileFormatError
from ..params import MapParams
from ..spec import SweepSpec

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "ROW_DTYPE",
    "ROW_FIELDS",
    "TIMING_FIELDS",
    "read_sweep",
    "read_definition",
]

FORMAT = "warpratchet-sweep"
FORMAT_VERSION = 1

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
        ("seconds", "<f8"),  # wall time of the ensemble run on whichever machine ran it
    ]
)
ROW_FIELDS: tuple[str, ...] = tuple(ROW_DTYPE.names)
#: Row fields that depend on the machine, not on (params, spec, index): leave them out when
#: comparing rows from different runs or executors.
TIMING_FIELDS: tuple[str, ...] = ("seconds",)

_STRING_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "S")
_INT_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "i")


def _record(row: dict[str, Any]) -> np.ndarray:
    record = np.zeros((), dtype=ROW_DTYPE)
    for name in ROW_FIELDS:
        record[name] = row[name].encode("ascii") if name in _STRING_FIELDS else row[name]
    return record


def _row(record: np.void) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for name in ROW_FIELDS:
        value = record[name]
        if name in _STRING_FIELDS:
            row[name] = bytes(value).decode("ascii")
        elif name in _INT_FIELDS:
            row[name] = int(value)
        else:
            row[name] = float(value)
    return row


def _definition_mismatch(f: h5py.File, params: np.ndarray, spec: SweepSpec) -> str | None:
    """Why the sweep stored in ``f`` is not (params, spec), or None if it is the same sweep."""
    stored_spec = json.loads(f.attrs["spec"])
    for key, value in spec.as_dict().items():
        if stored_spec.get(key) != value:
            return f"{key} is {stored_spec.get(key)!r} in the file, {value!r} requested"
    stored = f["parameters"][()]
    if stored.shape != params.shape:
        return f"the file has {stored.shape[0]} points, {params.shape[0]} requested"
    differ = np.flatnonzero(np.any(stored != params, axis=1))
    if differ.size:
        i = int(differ[0])
        return (
            f"point {i} is (K, b1, b2) = {tuple(stored[i].tolist())} in the file, "
            f"{tuple(params[i].tolist())} requested"
        )
    return None


def _version() -> str:
    from .. import __version__

    return __version__


class SweepFile:
    """An open sweep file: created, or reopened after checking it holds the same sweep.

    Parameters
    ----------
    path : path
        The file.
    params : ndarray, shape (n, 3)
        ``K, b1, b2`` of every point, in sweep order.
    spec : SweepSpec
        The ensemble run at every point.
    force : bool
        Replace a file that holds anything else.
    """

    def __init__(self, path: str | os.PathLike, params: np.ndarray, spec: SweepSpec, force: bool) -> None:
        self.path = os.fspath(path)
        if os.path.exists(self.path):
            if force:
                # TODO(house): use the shared file-safety module (build beside, fsync, rename; issue 13).
                os.remove(self.path)
            else:
                self.file = self._reopen(params, spec)
                return
        # "w-" fails if the file appeared meanwhile: a user's file is never truncated.
        self.file = h5py.File(self.path, "w-")
        f = self.file
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["warpratchet_version"] = _version()
        f.attrs["spec"] = spec.to_json()
        parameters = f.create_dataset("parameters", data=params)
        parameters.attrs["columns"] = "K, b1, b2"
        f.create_dataset("rows", shape=(0,), maxshape=(None,), dtype=ROW_DTYPE, chunks=(64,))
        f.create_dataset("rows_valid", data=np.int64(0))
        f.flush()

    def _reopen(self, params: np.ndarray, spec: SweepSpec) -> h5py.File:
        replace = "choose another file or pass force=True (CLI: --force) to replace it"
        if not h5py.is_hdf5(self.path):
            raise FileFormatError(f"{self.path} exists and is not an HDF5 sweep file; {replace}")
        try:
            f = h5py.File(self.path, "r+")
        except OSError as exc:
            # Typically a lock held by a sweep still writing it: never suggest replacing that one.
            raise FileFormatError(
                f"cannot open {self.path} for writing (is another sweep writing it?): {exc}"
            ) from None
        try:
            if f.attrs.get("format") != FORMAT or not {"parameters", "rows", "rows_valid"} <= set(f):
                raise FileFormatError(f"{self.path} exists and is not a warpratchet sweep file; {replace}")
            if f.attrs.get("format_version") != FORMAT_VERSION:
                raise FileFormatError(
                    f"{self.path} has sweep format version {f.attrs.get('format_version')!r}, "
                    f"this warpratchet writes {FORMAT_VERSION}; {replace}"
                )
            why = _definition_mismatch(f, params, spec)
            if why is not None:
                raise FileFormatError(f"{self.path} holds a different sweep ({why}); {replace}")
        except BaseException:
            f.close()
            raise
        return f

    def rows(self) -> list[dict[str, Any]]:
        """The complete records, in file order."""
        valid = int(self.file["rows_valid"][()])
        return [_row(record) for record in self.file["rows"][:valid]]

    def append(self, row: dict[str, Any]) -> None:
        """Write one row (keys :data:`ROW_FIELDS`), then declare it valid: each step flushed."""
        rows, valid = self.file["rows"], self.file["rows_valid"]
        n = int(valid[()])
        # A record past rows_valid is the remnant of an interrupted write: overwrite it.
        if rows.shape[0] < n + 1:
            rows.resize((n + 1,))
        rows[n] = _record(row)
        self.file.flush()  # the record is on disk before it is declared valid
        valid[()] = n + 1
        self.file.flush()

    def close(self) -> None:
        self.file.close()


def _open_for_reading(path: str | os.PathLike) -> h5py.File:
    path = os.fspath(path)
    try:
        f = h5py.File(path, "r", locking=False)
    except OSError as exc:
        raise FileFormatError(f"cannot read sweep file {path}: {exc}") from None
    if f.attrs.get("format") != FORMAT:
        f.close()
        raise FileFormatError(f"{path} is not a warpratchet sweep file")
    return f


def read_sweep(path: str | os.PathLike) -> list[dict[str, Any]]:
    """The finished rows of a sweep file, in sweep order (keys :data:`ROW_FIELDS`).

    An interrupted sweep gives only its finished points. Readable while a sweep is writing it
    (no file lock is taken; rows are flushed one by one).
    """
    with _open_for_reading(path) as f:
        valid = int(f["rows_valid"][()])
        rows = [_row(record) for record in f["rows"][:valid]]
    return sorted(rows, key=lambda row: row["index"])


def read_definition(path: str | os.PathLike) -> tuple[list[MapParams], SweepSpec]:
    """The points and spec a sweep file was created for (to resume it, or to plot what is missing)."""
    with _open_for_reading(path) as f:
        spec = SweepSpec.from_json(f.attrs["spec"])
        params = [MapParams(*row) for row in f["parameters"][()].tolist()]
    return params, spec
