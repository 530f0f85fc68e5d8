"""The optional ``/transport`` group of an archive (feature ``"transport"``).

An archive of a :class:`~warpratchet.transport.TransportEnsemble` run holds, besides the usual
layout:

* ``/transport/step`` and ``/transport/counts``: one row per chunk (with the series rows), the
  histograms of completed return gaps and flights so far, ``(3, BINS)`` int64 per row;
  ``/transport/rows``: how many rows are valid (raised after they are on disk, like
  ``/progress/series_rows``);
* ``/transport/a`` and ``/transport/b``: the transport state that belongs to the checkpoint in
  ``/checkpoint/a`` and ``/checkpoint/b`` (the carry state per point, the counts, the spread rows
  of mu), written inside the checkpoint's protocol (before its ``step`` is set), so a checkpoint
  is complete only with its transport state and a resume continues counting exactly.

Everything is created up front (SWMR allows no new objects later); the spread rows grow by
resizing. Readers that do not know the feature ignore the group (docs/archive.md).
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from ..glossary import describe
from ..spec import attr_value
from ..transport.fits import GROUPS
from ..transport.histograms import BINS, CARRY_FIELDS, HISTOGRAMS
from ..transport.report import counts_transport
from ._format import ROW_CHUNK, SLOTS, STATE_CHUNK, ArchiveError, _dimension, _group, _set_attrs, seal
from ._rows import Rows, read_counter, reading, valid_rows
from ._rows import refresh as _refresh

__all__ = [
    "FEATURE",
    "create",
    "TransportRows",
    "TransportWriter",
    "counts_transport",
    "write_slot",
    "read_slot",
    "read_rows",
    "restore",
]

#: The feature name in ``/@features``.
FEATURE = "transport"


def _dataset(group: h5py.Group, name: str, **kw: Any) -> h5py.Dataset:
    ds = group.create_dataset(name, fletcher32=True, **kw)
    units, long_name = describe("transport", name)  # slot datasets by their own name
    _set_attrs(ds, {"units": units, "long_name": long_name})
    return ds


def create(f: h5py.File, points: int) -> None:
    """Create ``/transport`` (rows, counter, both slots) and list the feature in ``/@features``."""
    features = [name for name in str(attr_value(f.attrs["features"])).split(",") if name]
    _set_attrs(f, {"features": ",".join([*features, FEATURE])})
    seal(f)
    g = _group(f, "transport")
    _set_attrs(g, {"bins": BINS, "groups": GROUPS, "histograms": ",".join(HISTOGRAMS)})
    # Every axis is a named (netCDF) dimension: rows, histogram, bin, point, group, moment.
    dims = {
        name: _dimension(g, name, size)
        for name, size in (
            ("counter", 1),
            ("histogram", len(HISTOGRAMS)),
            ("bin", BINS),
            ("point", points),
            ("group", GROUPS),
            ("moment", 3),
        )
    }
    step = _dataset(g, "step", shape=(0,), maxshape=(None,), chunks=(ROW_CHUNK,), dtype=np.int64)
    step.make_scale("step")
    counts = _dataset(
        g, "counts", shape=(0, len(HISTOGRAMS), BINS), maxshape=(None, len(HISTOGRAMS), BINS),
        chunks=(16, len(HISTOGRAMS), BINS), dtype=np.int64,
    )  # fmt: skip
    _attach(counts, step, dims["histogram"], dims["bin"])
    _attach(_dataset(g, "rows", data=np.zeros(1, np.int64), chunks=(1,)), dims["counter"])
    width = (min(points, STATE_CHUNK),)
    for slot in SLOTS:
        s = _group(g, slot)
        for name in CARRY_FIELDS:
            _attach(_dataset(s, name, shape=(points,), dtype=np.int64, chunks=width), dims["point"])
        shape = (len(HISTOGRAMS), BINS)
        counts = _dataset(s, "counts", shape=shape, dtype=np.int64, chunks=shape)
        _attach(counts, dims["histogram"], dims["bin"])
        steps = _dataset(s, "spread_steps", shape=(0,), maxshape=(None,), chunks=(64,), dtype=np.int64)
        steps.make_scale("spread_steps")
        spread = _dataset(
            s,
            "spread",
            shape=(0, GROUPS, 3),
            maxshape=(None, GROUPS, 3),
            chunks=(64, GROUPS, 3),
            dtype=np.float64,
        )
        _attach(spread, steps, dims["group"], dims["moment"])


def _attach(ds: h5py.Dataset, *scales: h5py.Dataset) -> None:
    """Name each axis of ``ds`` by its dimension scale, in order."""
    for axis, scale in enumerate(scales):
        ds.dims[axis].attach_scale(scale)


class TransportRows(Rows):
    """``/transport/step`` and ``/transport/counts`` behind the ``/transport/rows`` counter."""

    def __init__(self, f: h5py.File, count: int) -> None:
        super().__init__(f["transport"], ("step", "counts"), f["transport"]["rows"], count)


class TransportWriter:
    """The ``/transport`` group of a running archive: a row with the series row of each chunk,
    the transport state beside each checkpoint (the interface of ``HistoryWriter``)."""

    def __init__(self, f: h5py.File) -> None:
        self._file = f
        self.rows = TransportRows(f, int(f["transport"]["rows"][0]))  # a resume's fill put some there
        self._row: dict[str, Any] | None = None

    def record(self, ensemble: Any) -> None:
        self._row = {"step": ensemble.step, "counts": ensemble.histograms().counts()}

    def growth_bytes(self) -> int:
        return self.rows.growth_bytes()

    def put(self) -> None:
        self.rows.put(self._row)

    def commit(self) -> None:
        self.rows.commit()

    def trim(self) -> None:
        self.rows.trim()

    def slot_extra(self, ensemble: Any) -> tuple[Any, int]:
        """``(write(slot), bytes)``: the transport state a checkpoint is complete only with."""
        state = ensemble.transport_state()
        return (lambda slot: write_slot(self._file, slot, state)), sum(v.nbytes for v in state.carry.values())


def write_slot(f: h5py.File, slot: str, transport: Any) -> None:
    """Write a :class:`~warpratchet.transport.ensemble.TransportState` into ``/transport/<slot>``."""
    s = f["transport"][slot]
    for name in CARRY_FIELDS:
        s[name].write_direct(np.ascontiguousarray(transport.carry[name], dtype=np.int64))
    s["counts"].write_direct(np.ascontiguousarray(transport.counts, dtype=np.int64))
    rows = int(transport.spread_steps.size)
    for name, values in (("spread_steps", transport.spread_steps), ("spread", transport.spread)):
        s[name].resize(rows, axis=0)
        if rows:
            s[name].write_direct(np.ascontiguousarray(values))


def read_slot(f: h5py.File, path: str, slot: str, points: int) -> Any:
    """The transport state in ``/transport/<slot>`` (ArchiveError if it is unreadable)."""
    from ..transport.ensemble import TransportState

    with reading(path, f"/transport/{slot}"):
        s = f["transport"][slot]
        carry = {}
        for name in CARRY_FIELDS:
            ds = _refresh(s[name])
            if ds.shape != (points,):
                raise ArchiveError(
                    f"{path}: /transport/{slot}/{name} has shape {ds.shape}, expected ({points},)"
                )
            carry[name] = ds[:]
        return TransportState(
            carry=carry,
            counts=_refresh(s["counts"])[:],
            spread_steps=_refresh(s["spread_steps"])[:],
            spread=_refresh(s["spread"])[:],
        )


def read_rows(f: h5py.File, path: str) -> dict[str, np.ndarray]:
    """The valid rows: ``step`` ``(R,)`` int64, ``counts`` ``(R, 3, BINS)`` int64."""
    n = read_counter(path, f, "transport/rows")
    with reading(path, "/transport"):
        g = f["transport"]
    return {name: valid_rows(path, g, name, n) for name in ("step", "counts")}


def restore(
    params: Any,
    state: dict[str, np.ndarray],
    step: int,
    transport: Any,
    threshold: Any,
    threshold_rule: str = "strict",
    **kwargs: Any,
):
    """A :class:`~warpratchet.transport.TransportEnsemble` holding ``state`` at ``step``, counting
    on from ``transport`` (a ``TransportState``; None: counting starts at ``step``), with the
    run's chaos ``threshold`` and ``threshold_rule``; ``kwargs`` as :meth:`Ensemble.from_state`."""
    from ..transport import TransportEnsemble

    ensemble = TransportEnsemble.from_state(params, state, step, transport=transport, **kwargs)
    return ensemble.classify_with(threshold, threshold_rule)
