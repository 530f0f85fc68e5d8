"""Crash-safe, resumable HDF5 archives of ensemble runs.

Modelled on REBOUND's simulation archive: one HDF5 file per run that the run loop streams into
after every chunk, that survives a kill at any moment, can be read while it is written, and
from which a run continues *bit for bit* as if it had never stopped. The layout is documented
name by name in ``docs/archive.md`` (format ``warpratchet-archive``, version
:data:`FORMAT_VERSION`).

The package's public names are those below (``__all__``); the implementation is private, one
idea per module:

* :mod:`._format`: what an archive is (format and versions, names, units; the errors) and its
  layout, built up front;
* :mod:`._rows`: what grows as a run goes on (rows behind live counters, the two checkpoint
  slots, the ``/snapshots`` subsample) and reading it back safely;
* :mod:`._features`: the optional groups ``/history`` and ``/transport``;
* :mod:`._reader`: :func:`open_archive`, :class:`Archive`, what ``inspect`` reports, the pandas
  and xarray views;
* :mod:`._recovery`: what a resume keeps (used by :meth:`ArchiveSink.resume`) and
  :func:`verify_archive` (``warpratchet verify``);
* :mod:`._chunking`: :func:`schedule` (chunk length, checkpoint interval) and :func:`run_to`;
* :mod:`._writer`: :class:`ArchiveSink`, the observer that writes it, building a file under a
  temporary name and publishing it atomically, and the sink of ``Ensemble.run(archive=)``.

Each imports only modules above it in this list.

Atomic creation, locks, fsyncs and the HDF5 reader options are shared with the other writers
in :mod:`warpratchet._files`.
"""

from .._files import SWMR_READ_ATTEMPTS
from ._chunking import CHECKPOINT_CHUNKS, CHECKPOINT_SECONDS, MIN_ARCHIVE_CHUNK_STEPS, run_to, schedule
from ._format import (
    FORMAT,
    FORMAT_VERSION,
    KNOWN_FEATURES,
    READABLE_VERSIONS,
    SERIES_FIELDS,
    SNAPSHOT_FIELDS,
    ArchiveError,
    ArchiveWarning,
    NonFiniteStateError,
)
from ._reader import Archive, Snapshots, VirtualSourceError, open_archive
from ._recovery import verify_archive
from ._writer import ArchiveSink

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "READABLE_VERSIONS",
    "KNOWN_FEATURES",
    "NonFiniteStateError",
    "SERIES_FIELDS",
    "SNAPSHOT_FIELDS",
    "CHECKPOINT_CHUNKS",
    "CHECKPOINT_SECONDS",
    "MIN_ARCHIVE_CHUNK_STEPS",
    "SWMR_READ_ATTEMPTS",
    "ArchiveError",
    "ArchiveWarning",
    "VirtualSourceError",
    "Archive",
    "Snapshots",
    "ArchiveSink",
    "open_archive",
    "verify_archive",
    "schedule",
    "run_to",
]
