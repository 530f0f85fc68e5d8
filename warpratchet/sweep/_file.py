"""The sweep file: one HDF5 file per sweep, one row per finished point, resumable.

Layout (format ``warpratchet-sweep``, version :data:`FORMAT_VERSION`; HDF5 1.10 object formats,
:data:`warpratchet._files.LIBVER`, so HDF5 1.10 tools read it)::

    attrs   format = "warpratchet-sweep", format_version = 2, warpratchet_version, features = "",
            spec = JSON of SweepSpec.as_dict()   (RunSpec's names: points, steps, init, seed, threshold)
            knots, values: only for a sweep of another force than Eq. (fx) (warpratchet.force)
    parameters   float64 (n, 3): K, b1, b2 of every point, in sweep order (NaN b1, b2: that force)
    rows         compound (m,), resizable: one record per finished point, in completion order
                 (attributes column_units, column_long_names: one per column, ROW_DESCRIPTIONS)
    rows_valid   int64 (1,): how many records of ``rows`` are complete

Every dataset is chunked with a Fletcher-32 checksum (a flipped bit is an error, never a changed
number) and has ``units`` and ``long_name``; strings are fixed-length attributes in checksummed
object headers. The writer uses SWMR, so ``read_sweep`` may read while a sweep writes. Each
record is written and flushed before ``rows_valid`` is raised and flushed again, so a process
killed at any moment leaves a file whose first ``rows_valid`` records are complete; running
the same sweep with the same file resumes it and computes only the missing points (the same
rule as ``run --out``). Version 1 (release 0.1.0: no checksums, a scalar ``rows_valid``) still
reads and resumes; a resume rebuilds it as version 2. Optional groups follow the archive's rule
(``features``, docs/archive.md).
The columns (:data:`ROW_FIELDS`) carry RunSpec's names for its settings (``K, b1, b2, points,
steps, seed, init, threshold``); ``threshold`` is the value used, the default resolved.
"""

from __future__ import annotations

import os
from importlib import metadata
from typing import Any

import h5py
import numpy as np

from .._files import LIBVER, abandon_h5, check_new_path, claim, publish, sync_h5, temporary_beside, try_lock
from .._storage import StorageError, ensure_space, h5_bytes, storage_cause, storage_errors
from ..errors import FileFormatError
from ..spec import SweepSpec, attr_value
from . import _records
from ._reading import definition_mismatch, open_for_reading, valid_rows
from ._records import FORMAT, FORMAT_VERSION, READABLE_VERSIONS, ROW_DTYPE, ROW_FIELDS, to_record

try:  # advisory locks; absent on Windows
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = ["SweepFile", "FORMAT", "FORMAT_VERSION", "ROW_FIELDS"]

#: File space of a sweep file's layout before any data (attributes, three datasets):
#: ``scripts/h5_overhead.py`` measures 4559 B for 12 points and no records, and 1873 B of chunk
#: index that the first block of records adds.
LAYOUT_BYTES = 8 * 1024


def _version() -> str:
    # The installed distribution's version, as warpratchet.__version__ reads it (that module sits
    # above this one).
    try:
        return metadata.version("warpratchet")
    except metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


def _describe(ds: h5py.Dataset, units: str, long_name: str) -> None:
    ds.attrs["units"] = np.bytes_(units.encode())
    ds.attrs["long_name"] = np.bytes_(long_name.encode())


def _create(
    f: h5py.File,
    params: np.ndarray,
    spec: SweepSpec,
    rows: list[dict[str, Any]],
    table: dict[str, str] | None,
) -> None:
    """The whole layout in a new file, with ``rows`` already valid (SWMR allows no new objects later)."""
    for key, value in {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "warpratchet_version": _version(),
        "spec": spec.to_json(),
        "features": "",
        **(table or {}),
    }.items():
        # Fixed-length strings live in the checksummed object header (variable-length ones do not).
        f.attrs[key] = np.bytes_(value.encode()) if isinstance(value, str) else value
    parameters = f.create_dataset(
        "parameters", data=params, chunks=(max(1, min(len(params), 4096)), 3), fletcher32=True
    )
    parameters.attrs["columns"] = np.bytes_(b"K, b1, b2")
    _describe(parameters, "1", "K, b1, b2 of every point, in sweep order")
    stored = np.array([to_record(row) for row in rows], dtype=ROW_DTYPE).reshape(len(rows))
    ds = f.create_dataset(
        "rows", data=stored, maxshape=(None,), dtype=ROW_DTYPE, chunks=(64,), fletcher32=True
    )
    _describe(ds, "see column_units", "one record per finished point, in completion order")
    ds.attrs["column_units"] = np.array(
        [_records.ROW_DESCRIPTIONS[n][0].encode() for n in ROW_FIELDS], dtype="S16"
    )
    ds.attrs["column_long_names"] = np.array(
        [_records.ROW_DESCRIPTIONS[n][1].encode() for n in ROW_FIELDS], dtype="S64"
    )
    valid = f.create_dataset("rows_valid", data=np.array([len(rows)], np.int64), chunks=(1,), fletcher32=True)
    _describe(valid, "1", "how many records of rows are complete (raised after them)")


