"""Reading a sweep file: :func:`read_sweep`, :func:`read_definition` (also while a sweep writes it).

A file a writer has open (or a killed writer left marked open) is opened in SWMR-read mode
(:func:`warpratchet._files.open_h5`); only the first ``rows_valid`` records are read, and a
record whose checksum fails is an error, never a number.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from typing import Any

import h5py
import numpy as np

from .._files import open_h5
from .._h5verify import first_line, refresh
from ..errors import FileFormatError
from ..params import MapParams
from ..spec import SweepSpec, attr_value, params_of
from ._records import FORMAT, ROW_DESCRIPTIONS, ROW_FIELDS, from_record

__all__ = [
    "read_sweep",
    "read_definition",
    "open_for_reading",
    "valid_rows",
    "definition_mismatch",
    "first_line",
]


#: The file attributes of a sweep of another force than Eq. (fx) (absent for the paper's).
FORCE_ATTRS = ("knots", "values")


def stored_force(f: h5py.File) -> dict[str, str] | None:
    """The ``knots``, ``values`` a sweep file stores for another force, or None (Eq. fx)."""
    if "knots" not in f.attrs:
        return None
    return {name: str(attr_value(f.attrs[name])) for name in FORCE_ATTRS}


def stored_params(f: h5py.File) -> list[MapParams]:
    """The points of a sweep file: ``K, b1, b2`` rows, or ``K`` rows of its one other force."""
    force = stored_force(f)
    rows = f["parameters"][()].tolist()
    if force is None:
        return [MapParams(*row) for row in rows]
    return [params_of(row[0], **force) for row in rows]


def definition_mismatch(
    f: h5py.File, params: np.ndarray, spec: SweepSpec, force: dict[str, str] | None = None
) -> str | None:
    """Why the sweep stored in ``f`` is not (params, spec) of the paper's force or of another
    ``force`` (its ``knots``, ``values``), or None if it is the same sweep."""
    if stored_force(f) != force:

        def text(table: dict[str, str] | None) -> str:
            return (
                "that of b1, b2" if table is None else f"knots = {table['knots']}, values = {table['values']}"
            )

        return f"its force is {text(stored_force(f))}, {text(force)} requested"
    stored_spec = json.loads(attr_value(f.attrs["spec"]))
    # A setting added since the file was written is stored as its default (threshold_rule).
    defaults = {field.name: field.default for field in dataclasses.fields(SweepSpec)}
    for key, value in spec.as_dict().items():
        if stored_spec.get(key, defaults[key]) != value:
            return f"{key} is {stored_spec.get(key)!r} in the file, {value!r} requested"
    stored = f["parameters"][()]
    if stored.shape != params.shape:
        return f"the file has {stored.shape[0]} points, {params.shape[0]} requested"
    # another force's b1, b2 columns are NaN
    differ = np.flatnonzero(np.any((stored != params) & ~(np.isnan(stored) & np.isnan(params)), axis=1))
    if differ.size:
        i = int(differ[0])
        return (
            f"point {i} is (K, b1, b2) = {tuple(stored[i].tolist())} in the file, "
            f"{tuple(params[i].tolist())} requested"
        )
    return None


def open_for_reading(
    path: str | os.PathLike, foreign: str = "is not a warpratchet sweep file", *, locking: bool | None = None
) -> h5py.File:
    """Open a sweep file read-only (SWMR-read while a sweep writes it, or after a killed one).

    With HDF5's default locking (also beside the caller's own ``h5py.File`` of it), or
    ``locking=False`` for a caller that holds its own claim on the file
    (:func:`warpratchet._files.open_h5`).
    """
    path = os.fspath(path)
    try:
        f = open_h5(path, locking=locking)
    except OSError as exc:
        raise FileFormatError(f"cannot read sweep file {path}: {first_line(exc)}") from None
    try:
        fmt = attr_value(f.attrs.get("format", b""))
    except (OSError, KeyError, RuntimeError) as exc:
        f.close()
        raise FileFormatError(f"cannot read sweep file {path}: {first_line(exc)}; it is corrupted") from None
    if fmt != FORMAT:
        f.close()
        raise FileFormatError(f"{path} {foreign}")
    return f


#: Looks at the rows' extent when it lags the counter (a live writer), ~2 ms apart.
_EXTENT_ATTEMPTS = 25


def valid_rows(f: h5py.File, path: str) -> list[dict[str, Any]]:
    """The complete records of an open sweep file; a damaged one is an error, never a number."""
    try:
        valid_ds, rows_ds = f["rows_valid"], f["rows"]
        refresh(valid_ds)
        valid = int(valid_ds[()]) if valid_ds.shape == () else int(valid_ds[0])
        # The writer extends and fills the rows before it bumps the counter, but a SWMR reader
        # that has just seen the new counter may see the rows' new extent a moment later (the
        # rows' object header is another piece of metadata): look again before calling it damage.
        for _attempt in range(_EXTENT_ATTEMPTS):
            refresh(rows_ds)
            if valid <= rows_ds.shape[0]:
                break
            time.sleep(0.002)
        if not 0 <= valid <= rows_ds.shape[0]:
            raise FileFormatError(f"{path}: rows_valid = {valid} but the file has {rows_ds.shape[0]} rows")
        return [from_record(record) for record in rows_ds[:valid]]
    except (OSError, KeyError, RuntimeError, TypeError) as exc:
        raise FileFormatError(
            f"{path}: cannot read the rows ({first_line(exc)}); the sweep file is truncated or corrupted"
        ) from None


def read_sweep(path: str | os.PathLike, as_: str = "rows") -> list[dict[str, Any]] | Any:
    """The finished rows of a sweep file, in sweep order (keys :data:`ROW_FIELDS`).

    An interrupted sweep gives only its finished points. Readable while a sweep is writing it
    (SWMR). Every record is checksummed (format v2): a damaged one is a ``FileFormatError``,
    never a changed number.

    Parameters
    ----------
    as_ : {"rows", "pandas"}
        A list of dicts, or a ``pandas.DataFrame`` (one row per point, ``frame.attrs`` holds
        ``units`` and ``long_name`` of each column; needs ``warpratchet[xarray]``).
    """
    if as_ not in ("rows", "pandas"):
        raise ValueError(f"as_ = {as_!r} is not 'rows' or 'pandas'")
    with open_for_reading(path) as f:
        rows = valid_rows(f, os.fspath(path))
    rows = sorted(rows, key=lambda row: row["index"])
    if as_ == "rows":
        return rows
    try:
        import pandas as pd
    except ImportError:
        raise ImportError(
            "read_sweep(..., as_='pandas') needs pandas: pip install 'warpratchet[xarray]'"
        ) from None
    frame = pd.DataFrame(rows, columns=list(ROW_FIELDS))
    frame.attrs = {
        "units": {name: ROW_DESCRIPTIONS[name][0] for name in ROW_FIELDS},
        "long_name": {name: ROW_DESCRIPTIONS[name][1] for name in ROW_FIELDS},
        "path": os.fspath(path),
    }
    return frame


def read_definition(path: str | os.PathLike) -> tuple[list[MapParams], SweepSpec]:
    """The points and spec a sweep file was created for (to resume it, or to plot what is missing)."""
    with open_for_reading(path) as f:
        try:
            spec = SweepSpec.from_json(attr_value(f.attrs["spec"]))
            params = stored_params(f)
        except (OSError, KeyError, RuntimeError) as exc:
            raise FileFormatError(
                f"{os.fspath(path)}: cannot read the sweep's definition ({first_line(exc)})"
            ) from None
    return params, spec
