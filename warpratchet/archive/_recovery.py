"""Recovering an archive: what a resume keeps of it, and checking every byte of it.

What a resume keeps, and putting it back into the rebuilt file:
:meth:`ArchiveSink.resume <warpratchet.archive.ArchiveSink.resume>` rebuilds an archive
from what is valid in it: the metadata, the initial state, the series rows and snapshots up to
the newest good checkpoint, and that checkpoint. :func:`salvage` reads all of it (refusing a
kernel that would not continue the run bit for bit); :meth:`Salvage.write` puts it into the new
file, whose layout :func:`~warpratchet.archive._format.create` has made. Rows past the checkpoint
are dropped: the resumed run writes them again, identically (only their clocks differ). The
rebuilt file has today's layout and names: a file of an earlier format keeps its values, and its
snapshots' ``A`` (before minor version 2) becomes ``finite_time_acceleration``.

Damage costs only what it hit: a series row or snapshot whose checksum fails is
left out, a damaged initial state of a sampled ensemble is sampled again (the samplers are
deterministic), otherwise the checkpoint becomes the archive's initial state; each is named in
one :class:`~warpratchet.archive.ArchiveWarning`.

Checking every byte of an archive that can be checked (``warpratchet verify``):
:func:`verify_archive` reads every dataset whole (so HDF5 verifies the Fletcher-32 checksum of
every stored chunk, and of the metadata on the way), every attribute, checks that no chunk lies
past the end of the file, that the counters fit their datasets, that steps grow, and that the
initial state and every complete checkpoint are finite (release 0.1.0 could checkpoint a
non-finite state). It reports; it never repairs (``warpratchet resume`` keeps what verifies).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np

from .._files import claim, h5_bytes
from .._h5verify import first_line, read_everything, read_rows
from ..ensemble import STATE_FIELDS, Ensemble
from ..history import BLOCK_FIELDS, HISTORY_FIELDS, History
from ..spec import SAMPLERS
from ._features import (
    TRANSPORT_FEATURE,
    history_counts,
    history_settings,
    read_transport_rows,
    write_history,
    write_transport_slot,
)
from ._format import (
    COUNTERS,
    FILL,
    FORMAT_VERSION,
    ROW_CHUNK,
    SERIES_FIELDS,
    SLOTS,
    SNAPSHOT_FIELDS,
    STATE_CHUNK,
    ArchiveError,
    ArchiveWarning,
    kernel_constants,
    stored_name,
)
from ._reader import Archive, Snapshots, missing_virtual_sources
from ._rows import fill_rows, listed, nonfinite, read_counter, reading, slot_step

__all__ = [
    "Salvage",
    "rebuilt_bytes",
    "salvage",
    "verify_archive",
]


# -- what a resume keeps --------------------------------------------------------------------------
@dataclass(frozen=True)
class Salvage:
    """The valid part of an archive, up to its newest good checkpoint (one field per part)."""

    #: Restored bit for bit at ``step``.
    ensemble: Ensemble
    #: The checkpoint's state (keys ``STATE_FIELDS``), at ``step``.
    state: dict[str, np.ndarray]
    #: The checkpoint's step (the initial step if there is no checkpoint).
    step: int
    #: Keyword arguments of :func:`~warpratchet.archive._format.create` (metadata, stored settings,
    #: initial state, snapshot indices).
    layout: dict[str, Any]
    #: The rows up to ``step``, keys :data:`SERIES_FIELDS`.
    series: dict[str, np.ndarray]
    #: The snapshots up to ``step``.
    snapshots: Snapshots
    #: The ``/history`` records up to ``step`` (feature ``history``; else None), also
    #: ``layout["history"]``.
    history: History | None = None
    #: The ``/transport`` rows up to ``step`` (feature ``transport``; else None).
    transport_rows: dict[str, np.ndarray] | None = None

    @property
    def rows(self) -> int:
        return int(self.series["step"].size)

    def write(self, f: h5py.File) -> None:
        """Put the rows, snapshots and checkpoint into a freshly created layout ``f``."""
        counters = COUNTERS[FORMAT_VERSION]
        fill_rows(f["series"], self.series, f[counters["series"]])
        snaps = self.snapshots
        kept = {"step": snaps.steps, **{name: getattr(snaps, name) for name in SNAPSHOT_FIELDS}}
        fill_rows(f["snapshots"], kept, f[counters["snapshots"]])
        if self.history is not None:
            write_history(f, self.history)
        if self.transport_rows is not None:
            fill_rows(f["transport"], self.transport_rows, f["transport"]["rows"])
        if self.step != self.layout["initial_step"]:
            slot = f["checkpoint"]["a"]
            for name in STATE_FIELDS:
                slot[name].write_direct(np.ascontiguousarray(self.state[name]))
            if self.transport_rows is not None:
                write_transport_slot(f, "a", self.ensemble.transport_state())
            slot["step"][0] = self.step
            f["checkpoint"]["current"][0] = 0


def _readable_rows(
    arc: Archive, group: str, names: Sequence[str], n: int, problems: list[str]
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The first ``n`` rows of ``/group/<names>`` and which rows every dataset could give, under
    ``names`` (a dataset stored under a former name is found by it, :func:`stored_name`).

    Reads each dataset whole; one whose checksum fails is read row by row, and its damaged rows
    are marked (one problem line per dataset).
    """
    ok = np.ones(n, dtype=bool)
    out = {}
    for field in names:
        name = stored_name(arc.h5[group], field)
        ds = arc.h5[group][name]
        try:
            with reading(arc.path, f"/{group}/{name}"):
                out[field] = read_rows(ds, n)
            continue
        except ArchiveError:
            pass
        values = np.zeros((n, *ds.shape[1:]), dtype=ds.dtype)
        bad = []
        for i in range(n):
            try:
                with reading(arc.path, f"/{group}/{name}"):
                    values[i] = ds[i]
            except ArchiveError:
                bad.append(i)
        ok[bad] = False
        problems.append(f"{len(bad)} damaged row(s) of /{group}/{name}")
        out[field] = values
    return out, ok


