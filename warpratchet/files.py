"""File safety for front ends: the lock claim, the live-file open and the atomic write.

The public face of the few file primitives that a subcommand, a figure script or a report
needs; every writer of warpratchet shares their one implementation (:mod:`warpratchet._files`,
which explains each mechanism):

* :func:`claim`: an advisory ``flock`` on a file; ``exclusive=True`` fails with
  ``BlockingIOError`` while a live run (or an open reader) uses the file;
* :func:`open_h5`: open an HDF5 file that another process may be writing (SWMR-read when the
  file says a writer has it open);
* :func:`temporary_beside` and :func:`publish`: build a file under a temporary name in the same
  folder, make it durable, then give it its name atomically, so a path never holds half a file.
"""

from ._files import claim, publish, temporary_beside
from ._h5 import open_h5

__all__ = ["claim", "open_h5", "temporary_beside", "publish"]