class SweepFile:
    """A sweep file being written: created, or continued after checking it holds the same sweep.

    A new file (or, with ``force``, the replacement of an old one) is built beside its path,
    made durable and renamed into place, so the path never holds half a file and a replaced
    file is never deleted before its replacement exists. An existing file of the same sweep is
    continued: its finished rows are read, and when the first new row arrives the file is
    rebuilt (same way, the rows kept) in today's format and reopened for appending; a sweep
    with nothing left to compute leaves the file untouched. A writer holds a shared ``flock``
    on its file; a second sweep (or ``force``) needs an exclusive one and refuses a file in use.

    Parameters
    ----------
    path : path
        The file.
    params : ndarray, shape (n, 3)
        ``K, b1, b2`` of every point, in sweep order.
    spec : SweepSpec
        The ensemble run at every point.
    force : bool
        Replace a file that holds anything else (refused while another process uses it).
    table : dict, optional
        ``knots`` and ``values`` of another force than Eq. (fx), the sweep's one force (its
        ``b1, b2`` columns are NaN), stored as file attributes.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        params: np.ndarray,
        spec: SweepSpec,
        force: bool,
        table: dict[str, str] | None = None,
    ) -> None:
        self.path = os.fspath(path)
        self.params, self.spec, self.table = params, spec, table
        self.file: h5py.File | None = None
        self._lock_fd: int | None = None
        self._rows: list[dict[str, Any]] = []
        replace = "choose another file or pass force=True (CLI: --force) to replace it"
        try:
            exists = check_new_path(self.path, force=True)
            if exists:
                self._lock_fd = claim(self.path, exclusive=True)  # nobody else writes or rebuilds it
                if not force:
                    self._rows = self._existing_rows(replace)
            if not exists or force:
                self._build(replace=exists)
        except (FileExistsError, FileNotFoundError, BlockingIOError) as exc:
            self._release()
            raise FileFormatError(str(exc)) from None
        except BaseException:
            self._release()
            raise
        if fcntl is not None and self._lock_fd is not None:
            fcntl.flock(self._lock_fd, fcntl.LOCK_SH | fcntl.LOCK_NB)  # readers welcome, writers not

    def _existing_rows(self, replace: str) -> list[dict[str, Any]]:
        if not h5py.is_hdf5(self.path):
            raise FileFormatError(f"{self.path} exists and is not an HDF5 sweep file; {replace}")
        # No HDF5 lock: this process holds the exclusive claim on the file (HDF5's would collide).
        with open_for_reading(
            self.path, foreign=f"exists and is not a warpratchet sweep file; {replace}", locking=False
        ) as f:
            version = attr_value(f.attrs.get("format_version"))
            if version not in READABLE_VERSIONS:
                raise FileFormatError(
                    f"{self.path} has sweep format version {version!r}, this warpratchet reads "
                    f"{', '.join(map(str, READABLE_VERSIONS))}; {replace}"
                )
            why = definition_mismatch(f, self.params, self.spec, self.table)
            if why is not None:
                raise FileFormatError(f"{self.path} holds a different sweep ({why}); {replace}")
            return valid_rows(f, self.path)

    def _build(self, *, replace: bool) -> None:
        """Write the layout with the rows so far beside the path, publish it, keep it open (SWMR)."""
        count = len(self._rows)
        with storage_errors(self.path, "create" if not replace else "write", self._hint()):
            # The whole sweep's file: its layout, the parameters and every record (chunks of 64).
            blocks = -(-max(count, len(self.params), 1) // 64)
            needed = LAYOUT_BYTES + h5_bytes(self.params.nbytes, -(-len(self.params) // 4096))
            needed += h5_bytes(ROW_DTYPE.itemsize * 64 * blocks, blocks)
            ensure_space(self.path, needed, "the sweep file")
            with temporary_beside(self.path) as tmp:
                f = h5py.File(tmp, "w", libver=LIBVER, locking=False)
                try:
                    _create(f, self.params, self.spec, self._rows, self.table)
                    f.swmr_mode = True
                    sync_h5(f)  # durable before it gets its name
                    fd = os.open(tmp, os.O_RDONLY)
                    try_lock(fd, exclusive=False)  # held before the name exists: no one slips in
                    try:
                        publish(tmp, self.path, replace=replace)
                    except BaseException:
                        os.close(fd)
                        raise
                except BaseException:
                    abandon_h5(f)
                    raise
        self._release()
        self.file, self._lock_fd, self._count = f, fd, count

    def _hint(self) -> str:
        return (
            f"; {self.path} keeps its {len(self._rows)} finished point(s): once there is space, "
            "run the same command again to compute the rest"
        )

    def rows(self) -> list[dict[str, Any]]:
        """The complete records, in file order."""
        return list(self._rows)

    def append(self, row: dict[str, Any]) -> None:
        """Write one row (keys :data:`ROW_FIELDS`), then declare it valid: each step flushed."""
        if self.file is None:
            self._build(replace=True)  # continue an existing file: rebuilt in today's format
        f = self.file
        try:
            with storage_errors(self.path, "write", self._hint()):
                rows, valid = f["rows"], f["rows_valid"]
                n = self._count
                if n % 64 == 0:  # the first record of a new chunk allocates it
                    ensure_space(self.path, h5_bytes(64 * ROW_DTYPE.itemsize), "the next rows")
                # A record past rows_valid is the remnant of an interrupted write: overwrite it.
                if rows.shape[0] < n + 1:
                    rows.resize((n + 1,))
                rows[n] = to_record(row)
                f.flush()  # the record is on disk before it is declared valid
                valid[0] = n + 1
                f.flush()
        except BaseException as exc:
            if storage_cause(exc) is not None or isinstance(exc, StorageError):
                abandon_h5(f)  # as a killed sweep leaves it: resumable once there is space
                self.file = None
                self._release()
            raise
        self._count = n + 1
        self._rows.append(row)

    def _release(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def close(self) -> None:
        if self.file is not None and self.file.id.valid:
            try:
                with storage_errors(self.path, "write", self._hint()):
                    self.file.close()
            except BaseException:
                abandon_h5(self.file)
                raise
            finally:
                self.file = None
                self._release()
        self._release()