def _initial(arc: Archive, state: dict[str, np.ndarray], step: int, problems: list[str]) -> tuple[dict, int]:
    """The initial state to keep, and its step (a damaged one is sampled again or replaced)."""
    try:
        return arc.initial, arc.initial_step
    except ArchiveError as exc:
        s = arc.settings
        if s["init"] in SAMPLERS and s["seed"] is not None and arc.initial_step == 0:
            problems.append(
                f"the initial state is unreadable ({exc}); sampled it again ({s['init']}, seed {s['seed']})"
            )
            again = Ensemble.sample(arc.params, arc.points, s["init"], s["seed"], threads=1)
            return again.state(), 0
        problems.append(f"the initial state is unreadable ({exc}); the checkpoint at step {step} replaces it")
        return state, step


def salvage(path: str | os.PathLike, *, threads: int | None = None, device: str | None = None) -> Salvage:
    """Read what a resume of ``path`` keeps (the caller holds the file's exclusive lock).

    Raises
    ------
    ArchiveError
        Unreadable or incompatible archive, including one written with other renormalisation
        constants than this kernel's (a resumed run would not continue it bit for bit).
    """
    path = os.fspath(path)
    problems: list[str] = []
    with Archive(path, locking=False) as arc:
        s = arc.settings
        for key, ours in kernel_constants().items():
            if s.get(key) != ours:
                raise ArchiveError(
                    f"{path}: written with {key} = {s.get(key)!r} but this kernel uses {ours!r}; "
                    "a resumed run would not continue it bit for bit"
                )
        state, step, transport = arc.checkpoint_with_transport()
        ensemble = arc.restore(state, step, threads, device, transport)
        transport_rows = None
        if TRANSPORT_FEATURE in arc.features:
            rows = read_transport_rows(arc.h5, path)
            kept_rows = rows["step"] <= step
            transport_rows = {name: values[kept_rows] for name, values in rows.items()}
        series, ok = _readable_rows(arc, "series", SERIES_FIELDS, arc.rows, problems)
        keep = ok & (series["step"] <= step)
        with reading(path, "/snapshots/indices"):
            indices = arc.h5["snapshots"]["indices"][:]
        snaps, snap_ok = _readable_rows(
            arc, "snapshots", ("step", *SNAPSHOT_FIELDS), arc.snapshot_count, problems
        )
        kept = snap_ok & (snaps["step"] <= step)
        initial, initial_step = _initial(arc, state, step, problems)
        history = _history(arc, step, problems) if "history" in arc.features else None
        layout = {
            "params": arc.params,
            "settings": dict(s),
            "versions": dict(arc.versions),
            "created": arc.created,
            "initial": initial,
            "initial_step": initial_step,
            "indices": indices,
            "target_step": arc.target_step if arc.target_step is not None else -1,
            "history": history,
        }
    if problems:
        warnings.warn(f"{path}: {'; '.join(problems)}; skipped", ArchiveWarning, stacklevel=3)
    width = indices.size
    return Salvage(
        ensemble=ensemble,
        state=state,
        step=step,
        layout=layout,
        series={name: values[keep] for name, values in series.items()},
        snapshots=Snapshots(
            steps=snaps["step"][kept],
            indices=indices,
            **{name: snaps[name][kept].reshape(int(kept.sum()), width) for name in SNAPSHOT_FIELDS},
        ),
        history=history,
        transport_rows=transport_rows,
    )


