"""One archive of a sharded run: the merged rows, and the shards' per-point data as virtual datasets.

:func:`write_merged` writes ``out``, an ordinary archive (``docs/archive.md``: ``open_archive``,
``inspect``, ``verify`` and ``to_xarray`` read it) of the whole ensemble of a
:func:`warpratchet.cluster.run_sharded` run whose shards kept their archives in a ``workdir``:

* ``/series`` holds one row at each history step (the steps every shard recorded), the merged
  summary there, bit for bit the single machine's row at that step; ``/history`` the merged
  history;
* ``/initial`` and the checkpoint (slot ``a``, at the last step) are HDF5 virtual datasets: each
  field the concatenation, in global point order, of the same field of the shards' archives
  (their initial state, and the slot their last checkpoint is in). Nothing per point is copied;
  the shards' files must stay where they are (a reader refuses the file while one is missing,
  :class:`~warpratchet.archive.VirtualSourceError`), and their paths are stored relative to
  ``out``'s folder, so the two move together;
* with transport counting, ``/transport`` as a single machine's archive has it: its rows the sums
  of the shards' rows, the checkpoint slot's counts and spread rows the merged ones (bit for bit
  the single machine's), its carry per point virtual datasets over the shards';
* with snapshots, ``/snapshots`` as a single machine's archive has it (the subsample of the whole
  ensemble, the multiples of ``snapshot_every``), each field of
  :data:`~warpratchet.archive._format.SNAPSHOT_FIELDS` a virtual dataset over the shards'
  snapshot files (:func:`snapshot_file`), their columns side by side in global point order.
"""

from __future__ import annotations

import datetime
import os
import time
from typing import Any

import h5py
import numpy as np

from ._h5 import sync_h5
from .archive import _format
from .archive._features import write_history
from .archive._format import COUNTERS, FORMAT_VERSION, SERIES_FIELDS, SLOTS, SNAPSHOT_FIELDS, describe
from .archive._rows import fill_rows, set_counter, snapshot_indices
from .archive._writer import build_file
from .ensemble import STATE_FIELDS
from .spec import CHECKPOINT_SECONDS

__all__ = ["shards_folder", "write_merged"]


def shard_paths(workdir: str | os.PathLike, index: int) -> tuple[str, str]:
    """``(archive, records folder)`` of shard ``index`` in ``workdir``."""
    base = os.path.join(os.fspath(workdir), f"shard-{index:04d}")
    return base + ".h5", base + ".records"


def snapshot_steps(steps: int, snapshot_every: int) -> list[int]:
    """The steps at which an archive of a run of ``steps`` steps takes its snapshots: the multiples
    of ``snapshot_every`` (0: none), where its chunks end (:func:`warpratchet.archive.schedule`)."""
    return list(range(snapshot_every, steps + 1, snapshot_every)) if snapshot_every else []


def snapshot_file(folder: str) -> str:
    """The file of a shard's snapshots in its records ``folder``."""
    return os.path.join(folder, "snapshots.h5")


def _virtual(
    group: h5py.Group, name: str, sources: list[tuple[str, str, int, int]], fill: float | int
) -> None:
    """Replace ``group[name]`` by a virtual dataset over ``sources``: ``(file, dataset, lo, hi)``."""
    dtype = group[name].dtype.type
    attrs = {key: group[name].attrs[key] for key in ("units", "long_name") if key in group[name].attrs}
    points = sources[-1][3]
    virtual = h5py.VirtualLayout(shape=(points,), dtype=dtype)
    for path, dataset, lo, hi in sources:
        virtual[lo:hi] = h5py.VirtualSource(path, dataset, shape=(hi - lo,))
    del group[name]
    ds = group.create_virtual_dataset(name, virtual, fillvalue=dtype(fill))
    if not attrs:
        units, long_name = describe(group.name.lstrip("/"), name)
        attrs = {"units": np.bytes_(units.encode()), "long_name": np.bytes_(long_name.encode())}
    ds.attrs.update(attrs)


