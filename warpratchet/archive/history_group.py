"""The optional ``/history`` group of an archive (feature ``history``): a run's :class:`History`.

Rows and block records of a :class:`~warpratchet.history.History` are written by the archive
sink at each chunk end, in the same flush as the series row and before their counters
(``/progress/history_rows``, ``/progress/block_rows``), so a kill leaves only complete records;
the history of a chunk end is on disk before any checkpoint at that step. A resume keeps the
records up to the checkpoint (the resumed run records the rest, identically), so a resumed
run's history equals the uninterrupted one bit for bit. The layout is created with the rest
(:func:`warpratchet.archive._format.create`); this module writes, reads and salvages it.
"""

from __future__ import annotations

from typing import Any

import h5py

from ..history import BLOCK_FIELDS, HISTORY_FIELDS, History
from ._format import HISTORY_COUNTERS
from ._rows import Rows, fill_rows, read_counter, reading, valid_rows
from ._rows import refresh as _refresh

__all__ = [
    "HistoryWriter",
    "check_history",
    "read_history",
    "history_counts",
    "history_settings",
    "history_info",
    "write_history",
]


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
        indices = _refresh(g["block_indices"])[:]
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
