"""What an archive holds as a run grows, and reading it back safely.

Reading safely (:func:`reading`, :func:`read_counter`, :func:`valid_rows`, ...): HDF5 failures
as one line, SWMR refreshes, extents, counters and the valid rows they count, finite states;
shared by the reader, the writer, ``resume`` and ``verify`` of :mod:`warpratchet.archive`.

Append-only rows of an archive group (``/series``, ``/snapshots``, ``/history``) and their
counter: :meth:`Rows.put` writes the next row of every dataset (growing them :data:`ROW_CHUNK` rows at a
time), :meth:`Rows.commit` makes the rows put since the last commit valid by raising the
counter, :meth:`Rows.trim` cuts the datasets to the valid rows when the archive is closed (so a
closed archive holds exactly its rows); :func:`fill_rows` puts a rebuilt archive's kept rows
in at once. Rows are written with low-level HDF5 calls: h5py's indexing costs more per call
than a short chunk's kernel time (benchmarks/README.md, archive_overhead.py).

The two checkpoint slots, written crash-safe into the free one, read newest first.

Writing (:func:`write_slot`): the slot *not* holding the newest checkpoint gets ``step`` -1 (in
progress: nobody may trust it), its data fsynced, then its ``step`` and ``/checkpoint/current``.
Reading (:func:`newest_good`): the complete slots newest first, each slot's ``step`` read before
and after its data (a sequence lock), so a slot a live writer recycles meanwhile is read again,
never reported as damaged; a slot whose checksum fails or that holds non-finite values (written
by format v1 releases) is skipped and described. docs/archive.md has the whole story.

The ``/snapshots`` group, phase-space snapshots of a fixed random subsample of points.

The subsample (:func:`snapshot_indices`) is drawn once, from the run's seed and a salt of its
own, and stored with the archive; every snapshot (:func:`snapshot_row`) holds those points'
``x``, ``p`` mod 1, FTLE and finite-time acceleration ``A_n`` (Eqs. cpem, An);
:func:`read_snapshots` returns the valid rows as :class:`Snapshots`, under today's names whatever
names the file stores (:func:`~._format.stored_name`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np
from h5py import h5s

from .._files import dataset_bytes, ensure_space, h5_bytes, sync_h5
from .._h5verify import chunk_past_end, first_line, read_rows, refresh
from ..ensemble import STATE_FIELDS
from ..errors import renamed_attribute
from ..observables import finite_time_acceleration, lyapunov
from ..sampling import salted_subsample
from ._format import (
    ROW_CHUNK,
    SLOTS,
    SNAPSHOT_FIELDS,
    TEXT_CHECKSUM,
    ArchiveError,
    stored_name,
    text_checksum,
)

__all__ = [
    "reading",
    "refresh",
    "check_extent",
    "read_counter",
    "valid_rows",
    "nonfinite",
    "listed",
    "check_text",
    "Rows",
    "set_counter",
    "fill_rows",
    "read_state",
    "slot_step",
    "slot_steps",
    "newest_good",
    "write_slot",
    "Snapshots",
    "read_snapshots",
    "snapshot_indices",
    "snapshot_row",
]


# -- reading safely -------------------------------------------------------------------------------
@contextlib.contextmanager
def reading(path: str, what: str) -> Iterator[None]:
    """Turn any HDF5/h5py failure while reading ``what`` into one clear :class:`ArchiveError`."""
    try:
        yield
    except ArchiveError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError) as exc:
        raise ArchiveError(
            f"{path}: cannot read {what} ({first_line(exc)}); the archive is truncated or corrupted"
        ) from None


def check_extent(path: str, ds: h5py.Dataset, rows: int | None = None) -> None:
    """ArchiveError if a chunk of ``ds`` holding one of its first ``rows`` rows is past the end of
    the file (HDF5 would read it as zeros with a valid checksum; see ``_h5verify.chunk_past_end``)."""
    past = chunk_past_end(path, ds, rows)
    if past is not None:
        raise ArchiveError(f"{path}: {past}; the archive is truncated or corrupted")


def read_counter(path: str, f: h5py.File, where: str, *, signed: bool = False) -> int:
    """The ``(1,)`` int64 counter at ``where`` in ``f`` (``"progress/series_rows"``, ...), read afresh.

    ArchiveError if it is unreadable, past the end of the file, or negative (unless ``signed``:
    ``progress/target_step`` is -1 before a run's first target is known).
    """
    with reading(path, f"/{where}"):
        ds = refresh(f[where])
        check_extent(path, ds)
        n = int(ds[0])
    if n < 0 and not signed:
        raise ArchiveError(f"{path}: /{where} = {n} is negative; the archive is corrupted")
    return n


def valid_rows(path: str, group: h5py.Group, name: str, n: int) -> np.ndarray:
    """The first ``n`` rows of the appendable dataset ``group[name]``: the valid ones, as its
    counter says (``(n, ...)``, the dataset's dtype).

    Read afresh (a live writer may have appended since), refused if the dataset holds fewer rows
    or a chunk of them lies past the end of the file, every checksum verified; a torn append of
    a killed writer, or a rewrite a live writer is half way through, reads as
    :func:`warpratchet._h5verify.read_rows` reads it. Any failure is one :class:`ArchiveError`.
    """
    where = f"{group.name}/{name}"
    with reading(path, where):
        ds = refresh(group[name])
        if ds.shape[0] < n:
            raise ArchiveError(f"{path}: {where} has {ds.shape[0]} rows, {n} are valid")
        check_extent(path, ds, n)
        return read_rows(ds, n)


def nonfinite(state: dict[str, np.ndarray]) -> dict[str, int]:
    """How many non-finite values each field of ``state`` holds (only the fields that have some)."""
    counts = {name: int(np.size(v) - np.count_nonzero(np.isfinite(v))) for name, v in state.items()}
    return {name: c for name, c in counts.items() if c}


def listed(counts: dict[str, int]) -> str:
    """``{"dx": 766}`` as ``"766 dx"`` (several joined by commas)."""
    return ", ".join(f"{count} {field}" for field, count in counts.items())


def check_text(path: str, obj: h5py.Group, what: str) -> None:
    """ArchiveError if the string attributes of ``obj`` differ from their :data:`TEXT_CHECKSUM`
    (archives without one, written before strings were variable-length, are not checked)."""
    with reading(path, what):
        attrs = dict(obj.attrs.items())
    stored = attrs.get(TEXT_CHECKSUM)
    if stored is not None and int(stored) != text_checksum(attrs):
        raise ArchiveError(f"{path}: {what} are damaged (their checksum differs); the archive is corrupted")


# -- rows behind a live counter -------------------------------------------------------------------
def set_counter(ds: h5py.Dataset, value: int) -> None:
    """Write a ``(1,)`` int64 counter (low-level: no h5py indexing machinery per chunk)."""
    ds.id.write(h5s.ALL, h5s.ALL, np.array([value], dtype=np.int64))


def fill_rows(group: h5py.Group, rows: Mapping[str, Any], counter: h5py.Dataset) -> None:
    """Put ``rows`` (name: its values, ``(n, ...)``, the same ``n`` for every name) into the empty
    datasets of a freshly created ``group`` and set ``counter`` to ``n`` (a rebuilt archive)."""
    n = 0
    for name, values in rows.items():
        ds = group[name]
        values = np.asarray(values, dtype=ds.dtype)
        n = len(values)
        if n:
            ds.resize(n, axis=0)
            ds[...] = values.reshape(ds.shape)
    set_counter(counter, n)


class Rows:
    """The datasets ``names`` of ``group``, whose first ``count`` rows are valid (``counter``)."""

    def __init__(self, group: h5py.Group, names: Sequence[str], counter: h5py.Dataset, count: int) -> None:
        self.datasets = {name: group[name] for name in names}
        self.dtypes = {name: ds.dtype for name, ds in self.datasets.items()}
        self.row_shapes = {name: ds.shape[1:] for name, ds in self.datasets.items()}
        # A dataset's chunks never change: their rows, and the file space a new one takes
        self.chunk_rows = {name: ds.chunks[0] for name, ds in self.datasets.items()}
        self.chunk_bytes = {
            name: h5_bytes(ds.dtype.itemsize * int(np.prod(ds.chunks))) for name, ds in self.datasets.items()
        }
        # Per dataset, the memory space of one row and the file space (taken again after a resize)
        self._spaces: dict[str, tuple] = {}
        self.capacity = min(ds.shape[0] for ds in self.datasets.values())
        self.counter = counter
        self.count = count
        self.staged = 0  # rows put since the last commit

    def put(self, row: dict[str, Any]) -> None:
        index = self.count + self.staged
        if index >= self.capacity:
            self.capacity = index + ROW_CHUNK
            for ds in self.datasets.values():
                ds.resize(self.capacity, axis=0)
            self._spaces.clear()
        for name, value in row.items():
            shape = (1, *self.row_shapes[name])
            values = np.ascontiguousarray(value, dtype=self.dtypes[name]).reshape(shape)
            ds = self.datasets[name]
            spaces = self._spaces.get(name)
            if spaces is None:
                spaces = self._spaces[name] = h5s.create_simple(shape), ds.id.get_space()
            spaces[1].select_hyperslab((index,) + (0,) * (len(shape) - 1), shape)
            ds.id.write(spaces[0], spaces[1], values)
        self.staged += 1

    def growth_bytes(self, rows: int = 1) -> int:
        """File space of the new chunks the next ``rows`` :meth:`put` calls allocate (HDF5 allocates a
        chunk at its first write; :func:`~warpratchet._storage.h5_bytes`)."""
        first = self.count + self.staged
        return sum(
            self.chunk_bytes[name] * sum((first + k) % chunk_rows == 0 for k in range(rows))
            for name, chunk_rows in self.chunk_rows.items()
        )

    def commit(self) -> None:
        """Declare the rows put since the last commit valid (call after flushing them)."""
        self.count += self.staged
        self.staged = 0
        set_counter(self.counter, self.count)

    def trim(self) -> None:
        """Cut every dataset to the valid rows (a reader reads at most ``count`` rows anyway)."""
        if self.capacity != self.count:
            for ds in self.datasets.values():
                ds.resize(self.count, axis=0)
            self.capacity = self.count
            self._spaces.clear()


# -- the two checkpoint slots ---------------------------------------------------------------------
#: Attempts at reading a slot that a live writer keeps recycling.
_ATTEMPTS = 10


def read_state(path: str, f: h5py.File, group: str, points: int) -> dict[str, np.ndarray]:
    """The per-point state stored in ``group`` (``"initial"``, ``"checkpoint/a"``, ...), unchecked."""
    state = {}
    for name in STATE_FIELDS:
        with reading(path, f"/{group}/{name}"):
            ds = refresh(f[group][name])
            if ds.shape != (points,):
                raise ArchiveError(f"{path}: /{group}/{name} has shape {ds.shape}, expected ({points},)")
            check_extent(path, ds)
            state[name] = ds[:]
    return state


def slot_step(path: str, f: h5py.File, name: str) -> int:
    """The ``step`` of slot ``name`` (-1: in progress)."""
    with reading(path, f"/checkpoint/{name}/step"):
        ds = refresh(f["checkpoint"][name]["step"])
        check_extent(path, ds)
        return int(ds[0])


def slot_steps(path: str, f: h5py.File, problems: list[str] | None = None) -> list[tuple[int, str]]:
    """Complete slots as ``(step, name)``, newest first (``step`` -1 marks a slot in progress).

    An unreadable slot raises, or is skipped and described in ``problems`` if given.
    """
    out = []
    for name in SLOTS:
        try:
            step = slot_step(path, f, name)
        except ArchiveError as exc:
            if problems is None:
                raise
            problems.append(f"checkpoint slot {name!r} is unreadable ({exc})")
            continue
        if step >= 0:
            out.append((step, name))
    return sorted(out, reverse=True)


def newest_good(
    path: str, f: h5py.File, points: int, read_extra: Callable[[str], Any] | None = None
) -> tuple[tuple[dict[str, np.ndarray], int, Any] | None, list[str]]:
    """``((state, step, extra) or None, problems)``: the newest slot whose data verify and are finite.

    ``read_extra(slot)`` reads what a feature keeps beside the state in a slot (the transport
    state); it raises :class:`ArchiveError` like a damaged state, and ``extra`` is None without it.
    ``problems`` describes the slots skipped on the way (the caller warns); None when no slot is
    good (the caller falls back to the initial state).
    """
    problems: list[str] = []
    for _attempt in range(_ATTEMPTS):
        problems.clear()
        retry = False
        for step, name in slot_steps(path, f, problems):
            try:
                state = read_state(path, f, f"checkpoint/{name}", points)
                extra = read_extra(name) if read_extra is not None else None
            except ArchiveError as exc:
                try:
                    again = slot_step(path, f, name)
                except ArchiveError:
                    again = step
                if again != step:  # recycled meanwhile: a torn read, not damage
                    retry = True
                    break
                problems.append(f"checkpoint at step {step} is unreadable ({exc})")
                continue
            try:
                again = slot_step(path, f, name)
            except ArchiveError as exc:
                problems.append(f"checkpoint at step {step} is unreadable ({exc})")
                continue
            if again != step:  # overwritten while we read: start over
                retry = True
                break
            bad = nonfinite(state)
            if bad:
                problems.append(f"checkpoint at step {step} holds non-finite values ({listed(bad)})")
                continue
            return (state, step, extra), problems
        if not retry:
            break
    return None, problems


def write_slot(
    path: str,
    f: h5py.File,
    free: int,
    state: dict[str, np.ndarray],
    step: int,
    write_extra: Callable[[str], None] | None = None,
    extra_bytes: int = 0,
) -> None:
    """Write the finite ``state`` at ``step`` into slot ``SLOTS[free]``, then make it current.

    ``write_extra(slot)`` writes what a feature keeps beside the state (``extra_bytes`` of it):
    the checkpoint is complete only with it. The caller has checked ``state`` is finite and turns
    a refused write into its error; a kill at any point leaves the other slot current and intact.
    """
    slot = f["checkpoint"][SLOTS[free]]
    if slot["x"].id.get_num_chunks() == 0:  # the slot's first use allocates its space
        needed = sum(dataset_bytes(slot[name]) for name in STATE_FIELDS) + h5_bytes(extra_bytes)
        ensure_space(path, needed, "the checkpoint")
    set_counter(slot["step"], -1)  # in progress: neither a reader nor a recovery may trust it
    f.flush()
    for name in STATE_FIELDS:
        slot[name].write_direct(state[name])
    if write_extra is not None:
        write_extra(SLOTS[free])
    sync_h5(f)  # the data is durable before anything points at it
    set_counter(slot["step"], step)
    set_counter(f["checkpoint"]["current"], free)
    sync_h5(f)


# -- the /snapshots subsample ---------------------------------------------------------------------
#: Salt of the snapshot subsample's generator, so it differs from the sampler's stream.
_SNAPSHOT_SALT = 0x5A4E


@dataclass(frozen=True)
class Snapshots:
    """Phase-space snapshots of a fixed random subsample of ``M`` points.

    Attributes
    ----------
    steps : ndarray, shape (S,), int64
        Iteration numbers of the snapshots.
    indices : ndarray, shape (M,), int64
        Indices of the sampled points in the ensemble (sorted).
    x, p : ndarray, shape (S, M)
        Position and momentum mod 1, both in ``[0, 1)`` (Eq. cpem on the torus).
    ftle : ndarray, shape (S, M)
        Finite-time Lyapunov exponent per iteration.
    finite_time_acceleration : ndarray, shape (S, M)
        Each point's ``A_n`` of Eq. (An), per iteration
        (:func:`~warpratchet.observables.finite_time_acceleration`; the ensemble's ``A`` is their
        mean over the chaotic points).
    """

    steps: np.ndarray
    indices: np.ndarray
    x: np.ndarray
    p: np.ndarray
    ftle: np.ndarray
    finite_time_acceleration: np.ndarray

    #: The former name of :attr:`finite_time_acceleration` (DeprecationWarning).
    A = renamed_attribute("Snapshots", "A", "finite_time_acceleration")

    def __len__(self) -> int:
        return int(self.steps.size)


def snapshot_indices(points: int, m: int, seed: int | None) -> np.ndarray:
    """The sorted int64 indices of ``m`` of ``points`` points, fixed by ``seed`` (None as 0)."""
    return salted_subsample(points, seed, m, _SNAPSHOT_SALT)


def snapshot_row(live: dict[str, np.ndarray], indices: np.ndarray, step: int) -> dict[str, Any]:
    """The snapshot at ``step`` of the points ``indices`` of the state ``live``."""
    sub = {name: live[name][indices] for name in STATE_FIELDS}
    return {
        "step": step,
        "x": sub["x"],
        "p": sub["q"],  # p mod 1 is exactly q
        "ftle": lyapunov(sub, step),
        "finite_time_acceleration": finite_time_acceleration(sub, step),
    }


def read_snapshots(path: str, f: h5py.File, n: int) -> Snapshots:
    """The first ``n`` (valid) snapshots of the archive ``f`` at ``path``."""
    with reading(path, "/snapshots"):
        g = f["snapshots"]
        indices = refresh(g["indices"])[:]
        check_extent(path, g["indices"])
    fields = {"steps": valid_rows(path, g, "step", n), "indices": indices}
    for name in SNAPSHOT_FIELDS:
        with reading(path, "/snapshots"):
            stored = stored_name(g, name)
        rows = valid_rows(path, g, stored, n)
        if n and rows.shape[1] != indices.size:
            raise ArchiveError(f"{path}: /snapshots/{stored} has shape {rows.shape}, expected ({n}, M)")
        fields[name] = rows.reshape(n, indices.size)
    return Snapshots(**fields)
