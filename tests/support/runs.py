"""Runs compared bit for bit: states, sweep rows and histories."""

from __future__ import annotations

import struct
from collections.abc import Callable

import numpy as np

from warpratchet import Observer
from warpratchet.ensemble import STATE_FIELDS
from warpratchet.history import BLOCK_FIELDS, HISTORY_FIELDS, History


class Capture(Observer):
    """Copies of the state at the start of a run and after chunks, keyed by step.

    ``keep(step)`` chooses the chunk ends to copy (default: all); the reference states that
    checkpoints and resumed runs are compared with.
    """

    def __init__(self, keep: Callable[[int], bool] = lambda step: True) -> None:
        self.keep = keep
        self.states: dict[int, dict[str, np.ndarray]] = {}

    def begin(self, ensemble, target_step):
        self.states[ensemble.step] = ensemble.state()

    def after_chunk(self, ensemble, seconds):
        if self.keep(ensemble.step):
            self.states[ensemble.step] = ensemble.state()


def bits(value: object) -> object:
    """Exact identity of a value: a float by its bits, so NaN equals NaN and -0.0 is not 0.0; any
    other value with its type."""
    return struct.pack("<d", value) if isinstance(value, float) else (type(value), value)


def exact_rows(rows: list[dict], skip=()) -> list[dict]:
    """Rows (sweep rows: field -> value) in a form that compares bit for bit (:func:`bits`), without
    the fields in ``skip``."""
    return [{k: bits(v) for k, v in row.items() if k not in skip} for row in rows]


def same_state(a: dict, b: dict) -> bool:
    """Two ensemble states equal bit for bit in every field of ``STATE_FIELDS``."""
    return all(np.array_equal(a[k], b[k]) for k in STATE_FIELDS)


def same_history(a: History | dict, b: History | dict, prefix: bool = False) -> bool:
    """Two histories equal bit for bit (NaN equal to NaN).

    ``a`` and ``b`` are :class:`~warpratchet.history.History` objects, compared in their rows (every
    field of ``HISTORY_FIELDS``), block records (every field of ``BLOCK_FIELDS``) and block
    subsample, or dicts of rows (field -> sequence: ``History.as_dict()``, ``run --json``'s
    ``history``, whose JSON null is read as NaN), compared in their rows. With ``prefix``, ``a`` holds
    the first rows (and block records) of ``b`` rather than all of them.
    """

    def parts(h: History | dict) -> tuple:
        return (h.rows, h.block_rows, h.block_indices) if isinstance(h, History) else (h, None, None)

    def same(x: dict, y: dict, fields: tuple[str, ...]) -> bool:
        n, m = len(x[fields[0]]), len(y[fields[0]])
        if n > m or (n < m and not prefix):
            return False
        # float: JSON's null becomes NaN; the integer fields (steps, counts) stay exact below 2^53
        return all(
            np.array_equal(np.array(x[k], dtype=float), np.array(y[k][:n], dtype=float), equal_nan=True)
            for k in fields
        )

    (rows_a, blocks_a, idx_a), (rows_b, blocks_b, idx_b) = parts(a), parts(b)
    if not same(rows_a, rows_b, HISTORY_FIELDS):
        return False
    if blocks_a is None or blocks_b is None:
        return True
    return same(blocks_a, blocks_b, BLOCK_FIELDS) and np.array_equal(idx_a, idx_b)
