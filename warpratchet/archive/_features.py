"""The optional groups of an archive, named in ``/@features``: each writes, reads and salvages
its group, and readers that do not know a feature ignore its group (docs/archive.md).

The ``/history`` group (feature ``history``), a run's :class:`~warpratchet.history.History`.
Rows and block records of a :class:`~warpratchet.history.History` are written by the archive
sink at each chunk end, in the same flush as the series row and before their counters
(``/progress/history_rows``, ``/progress/block_rows``), so a kill leaves only complete records;
the history of a chunk end is on disk before any checkpoint at that step. A resume keeps the
records up to the checkpoint (the resumed run records the rest, identically), so a resumed
run's history equals the uninterrupted one bit for bit. The layout is created with the rest
(:func:`warpratchet.archive._format.create`).

The ``/transport`` group (feature ``"transport"``). An archive of a
:class:`~warpratchet.transport.TransportEnsemble` run holds, besides the usual layout:

* ``/transport/step`` and ``/transport/counts``: one row per chunk (with the series rows), the
  histograms of completed return gaps and flights so far, ``(3, BINS)`` int64 per row;
  ``/transport/rows``: how many rows are valid (raised after they are on disk, like
  ``/progress/series_rows``);
* ``/transport/a`` and ``/transport/b``: the transport state that belongs to the checkpoint in
  ``/checkpoint/a`` and ``/checkpoint/b`` (the carry state per point, the counts, the spread rows
  of mu), written inside the checkpoint's protocol (before its ``step`` is set), so a checkpoint
  is complete only with its transport state and a resume continues counting exactly.

Everything is created up front (SWMR allows no new objects later); the spread rows grow by
resizing.
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from ..glossary import describe
from ..history import BLOCK_FIELDS, HISTORY_FIELDS, History
from ..spec import attr_value
from ..transport import BINS, CARRY_FIELDS, HISTOGRAMS, counts_transport
from ..transport._fits import GROUPS
from ._format import (
    HISTORY_COUNTERS,
    ROW_CHUNK,
    SLOTS,
    STATE_CHUNK,
    ArchiveError,
    _dimension,
    _group,
    _set_attrs,
    seal,
)
from ._rows import Rows, fill_rows, read_counter, reading, refresh, valid_rows

__all__ = [
    "HistoryWriter",
    "check_history",
    "read_history",
    "history_counts",
    "history_settings",
    "history_info",
    "write_history",
    "TRANSPORT_FEATURE",
    "create_transport",
    "TransportRows",
    "TransportWriter",
    "counts_transport",
    "write_transport_slot",
    "read_transport_slot",
    "read_transport_rows",
    "restore_transport",
]


# -- the /history group ---------------------------------------------------------------------------
def check_history(history: History, threshold: float | None, rule: str) -> None:
    """ValueError unless ``history`` can be kept by a new archive classifying with ``threshold``, ``rule``."""
    if not isinstance(history, History):
        raise ValueError(f"history = {history!r} is not a History")
    if (history.threshold, history.threshold_rule) != (threshold, rule):
        raise ValueError(
            f"the history classifies with threshold = {history.threshold!r}, "
            f"threshold_rule = {history.threshold_rule!r}; "
            f"the archive with threshold = {threshold!r}, threshold_rule = {rule!r}"
        )
    if history.rows["step"] or history.block_rows["block_step"]:
        raise ValueError(
            "history holds records of an earlier run; a new archive needs a new History "
            "(ArchiveSink.resume continues an archived one)"
        )


class HistoryWriter:
    """Appends the records of ``history`` that are not in the file yet (``rows``, ``blocks`` are)."""

    def __init__(self, f: h5py.File, history: History, rows: int, blocks: int) -> None:
        self.history = history
        g = f["history"]
        self.rows = Rows(g, HISTORY_FIELDS, f[HISTORY_COUNTERS["rows"]], rows)
        self.blocks = Rows(g, BLOCK_FIELDS, f[HISTORY_COUNTERS["blocks"]], blocks)

    def record(self, ensemble: Any) -> None:
        """Make sure the history holds its record of this step (``after_chunk`` is idempotent), and
        that it has not missed earlier steps (it must be an observer of the run, for its stops)."""
        missed = self.history.overdue(ensemble.step)
        self.history.after_chunk(ensemble, 0.0)
        if missed:
            raise ValueError(
                f"the archive's history missed its step {missed[0]}: pass sink.history to Ensemble.run "
                "among the observers (it ends chunks at its steps)"
            )

    def _new(self) -> tuple[int, int]:
        return (
            len(self.history.rows["step"]) - self.rows.count - self.rows.staged,
            len(self.history.block_rows["block_step"]) - self.blocks.count - self.blocks.staged,
        )

    def growth_bytes(self) -> int:
        """Bytes of new chunks the records waiting to be written allocate."""
        rows, blocks = self._new()
        return self.rows.growth_bytes(rows) + self.blocks.growth_bytes(blocks)

    def put(self) -> None:
        """Write every record not yet in the file (not yet valid: :meth:`commit` after a flush)."""
        h = self.history
        for i in range(self.rows.count + self.rows.staged, len(h.rows["step"])):
            self.rows.put({name: h.rows[name][i] for name in HISTORY_FIELDS})
        for i in range(self.blocks.count + self.blocks.staged, len(h.block_rows["block_step"])):
            self.blocks.put({name: h.block_rows[name][i] for name in BLOCK_FIELDS})

    def commit(self) -> None:
        if self.rows.staged:
            self.rows.commit()
        if self.blocks.staged:
            self.blocks.commit()

    def trim(self) -> None:
        self.rows.trim()
        self.blocks.trim()


def history_counts(path: str, f: h5py.File) -> tuple[int, int]:
    """The valid ``(rows, block records)`` of the ``/history`` of an open archive."""
    return read_counter(path, f, HISTORY_COUNTERS["rows"]), read_counter(path, f, HISTORY_COUNTERS["blocks"])


def history_settings(path: str, f: h5py.File, settings: dict[str, Any]) -> dict[str, Any]:
    """The :class:`History` keywords of an archive: the run's threshold and rule, the group's attributes."""
    from ..spec import attr_value

    with reading(path, "/history"):
        attrs = {k: attr_value(v) for k, v in f["history"].attrs.items()}
    return {
        "threshold": settings.get("threshold"),
        "threshold_rule": settings.get("threshold_rule") or "strict",
        "per_decade": int(attrs["per_decade"]),
        "blocks": int(attrs["blocks"]),
        "block_points": max(2, int(attrs["block_points"])),
    }


def read_history(path: str, f: h5py.File, settings: dict[str, Any]) -> History:
    """The :class:`History` stored in an open archive (its valid records), ready to continue."""
    n_rows, n_blocks = history_counts(path, f)
    with reading(path, "/history"):
        g = f["history"]
    rows = {name: valid_rows(path, g, name, n_rows) for name in HISTORY_FIELDS}
    blocks = {name: valid_rows(path, g, name, n_blocks) for name in BLOCK_FIELDS}
    with reading(path, "/history/block_indices"):
        indices = refresh(g["block_indices"])[:]
    return History.restore(rows, blocks, indices, **history_settings(path, f, settings))


def history_info(history: History | None) -> dict[str, Any] | None:
    """Rows and block records of a history and the verdict at its last row (what ``inspect`` shows)."""
    if history is None:
        return None
    info: dict[str, Any] = {
        "rows": len(history.rows["step"]),
        "blocks": len(history.block_rows["block_step"]),
    }
    if history.rows["step"]:
        info["convergence"] = history.convergence().as_dict()
    return info


def write_history(f: h5py.File, history: History) -> None:
    """Put the records of ``history`` into the freshly created ``/history`` of ``f`` (a rebuilt archive)."""
    for names, records, key in (
        (HISTORY_FIELDS, history.rows, "rows"),
        (BLOCK_FIELDS, history.block_rows, "blocks"),
    ):
        fill_rows(f["history"], {name: records[name] for name in names}, f[HISTORY_COUNTERS[key]])


# -- the /transport group -------------------------------------------------------------------------
#: The feature name in ``/@features``.
TRANSPORT_FEATURE = "transport"


def _dataset(group: h5py.Group, name: str, **kw: Any) -> h5py.Dataset:
    ds = group.create_dataset(name, fletcher32=True, **kw)
    units, long_name = describe("transport", name)  # slot datasets by their own name
    _set_attrs(ds, {"units": units, "long_name": long_name})
    return ds


def create_transport(f: h5py.File, points: int) -> None:
    """Create ``/transport`` (rows, counter, both slots) and list the feature in ``/@features``."""
    features = [name for name in str(attr_value(f.attrs["features"])).split(",") if name]
    _set_attrs(f, {"features": ",".join([*features, TRANSPORT_FEATURE])})
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
        return (lambda slot: write_transport_slot(self._file, slot, state)), sum(
            v.nbytes for v in state.carry.values()
        )


def write_transport_slot(f: h5py.File, slot: str, transport: Any) -> None:
    """Write a :class:`~warpratchet.transport._ensemble.TransportState` into ``/transport/<slot>``."""
    s = f["transport"][slot]
    for name in CARRY_FIELDS:
        s[name].write_direct(np.ascontiguousarray(transport.carry[name], dtype=np.int64))
    s["counts"].write_direct(np.ascontiguousarray(transport.counts, dtype=np.int64))
    rows = int(transport.spread_steps.size)
    for name, values in (("spread_steps", transport.spread_steps), ("spread", transport.spread)):
        s[name].resize(rows, axis=0)
        if rows:
            s[name].write_direct(np.ascontiguousarray(values))


def read_transport_slot(f: h5py.File, path: str, slot: str, points: int) -> Any:
    """The transport state in ``/transport/<slot>`` (ArchiveError if it is unreadable)."""
    from ..transport._ensemble import TransportState

    with reading(path, f"/transport/{slot}"):
        s = f["transport"][slot]
        carry = {}
        for name in CARRY_FIELDS:
            ds = refresh(s[name])
            if ds.shape != (points,):
                raise ArchiveError(
                    f"{path}: /transport/{slot}/{name} has shape {ds.shape}, expected ({points},)"
                )
            carry[name] = ds[:]
        return TransportState(
            carry=carry,
            counts=refresh(s["counts"])[:],
            spread_steps=refresh(s["spread_steps"])[:],
            spread=refresh(s["spread"])[:],
        )


def read_transport_rows(f: h5py.File, path: str) -> dict[str, np.ndarray]:
    """The valid rows: ``step`` ``(R,)`` int64, ``counts`` ``(R, 3, BINS)`` int64."""
    n = read_counter(path, f, "transport/rows")
    with reading(path, "/transport"):
        g = f["transport"]
    return {name: valid_rows(path, g, name, n) for name in ("step", "counts")}


def restore_transport(
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