def _history(arc: Archive, step: int, problems: list[str]) -> History:
    """The ``/history`` records up to ``step`` (damaged ones left out, like series rows)."""
    n_rows, n_blocks = history_counts(arc.path, arc.h5)
    rows, ok = _readable_rows(arc, "history", HISTORY_FIELDS, n_rows, problems)
    keep = ok & (rows["step"] <= step)
    blocks, block_ok = _readable_rows(arc, "history", BLOCK_FIELDS, n_blocks, problems)
    kept = block_ok & (blocks["block_step"] <= step)
    with reading(arc.path, "/history/block_indices"):
        indices = arc.h5["history"]["block_indices"][:]
    return History.restore(
        {name: values[keep] for name, values in rows.items()},
        {name: values[kept] for name, values in blocks.items()},
        indices,
        **history_settings(arc.path, arc.h5, arc.settings),
    )


def _increasing(values: np.ndarray) -> bool:
    return bool(np.all(np.diff(values) > 0))


def _check_history(arc: Archive, problems: list[str]) -> None:
    """The ``/history`` counters fit their datasets and its steps grow."""
    try:
        rows, blocks = history_counts(arc.path, arc.h5)
        g = arc.h5["history"]
        for count, name, what in ((rows, "step", "history_rows"), (blocks, "block_step", "block_rows")):
            if count > g[name].shape[0]:
                problems.append(f"progress/{what} = {count} but /history/{name} has {g[name].shape[0]} rows")
            elif not _increasing(g[name][:count]):
                problems.append(f"/history/{name} is not increasing")
    except (ArchiveError, KeyError, OSError, RuntimeError) as exc:
        problems.append(f"/history: damaged ({first_line(exc)})")


