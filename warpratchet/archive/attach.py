"""The archive of ``Ensemble.run(archive=path)``: a new one, or this run's to append to.

The run loop knows no sinks; :func:`archive_sink` is registered for the ``archive=`` keyword
(:func:`warpratchet.runloop.register_sink`) by the package's public face, ``warpratchet``.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..history import History
from ._reader import open_archive
from .writer import ArchiveSink

__all__ = ["archive_sink"]


def archive_sink(ensemble: Any, path: str | os.PathLike, chunk_steps: int | None) -> Any:
    """The ArchiveSink of ``Ensemble.run(archive=path)``: a new archive, or this run's to append to.

    A new archive keeps the run's :class:`~warpratchet.history.History` (``sink.history``, an
    observer of the run too).

    An existing file is appended to only if it is an archive whose checkpoint holds exactly this
    ensemble (same step, every state array equal bit for bit): what a previous ``run(...,
    archive=path)`` of this ensemble leaves when it completes. Anything else is refused, so an
    archive never mixes two runs.
    """
    if not os.path.lexists(path):
        return ArchiveSink(path, ensemble, chunk_steps=chunk_steps, threshold=None, history=History())
    with open_archive(path) as arc:
        state, step = arc.checkpoint()
        params = arc.params
    same = (
        params == ensemble.params
        and step == ensemble.step
        and all(np.array_equal(state[name], ensemble.array(name)) for name in state)
    )
    if not same:
        raise ValueError(
            f"{os.fspath(path)} exists and does not hold this ensemble at step {ensemble.step} "
            f"(its checkpoint is at step {step}); choose a new path, or continue that run from "
            "open_archive(path).ensemble()"
        )
    sink, _ = ArchiveSink.resume(path, threads=ensemble.threads, device=ensemble.device)
    if chunk_steps is not None and chunk_steps != sink.chunk_steps:
        sink.close()
        raise ValueError(
            f"chunk_steps = {chunk_steps} differs from the archive's chunk_steps = {sink.chunk_steps}"
        )
    sink.ensemble = ensemble  # the restored twin equals this ensemble bit for bit (checked above)
    return sink
