"""The two checkpoint slots: written crash-safe into the free one, read newest first.

Writing (:func:`write_slot`): the slot *not* holding the newest checkpoint gets ``step`` -1 (in
progress: nobody may trust it), its data fsynced, then its ``step`` and ``/checkpoint/current``.
Reading (:func:`newest_good`): the complete slots newest first, each slot's ``step`` read before
and after its data (a sequence lock), so a slot a live writer recycles meanwhile is read again,
never reported as damaged; a slot whose checksum fails or that holds non-finite values (written
by format v1 releases) is skipped and described. docs/archive.md has the whole story.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import h5py
import numpy as np

from .._files import dataset_bytes, ensure_space, h5_bytes, sync_h5
from ..ensemble import STATE_FIELDS
from .checks import check_extent, listed, nonfinite, reading
from .checks import refresh as _refresh
from .names import SLOTS, ArchiveError
from .rows import set_counter

__all__ = ["read_state", "slot_step", "slot_steps", "newest_good", "write_slot"]

#: Attempts at reading a slot that a live writer keeps recycling.
_ATTEMPTS = 10


def read_state(path: str, f: h5py.File, group: str, points: int) -> dict[str, np.ndarray]:
    """The per-point state stored in ``group`` (``"initial"``, ``"checkpoint/a"``, ...), unchecked."""
    state = {}
    for name in STATE_FIELDS:
        with reading(path, f"/{group}/{name}"):
            ds = _refresh(f[group][name])
            if ds.shape != (points,):
                raise ArchiveError(f"{path}: /{group}/{name} has shape {ds.shape}, expected ({points},)")
            check_extent(path, ds)
            state[name] = ds[:]
    return state


def slot_step(path: str, f: h5py.File, name: str) -> int:
    """The ``step`` of slot ``name`` (-1: in progress)."""
    with reading(path, f"/checkpoint/{name}/step"):
        ds = _refresh(f["checkpoint"][name]["step"])
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
