"""What a resume keeps of an archive, and putting it back into the rebuilt file.

:meth:`ArchiveSink.resume <warpratchet.archive.writer.ArchiveSink.resume>` rebuilds an archive
from what is valid in it: the metadata, the initial state, the series rows and snapshots up to
the newest good checkpoint, and that checkpoint. :func:`salvage` reads all of it (refusing a
kernel that would not continue the run bit for bit); :meth:`Salvage.write` puts it into the new
file, whose layout :func:`~warpratchet.archive.layout.create` has made. Rows past the checkpoint
are dropped: the resumed run writes them again, identically (only their clocks differ).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np

from ..ensemble import STATE_FIELDS, Ensemble
from .layout import SERIES_FIELDS, SNAPSHOT_FIELDS, ArchiveError, kernel_constants
from .reader import Archive, Snapshots

__all__ = ["Salvage", "salvage"]


@dataclass(frozen=True)
class Salvage:
    """The valid part of an archive, up to its newest good checkpoint.

    Attributes
    ----------
    ensemble : Ensemble
        Restored bit for bit at ``step``.
    state : dict of ndarray
        The checkpoint's state (keys ``STATE_FIELDS``), at ``step``.
    step : int
        The checkpoint's step (the initial step if there is no checkpoint).
    layout : dict
        Keyword arguments of :func:`~warpratchet.archive.layout.create` (metadata, stored
        settings, initial state, snapshot indices).
    series : dict of ndarray
        The rows up to ``step``, keys :data:`SERIES_FIELDS`.
    snapshots : Snapshots
        The snapshots up to ``step``.
    """

    ensemble: Ensemble
    state: dict[str, np.ndarray]
    step: int
    layout: dict[str, Any]
    series: dict[str, np.ndarray]
    snapshots: Snapshots

    @property
    def rows(self) -> int:
        return int(self.series["step"].size)

    def write(self, f: h5py.File) -> None:
        """Put the rows, snapshots and checkpoint into a freshly created layout ``f``."""
        g = f["series"]
        for name in SERIES_FIELDS:
            if self.rows:
                g[name].resize(self.rows, axis=0)
                g[name][:] = self.series[name]
        g["n_valid"][0] = self.rows
        g = f["snapshots"]
        snaps = self.snapshots
        for name in ("step", *SNAPSHOT_FIELDS):
            if len(snaps):
                g[name].resize(len(snaps), axis=0)
                g[name][...] = snaps.steps if name == "step" else getattr(snaps, name)
        g["n_valid"][0] = len(snaps)
        if self.step != self.layout["initial_step"]:
            slot = f["checkpoint"]["a"]
            for name in STATE_FIELDS:
                slot[name].write_direct(np.ascontiguousarray(self.state[name]))
            slot["step"][0] = self.step
            f["checkpoint"]["current"][0] = 0


def salvage(path: str | os.PathLike, *, threads: int | None = None, device: str | None = None) -> Salvage:
    """Read what a resume of ``path`` keeps (the caller holds the file's exclusive lock).

    Raises
    ------
    ArchiveError
        Unreadable or incompatible archive, including one written with other renormalisation
        constants than this kernel's (a resumed run would not continue it bit for bit).
    """
    path = os.fspath(path)
    with Archive(path, locking=False) as arc:
        s = arc.settings
        for key, ours in kernel_constants().items():
            if s.get(key) != ours:
                raise ArchiveError(
                    f"{path}: written with {key} = {s.get(key)!r} but this kernel uses {ours!r}; "
                    "a resumed run would not continue it bit for bit"
                )
        state, step = arc.checkpoint()
        ensemble = arc._restore(state, step, threads, device)
        series = arc.series
        keep = int(np.searchsorted(series["step"], step, side="right"))
        snaps = arc.snapshots
        kept = int(np.searchsorted(snaps.steps, step, side="right"))
        layout = {
            "params": arc.params,
            "settings": arc._stored_settings(),
            "versions": dict(arc.versions),
            "created": arc.created,
            "initial": arc.initial,
            "initial_step": arc.initial_step,
            "indices": snaps.indices,
        }
    return Salvage(
        ensemble=ensemble,
        state=state,
        step=step,
        layout=layout,
        series={name: values[:keep] for name, values in series.items()},
        snapshots=Snapshots(
            steps=snaps.steps[:kept],
            indices=snaps.indices,
            x=snaps.x[:kept],
            p=snaps.p[:kept],
            ftle=snaps.ftle[:kept],
            A=snaps.A[:kept],
        ),
    )
