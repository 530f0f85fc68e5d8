"""Crash-safe, resumable HDF5 archives of ensemble runs.

Modelled on REBOUND's simulation archive: one HDF5 file per run that the run loop streams into
after every chunk, that survives a kill at any moment, can be read while it is written, and
from which a run continues *bit for bit* as if it had never stopped. The layout is documented
name by name in ``docs/archive.md`` (format ``warpratchet-archive``, version
:data:`FORMAT_VERSION`).

One idea per module:

* :mod:`._format`: what an archive contains (format and versions, names, units; the errors);
* :mod:`.layout`: building it (settings attributes, every dataset up front);
* :mod:`.rows`: appending rows behind a live counter;
* :mod:`.building`: a file made under a temporary name and published atomically;
* :mod:`.slots`: the two checkpoint slots (crash-safe writes, sequence-locked reads);
* :mod:`.snapshots`: the ``/snapshots`` subsample, :class:`Snapshots`;
* :mod:`.history_group`: the optional ``/history`` group (feature ``history``);
* :mod:`.writer`: :class:`ArchiveSink`, the observer that writes it;
* :mod:`.reader`: :func:`open_archive`, :class:`Archive`;
* :mod:`.progress`: percentage done and ETA of ``inspect``;
* :mod:`.export`: ``Archive.to_pandas()`` and ``Archive.to_xarray()``;
* :mod:`.verify`: :func:`verify_archive`, every checksum and value of a file (``warpratchet verify``);
* :mod:`.resume`: what a resume keeps (used by :meth:`ArchiveSink.resume`);
* :mod:`.chunking`: :func:`schedule` (chunk length, checkpoint interval) and :func:`run_to`.

Atomic creation, locks, fsyncs and the HDF5 reader options are shared with the other writers
in :mod:`warpratchet._files`.
"""

from .._files import SWMR_READ_ATTEMPTS
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
from ._reader import Archive, Snapshots, open_archive
from ._recovery import verify_archive
from ._chunking import CHECKPOINT_CHUNKS, CHECKPOINT_SECONDS, MIN_ARCHIVE_CHUNK_STEPS, run_to, schedule
from .writer import ArchiveSink

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
    "Archive",
    "Snapshots",
    "ArchiveSink",
    "open_archive",
    "verify_archive",
    "schedule",
    "run_to",
]
