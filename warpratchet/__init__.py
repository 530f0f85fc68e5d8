"""warpratchet: the weak-chaos ratchet accelerator of Dana & Roitberg, simulated with Warp.

The map (Eq. cpem) ``p' = p + K f(x), x' = x + p' mod 1`` with the piecewise-linear force of
Eq. (fx). Start with :class:`MapParams`, :mod:`warpratchet.theory`, :class:`Ensemble` and
:meth:`Ensemble.summary`; :class:`RunSpec` holds every setting of a run (docs/architecture.md,
docs/api.md).

The names that need Warp or HDF5 (:class:`Ensemble`, :class:`Observer`, :func:`open_archive`)
are imported on first use, so that ``warpratchet --help`` and ``--version`` answer at once and
Ctrl-C during start-up has nothing to interrupt but this light import.
"""

from importlib import import_module
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from . import theory
from .errors import renamed_globals
from .observables import (
    Summary,
    UnreliableWarning,
    chaotic_mask,
    finite_time_acceleration,
    lyapunov,
    summarize,
)
from .params import MapParams
from .runloop import register_sink
from .spec import RunSpec

try:
    __version__ = version("warpratchet")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

#: Public names imported on first use: name -> module.
_LAZY = {
    "Ensemble": ".ensemble",
    "Observer": ".runloop",
    "History": ".history",
    "open_archive": ".archive",
    "StorageError": "._storage",
}

#: Former public names, still answered with a DeprecationWarning: name -> its name now.
_renamed = renamed_globals(__name__, {"acceleration": "finite_time_acceleration"}, globals())

__all__ = [
    "MapParams",
    "RunSpec",
    "Ensemble",
    "Observer",
    "History",
    "Summary",
    "UnreliableWarning",
    "theory",
    "finite_time_acceleration",
    "lyapunov",
    "chaotic_mask",
    "summarize",
    "open_archive",
    "StorageError",
    "__version__",
]


def _archive_sink(ensemble: Any, path: Any, chunk_steps: int | None) -> Any:
    """``Ensemble.run(archive=path)``'s sink: the archive sits above the run loop, which reaches it
    only through this registration (:func:`warpratchet.runloop.register_sink`)."""
    from .archive._writer import archive_sink

    return archive_sink(ensemble, path, chunk_steps)


register_sink("archive", _archive_sink)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    return _renamed(name)  # a former name (with a DeprecationWarning), or AttributeError


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
