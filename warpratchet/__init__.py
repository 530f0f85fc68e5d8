"""warpratchet: the weak-chaos ratchet accelerator of Dana & Roitberg, simulated with Warp.

The map (Eq. cpem) ``p' = p + K f(x), x' = x + p' mod 1`` with the piecewise-linear force of
Eq. (fx). Start with :class:`MapParams`, :mod:`warpratchet.theory`, :class:`Ensemble` and
:func:`summarize`; :class:`RunSpec` holds every setting of a run (docs/architecture.md).
"""

from importlib.metadata import PackageNotFoundError, version

from . import theory
from .archive import open_archive
from .ensemble import Ensemble, Observer
from .observables import acceleration, chaotic_mask, lyapunov, summarize
from .params import MapParams
from .spec import RunSpec

try:
    __version__ = version("warpratchet")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

__all__ = [
    "MapParams",
    "RunSpec",
    "Ensemble",
    "Observer",
    "theory",
    "acceleration",
    "lyapunov",
    "chaotic_mask",
    "summarize",
    "open_archive",
    "__version__",
]