def _write_transport(
    f: h5py.File, merged: Any, archives: list, relative: list, slots: list, bounds: list
) -> None:
    """``/transport`` as a :class:`~warpratchet.transport.TransportEnsemble`'s archive has it: its
    rows the sums of the shards' rows (the shards end their chunks at the same steps), the
    checkpoint slot's counts and spread rows the merged ones, its carry per point virtual datasets
    over the shards' (:mod:`warpratchet.archive._features`)."""
    from .archive._features import create_transport, read_transport_rows
    from .transport import CARRY_FIELDS

    create_transport(f, merged.points)
    total = None
    for path in archives:
        with h5py.File(path, "r") as shard:
            rows = read_transport_rows(shard, path)
        if total is None:
            total = rows
        elif np.array_equal(rows["step"], total["step"]):
            total["counts"] = total["counts"] + rows["counts"]
        else:
            raise ValueError(f"{path}: its /transport rows are at other steps than the first shard's")
    fill_rows(f["transport"], total, f["transport"]["rows"])
    slot = f["transport"][SLOTS[0]]
    slot["counts"].write_direct(np.ascontiguousarray(merged.counts, dtype=np.int64))
    for name, values in (("spread_steps", merged.spread_steps), ("spread", merged.spread)):
        slot[name].resize(len(values), axis=0)
        if len(values):
            slot[name].write_direct(np.ascontiguousarray(values))
    for name in CARRY_FIELDS:
        sources = [
            (rel, f"/transport/{s}/{name}", lo, hi)
            for rel, s, (lo, hi) in zip(relative, slots, bounds, strict=True)
        ]
        _virtual(slot, name, sources, 0)


def _current_slot(path: str) -> str:
    """The slot of a shard archive's last checkpoint."""
    with h5py.File(path, "r") as f:
        return SLOTS[int(f["checkpoint"]["current"][0])]


def _write_snapshots(f: h5py.File, steps: list[int], sources: list[tuple[str, int, int]]) -> None:
    """``/snapshots``: the rows at ``steps``, each field of :data:`~._format.SNAPSHOT_FIELDS` a
    virtual dataset ``(snapshots, M)`` over the shards' snapshot files ``(file, lo, hi)``: their
    columns ``lo:hi`` of the subsample, with the datasets' dimension scales attached again."""
    g = f["snapshots"]
    fill_rows(g, {"step": np.asarray(steps, dtype=np.int64)}, f[COUNTERS[FORMAT_VERSION]["snapshots"]])
    if not steps:
        return
    scales = (g["step"], g["indices"])
    shape = (len(steps), g["indices"].shape[0])
    for name in SNAPSHOT_FIELDS:
        old = g[name]
        dtype, fill = old.dtype, old.fillvalue
        attrs = {key: old.attrs[key] for key in ("units", "long_name")}
        for axis, scale in enumerate(scales):
            old.dims[axis].detach_scale(scale)
        del g[name]
        layout = h5py.VirtualLayout(shape=shape, dtype=dtype)
        for path, lo, hi in sources:
            layout[:, lo:hi] = h5py.VirtualSource(path, name, shape=(shape[0], hi - lo))
        ds = g.create_virtual_dataset(name, layout, fillvalue=fill)
        ds.attrs.update(attrs)
        for axis, scale in enumerate(scales):
            ds.dims[axis].attach_scale(scale)


def shards_folder(out: str | os.PathLike) -> str | None:
    """The folder of the shards whose data the merged archive ``out`` reads (the folder of the
    source file of ``/initial``'s virtual datasets, resolved as HDF5 does), or None when ``out``
    has no virtual datasets there (an archive of one machine)."""
    from .archive._reader import virtual_source_path

    out = os.fspath(out)
    with h5py.File(out, "r", locking=False) as f:
        ds = f["initial"][STATE_FIELDS[0]]
        if not ds.is_virtual:
            return None
        return os.path.dirname(os.path.abspath(virtual_source_path(out, ds.virtual_sources()[0].file_name)))


