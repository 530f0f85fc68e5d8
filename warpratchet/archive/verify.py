"""Checking every byte of an archive that can be checked: ``warpratchet verify`` for run archives.

:func:`verify_archive` reads every dataset whole (so HDF5 verifies the Fletcher-32 checksum of
every stored chunk, and of the metadata on the way), every attribute, checks that no chunk lies
past the end of the file, that the counters fit their datasets, that steps grow, and that the
initial state and every complete checkpoint are finite (release 0.1.0 could checkpoint a
non-finite state). It reports; it never repairs (``warpratchet resume`` keeps what verifies).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import Any

import numpy as np

from .._files import claim
from .._h5verify import first_line, read_everything
from ._features import history_counts
from ._format import COUNTERS, SLOTS, ArchiveError
from ._reader import Archive
from ._rows import listed, nonfinite, read_counter, slot_step

__all__ = ["verify_archive"]


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
    with _alone(path), Archive(path, locking=False) as arc:
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
