"""Transport beyond the mean: return times to B, flights, anomalous diffusion.

* :class:`TransportEnsemble` (:mod:`._ensemble`): an ensemble whose runs also count, in the kernel
  (:mod:`warpratchet.kernels._transport`), the return times to the strip B (Eq. B) and the flights
  (runs of equal nonzero whole-unit gain) into log2-binned histograms, exactly;
* :mod:`._histograms`: the bins, :class:`Histograms`, the runs still open;
* :mod:`._twin`: the kernel's NumPy twin (tests).
"""

from ._fits import bin_masses
from ._histograms import BINS, CARRY_FIELDS, HISTOGRAMS, Histograms, bin_of, edges, open_runs
from ._report import counts_transport, format_transport

__all__ = [
    "BINS",
    "CARRY_FIELDS",
    "HISTOGRAMS",
    "Histograms",
    "TransportEnsemble",
    "bin_masses",
    "bin_of",
    "counts_transport",
    "edges",
    "format_transport",
    "open_runs",
]


def __getattr__(name: str):
    # The ensemble needs Warp; the pure parts above do not, so it is imported on first use.
    if name == "TransportEnsemble":
        from ._ensemble import TransportEnsemble

        return TransportEnsemble
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