def write_merged(
    out: str | os.PathLike,
    merged: Any,
    workdir: str,
    bounds: list[tuple[int, int]],
    snapshots: tuple[int, int] = (0, 0),
    *,
    replace: bool = False,
) -> None:
    """Write ``out`` for ``merged`` (a :class:`~warpratchet.cluster.ShardedRun`) whose shards'
    archives are in ``workdir`` (module docstring).

    ``snapshots``: ``(snapshot_every, snapshot_points)`` of the run (the shards' snapshot files
    are in their records folders); ``replace``: replace an existing ``out`` (atomically, when the
    new file is complete: the file at ``out`` reads its own shards' files at every instant, the
    old ones until the rename, the new ones after).
    """
    out = os.fspath(out)
    folder = os.path.dirname(os.path.abspath(out))
    archives = [shard_paths(workdir, k)[0] for k in range(len(bounds))]
    relative = [os.path.relpath(shard_paths(workdir, k)[0], folder) for k in range(len(bounds))]
    spec = merged.spec
    every, m = snapshots
    settings = _format.run_settings(
        merged, threshold=spec.threshold, threshold_rule=spec.threshold_rule,
        chunk_steps=spec.chunk_steps or spec.steps, checkpoint_every=spec.steps,
        checkpoint_seconds=CHECKPOINT_SECONDS, snapshot_every=every, snapshot_points=m if every else 0,
    )  # fmt: skip
    indices = snapshot_indices(merged.points, m if every else 0, spec.seed)
    columns = []  # each shard's snapshot file and its columns of the subsample
    for k, (lo, hi) in enumerate(bounds):
        inside = np.flatnonzero((indices >= lo) & (indices < hi))
        if inside.size:
            path = snapshot_file(shard_paths(workdir, k)[1])
            columns.append((os.path.relpath(path, folder), int(inside[0]), int(inside[-1]) + 1))
    fills = {name: np.broadcast_to(_format.FILL[name], (merged.points,)) for name in STATE_FIELDS}
    contents = {
        "params": merged.params,
        "settings": settings,
        "versions": _format.software_versions(),
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "initial": fills,  # every field its fill value: nothing is written, the virtual data follows
        "initial_step": 0,
        "indices": indices,
        "target_step": merged.step,
        "history": merged.history,
    }
    slots = [_current_slot(path) for path in archives]

    def fill(f: h5py.File) -> None:
        for name in STATE_FIELDS:
            sources = [
                (rel, f"/initial/{name}", lo, hi) for rel, (lo, hi) in zip(relative, bounds, strict=True)
            ]
            _virtual(f["initial"], name, sources, _format.FILL[name])
            sources = [
                (rel, f"/checkpoint/{slot}/{name}", lo, hi)
                for rel, slot, (lo, hi) in zip(relative, slots, bounds, strict=True)
            ]
            _virtual(f["checkpoint"][SLOTS[0]], name, sources, 0)
        rows = [merged.summary(spec.threshold, spec.threshold_rule, warn=False, step=n).as_dict()
                for n in merged.history.rows["step"]]  # fmt: skip
        clocks = {"wall_time": np.nan, "unix_time": time.time()}
        series = {name: [clocks.get(name, row.get(name)) for row in rows] for name in SERIES_FIELDS}
        fill_rows(f["series"], series, f[COUNTERS[FORMAT_VERSION]["series"]])
        write_history(f, merged.history)
        if merged.transport:
            _write_transport(f, merged, archives, relative, slots, bounds)
        _write_snapshots(f, snapshot_steps(spec.steps, every), columns)
        set_counter(f["checkpoint"][SLOTS[0]]["step"], merged.step)
        set_counter(f["checkpoint"]["current"], 0)

    def start(f: h5py.File) -> None:
        # closed and durable before it gets its name: a kill after the rename leaves a complete
        # file, not one marked open by a writer
        sync_h5(f)
        name = f.filename
        f.close()
        fd = os.open(name, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)

    build_file(out, contents, start, replace=replace, fill=fill)
