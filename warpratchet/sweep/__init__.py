"""Parameter sweeps: one ensemble per point (K, b1, b2), run locally or on a Dask cluster.

A sweep is a list of map parameters and one :class:`~warpratchet.spec.SweepSpec` (the subset of
:class:`~warpratchet.spec.RunSpec` every point shares: ensemble size, steps, sampler, root seed,
chaos threshold). Every point yields one summary row (:data:`ROW_FIELDS`): the parameters, the
existence domain of Fig. 3, the theory's A where the paper has a closed form (K = 3: Eqs. Aa,
Ab), and the numerical A, FTLE statistics and chaotic fraction of
:func:`warpratchet.observables.summarize`.

The package has three rooms:

* :mod:`~warpratchet.sweep._paths`: the paper's paths and grids (Figs. 5-9), pure;
* :mod:`~warpratchet.sweep._records`: format, versions and the columns of a row;
* :mod:`~warpratchet.sweep._file`: writing the HDF5 sweep file (layout, resume, ``--force``);
* :mod:`~warpratchet.sweep._reading`: :func:`read_sweep`, :func:`read_definition`;
* :mod:`~warpratchet.sweep._verify`: :func:`verify_sweep` (``warpratchet verify``);
* :mod:`~warpratchet.sweep._run`: one point (:func:`run_point`), seeds (:func:`point_seed`),
  and the local and Dask executors (:func:`run_sweep`).

The names that need Warp or HDF5 (the runner, the reader, the verifier) are imported on first
use, so that the paths and the row format load neither.
"""

from typing import Any

from ..spec import SweepSpec
from ._paths import (
    DOMAINS,
    SWEEP_BYTES_PER_POINT,
    check_sweep_size,
    fixed_b1_path,
    grid_points,
    k_path,
    line_path,
    maximal_path,
)
from ._records import (
    FORMAT,
    FORMAT_VERSION,
    READABLE_VERSIONS,
    ROW_DESCRIPTIONS,
    ROW_DTYPE,
    ROW_FIELDS,
    TIMING_FIELDS,
)

__all__ = [
    "SweepSpec",
    "maximal_path",
    "line_path",
    "fixed_b1_path",
    "grid_points",
    "k_path",
    "DOMAINS",
    "SWEEP_BYTES_PER_POINT",
    "check_sweep_size",
    "point_seed",
    "run_point",
    "run_sweep",
    "read_sweep",
    "read_definition",
    "verify_sweep",
    "ROW_DTYPE",
    "ROW_FIELDS",
    "TIMING_FIELDS",
    "FORMAT",
    "FORMAT_VERSION",
    "READABLE_VERSIONS",
    "ROW_DESCRIPTIONS",
]


def __getattr__(name: str) -> Any:
    # Written as import statements, not module names in strings, so that the import test of
    # docs/architecture.md sees these arrows too.
    if name in ("point_seed", "run_point", "run_sweep"):
        from . import _run as home
    elif name in ("read_sweep", "read_definition"):
        from . import _reading as home
    elif name == "verify_sweep":
        from . import _verify as home
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(home, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