def rebuilt_bytes(old: Salvage) -> int:
    """Estimated file space of the data a rebuilt archive holds beside its layout.

    The state arrays (initial, checkpoint, transport state) take chunks of ``STATE_CHUNK``
    values, the rows whole chunks of ``ROW_CHUNK`` rows (one row per chunk where a row is an
    array, as a snapshot's); :func:`~warpratchet._storage.h5_bytes` adds HDF5's share.
    """
    initial = old.layout["initial"]
    states = [{k: v for k, v in initial.items() if np.any(v != FILL[k])}]  # a uniform field: no storage
    if old.step != old.layout["initial_step"]:
        states.append(old.state)
        if old.transport_rows is not None:
            carry = old.ensemble.transport_state()
            states.append({**carry.carry, "counts": carry.counts})
    rows = [old.series, old.transport_rows or {}]
    rows.append({name: getattr(old.snapshots, name) for name in ("steps", *SNAPSHOT_FIELDS)})
    if old.history is not None:
        rows += [old.history.rows, old.history.block_rows]
    total = sum(
        h5_bytes(v.nbytes, -(-v.size // STATE_CHUNK)) for s in states for v in map(np.asarray, s.values())
    )
    for group in rows:
        for v in map(np.asarray, group.values()):
            if v.ndim > 1:  # one row per chunk
                total += h5_bytes(v.nbytes, len(v))
            else:  # whole chunks of ROW_CHUNK rows
                chunks = -(-len(v) // ROW_CHUNK)
                total += h5_bytes(chunks * ROW_CHUNK * v.itemsize, chunks)
    return total


# -- verify ---------------------------------------------------------------------------------------
@contextlib.contextmanager
def _alone(path: str) -> Iterator[None]:
    """Hold an exclusive claim on ``path`` for the block, or ArchiveError naming it "in use"."""
    if not os.path.exists(path):
        yield  # Archive names it missing
        return
    try:
        fd = claim(path, exclusive=True)
    except BlockingIOError as exc:
        raise ArchiveError(f"{exc}; verify it once the run is done") from None
    except FileExistsError as exc:
        raise ArchiveError(str(exc)) from None
    try:
        yield
    finally:
        os.close(fd)


def verify_archive(path: str | os.PathLike) -> tuple[list[str], dict[str, Any]]:
    """Every problem of the archive at ``path`` (empty: clean) and what was checked.

    Returns
    -------
    (problems, checked)
        ``problems``: one line each (damaged datasets or metadata, counters beyond their data,
        steps out of order, non-finite states). ``checked``: format, version, counts of datasets,
        attributes and bytes read.

    Raises
    ------
    ArchiveError
        The file is not a warpratchet archive (or not one this release reads) at all, or it is
        in use by another process (a run writing it shows writes in progress, not damage:
        verify it once the run is done).
    """
    path = os.fspath(path)
    problems: list[str] = []
    # The claim excludes every writer, so HDF5's own lock (which our claim would refuse) is not taken.
    with _alone(path), Archive(path, locking=False, check_sources=False) as arc:
        problems.extend(missing_virtual_sources(arc.h5, path))
        counts = read_everything(arc.h5, path, problems)
        checked = {"format": "warpratchet-archive", "format_version": arc.format_version, **counts}
        for key, where in COUNTERS[arc.format_version].items():
            try:
                value = read_counter(path, arc.h5, where, signed=key == "target")
            except ArchiveError as exc:
                problems.append(str(exc).removeprefix(f"{path}: "))
                continue
            if key == "target":
                continue
            group = "series" if key == "series" else "snapshots"
            try:
                size = arc.h5[group]["step"].shape[0]
            except (OSError, KeyError, RuntimeError) as exc:
                problems.append(f"/{group}/step: damaged metadata ({first_line(exc)})")
                continue
            if value > size:
                problems.append(f"{where} = {value} but /{group} has {size} rows")
        if "history" in arc.features:
            _check_history(arc, problems)
        for what, read in (
            ("series", lambda: arc.series["step"]),
            ("snapshots", lambda: arc.snapshots.steps),
        ):
            try:
                steps = read()
            except (ArchiveError, KeyError):
                continue  # already reported as damaged data
            if not _increasing(steps):
                problems.append(f"/{what}/step is not increasing")
        states = [("initial", f"the initial state (step {arc.initial_step})")]
        for slot in SLOTS:
            try:
                step = slot_step(path, arc.h5, slot)
            except ArchiveError:
                continue
            if step >= 0:
                states.append((f"checkpoint/{slot}", f"the checkpoint at step {step} (slot {slot})"))
        for group, label in states:
            try:
                bad = nonfinite(arc.read_state(group))
            except (ArchiveError, KeyError):
                continue  # reported above
            if bad:
                problems.append(f"{label} holds non-finite values ({listed(bad)}); resume skips it")
    return problems, checked
