"""Parameter sweeps: one ensemble per point (K, b1, b2), run locally or on a Dask cluster.

A sweep is a list of map parameters and one :class:`SweepSpec` (ensemble size, steps, sampler,
seed, chaos threshold). Every point yields one summary row (:data:`ROW_FIELDS`): the
parameters, the existence domain of Fig. 3, the theory's A where the paper has a closed form
(K = 3: Eqs. Aa, Ab), and the numerical A, FTLE statistics and chaotic fraction of
:func:`warpratchet.observables.summarize`.

Built-in paths are the paper's: the maximal path of Eq. (b2max) (Fig. 7), the straight lines
``b1 = b2 / a`` of Eq. (Ama) (Fig. 8 has ``a = 1/3``), fixed ``b1`` with varying ``b2``
(Fig. 9: ``K = 2.99``, ``b1 = 0.25``), a ``(b1, b2)`` grid optionally masked to a domain
(Figs. 5 and 6) and paths in ``K``. Any list of :class:`MapParams` is a sweep too.

Reproducibility. Point ``i`` samples its ensemble with the seed :func:`point_seed`
``(spec.seed, i)``, the ``i``-th child of ``numpy.random.SeedSequence(spec.seed)``: points get
independent streams (their errors are uncorrelated along a path) and a row depends only on
``(params, spec, i)``, never on which executor ran it, in which order, or with how many threads
(the ensemble is bitwise independent of threads). The row stores the derived seed, so
``Ensemble.sample(params, points, init, seed=row["seed"])`` (or ``warpratchet run --seed``)
rebuilds that point's ensemble exactly.

Executors. ``client=None`` runs the points one after another in this process, each on every
core. A ``dask.distributed.Client`` (or a scheduler address) runs :func:`run_point` on the
workers, one point per Dask worker thread; workers need only ``pip install
warpratchet[distributed]``.

Sweep file (HDF5, one file per sweep)::

    attrs   format = "warpratchet-sweep", format_version = 1, warpratchet_version,
            spec = JSON of SweepSpec.as_dict()
    parameters   float64 (n, 3): K, b1, b2 of every point, in sweep order
    rows         compound (m,), resizable: one record per finished point, in completion order
    rows_valid   int64 scalar: how many records of ``rows`` are complete

Each record is written and flushed before ``rows_valid`` is raised and flushed again, so a
process killed at any moment leaves a file whose first ``rows_valid`` records are complete;
running the same sweep with the same file resumes it and computes only the missing points.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import h5py
import numpy as np

from . import theory
from .ensemble import SAMPLERS, Ensemble
from .observables import summarize
from .params import MapParams, check_real

__all__ = [
    "ROW_DTYPE",
    "ROW_FIELDS",
    "TIMING_FIELDS",
    "DOMAINS",
    "SweepSpec",
    "maximal_path",
    "line_path",
    "fixed_b1_path",
    "grid_points",
    "k_path",
    "point_seed",
    "run_point",
    "run_sweep",
    "read_sweep",
    "read_definition",
]

#: Columns of a sweep row, in order, with their HDF5 types.
ROW_DTYPE = np.dtype(
    [
        ("index", "<i8"),  # position of the point in the sweep
        ("K", "<f8"),
        ("b1", "<f8"),
        ("b2", "<f8"),
        ("domain", "S4"),  # "LR", "L", "R" or "none" (Fig. 3)
        ("A_theory", "<f8"),  # Eq. (Aa)/(Ab) at K = 3; NaN elsewhere
        ("A", "<f8"),  # mean A_n over chaotic points, per iteration (Eq. An)
        ("A_stderr", "<f8"),
        ("lyapunov", "<f8"),  # mean FTLE over chaotic points, per iteration
        ("lyapunov_std", "<f8"),
        ("lyapunov_min", "<f8"),
        ("chaotic_fraction", "<f8"),
        ("chaotic_points", "<i8"),
        ("points", "<i8"),  # ensemble size actually run (a grid rounds down to a square)
        ("steps", "<i8"),
        ("seed", "<i8"),  # the point's own seed, point_seed(spec.seed, index)
        ("init", "S8"),
        ("threshold", "<f8"),  # FTLE threshold used for the chaotic mask
        ("seconds", "<f8"),  # wall time of the ensemble run on whichever machine ran it
    ]
)
ROW_FIELDS: tuple[str, ...] = tuple(ROW_DTYPE.names)
#: Row fields that depend on the machine, not on (params, spec, index): leave them out when
#: comparing rows from different runs or executors.
TIMING_FIELDS: tuple[str, ...] = ("seconds",)
#: Existence domains of Fig. 3, as returned by :func:`warpratchet.theory.domain`.
DOMAINS: tuple[str, ...] = ("LR", "L", "R", "none")

FORMAT = "warpratchet-sweep"
FORMAT_VERSION = 1
_STRING_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "S")
_INT_FIELDS = tuple(name for name in ROW_FIELDS if ROW_DTYPE[name].kind == "i")


def _check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {name} >= {minimum} (an integer)")
    return int(value)


@dataclass(frozen=True)
class SweepSpec:
    """The ensemble run at every point of a sweep.

    Parameters
    ----------
    points : int
        Ensemble size per point (``>= 1``); the paper uses 10^4 (Fig. 7 caption).
    steps : int
        Iterations ``n`` per point (``>= 1``); the paper uses 120000.
    init : str
        Initial conditions, one of ``"strip"`` (the strip B of Eq. B), ``"torus"``, ``"grid"``.
    seed : int
        Root seed (``>= 0``); point ``i`` uses :func:`point_seed` ``(seed, i)``.
    threshold : float or None
        FTLE (per iteration) above which a point counts as chaotic; ``None`` for
        :func:`warpratchet.observables.default_lyapunov_threshold` of ``steps``.
    """

    points: int = 10_000
    steps: int = 120_000
    init: str = "strip"
    seed: int = 0
    threshold: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", _check_int("points", self.points, 1))
        object.__setattr__(self, "steps", _check_int("steps", self.steps, 1))
        object.__setattr__(self, "seed", _check_int("seed", self.seed, 0))
        if self.init not in SAMPLERS:
            raise ValueError(f"init = {self.init!r} is not one of {', '.join(SAMPLERS)}")
        if self.threshold is not None:
            object.__setattr__(self, "threshold", check_real("threshold", self.threshold))

    def as_dict(self) -> dict[str, Any]:
        """The spec as plain Python values (stored in sweep files as JSON)."""
        return asdict(self)


# -- paths through parameter space ------------------------------------------------------------
def _values(name: str, values: Iterable[float] | float) -> np.ndarray:
    array = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if array.ndim != 1:
        raise ValueError(f"{name} must be a number or a 1-D sequence of numbers; got shape {array.shape}")
    return array


def maximal_path(b2_values: Iterable[float], K: float = 3.0) -> list[MapParams]:
    """Points on the maximal path of Eq. (b2max): ``b1 = b1(b2)`` maximises Eq. (Aa) at fixed b2.

    Parameters
    ----------
    b2_values : sequence of float, shape (n,)
        Right strip widths, each in ``0 < b2 <= 1/6`` (the path ends at ``b1 = b2 = 1/6``).
    K : float
        Kick strength; the path is derived at K = 3 (Fig. 7), other K just reuse its b1(b2).
    """
    return [
        MapParams(K, theory.b1_on_maximal_path(float(b2)), float(b2))
        for b2 in _values("b2_values", b2_values)
    ]


def line_path(a: float, b2_values: Iterable[float], K: float = 3.0) -> list[MapParams]:
    """Points on the straight line ``b1 = b2 / a`` of Eq. (Ama) (Fig. 8: ``a = 1/3``, i.e. b1 = 3 b2)."""
    a = check_real("a", a)
    if not a > 0.0:
        raise ValueError(f"a = {a!r} is outside the allowed range a > 0")
    return [MapParams(K, float(b2) / a, float(b2)) for b2 in _values("b2_values", b2_values)]


def fixed_b1_path(b1: float, b2_values: Iterable[float], K: float) -> list[MapParams]:
    """Points with fixed ``b1`` and varying ``b2`` (Fig. 9: ``K = 2.99``, ``b1 = 0.25``, domain R)."""
    return [MapParams(K, b1, float(b2)) for b2 in _values("b2_values", b2_values)]


def _domain_set(domain: str | Iterable[str] | None) -> frozenset[str] | None:
    if domain is None:
        return None
    wanted = frozenset([domain] if isinstance(domain, str) else domain)
    bad = sorted(wanted - set(DOMAINS))
    if bad or not wanted:
        raise ValueError(f"domain = {domain!r} must name some of {', '.join(DOMAINS)}")
    return wanted


def grid_points(
    b1_values: Iterable[float],
    b2_values: Iterable[float],
    K: float = 3.0,
    domain: str | Iterable[str] | None = None,
) -> list[MapParams]:
    """Every ``(b1, b2)`` pair of two axes (Figs. 5 and 6), ``b1`` outer and ``b2`` inner.

    Pairs with ``b1 + b2 >= 1`` have no map (Eq. fx) and are skipped. With ``domain`` (a name or
    a set of names among ``"LR", "L", "R", "none"``) only points whose existence domain of
    Fig. 3 (:func:`warpratchet.theory.domain`) is in it are kept, e.g. ``{"LR"}`` for Eq. (Aa).
    """
    wanted = _domain_set(domain)
    out = []
    for b1 in _values("b1_values", b1_values):
        for b2 in _values("b2_values", b2_values):
            if b1 + b2 >= 1.0:
                continue
            p = MapParams(K, float(b1), float(b2))
            if wanted is None or theory.domain(p) in wanted:
                out.append(p)
    return out


def k_path(K_values: Iterable[float], b1: float, b2: float) -> list[MapParams]:
    """Points with fixed ``(b1, b2)`` and varying kick strength ``K`` (``0 < K < 4``, Eq. cpem)."""
    return [MapParams(float(K), b1, b2) for K in _values("K_values", K_values)]


# -- one point ----------------------------------------------------------------------------------
def point_seed(seed: int, index: int) -> int:
    """Seed of point ``index``: the ``index``-th child of ``SeedSequence(seed)``, as a 53-bit integer.

    Children of one SeedSequence are NumPy's recommended independent streams. 53 bits keep the
    seed exact in JSON readers that hold numbers as doubles.
    """
    child = np.random.SeedSequence(_check_int("seed", seed, 0), spawn_key=(_check_int("index", index, 0),))
    return int(child.generate_state(1, np.uint64)[0] >> np.uint64(11))


def _as_params(point: MapParams | Sequence[float]) -> MapParams:
    if isinstance(point, MapParams):
        return point
    try:
        K, b1, b2 = point
    except (TypeError, ValueError):
        raise ValueError(f"sweep point {point!r} is neither MapParams nor a (K, b1, b2) triple") from None
    return MapParams(K, b1, b2)


def run_point(
    params: MapParams, spec: SweepSpec, index: int = 0, threads: int | None = None
) -> dict[str, Any]:
    """Run the ensemble of one sweep point and summarise it: a pure function of its arguments.

    This is what Dask workers execute. Apart from ``seconds`` the row depends only on
    ``(params, spec, index)``, bit for bit.

    Parameters
    ----------
    params : MapParams
        The map at this point.
    spec : SweepSpec
        Ensemble size, steps, sampler, root seed and threshold.
    index : int
        Position of the point in its sweep (selects the seed, :func:`point_seed`).
    threads : int, optional
        CPU threads for the ensemble (default: one per core of this process).

    Returns
    -------
    dict
        One row, keys :data:`ROW_FIELDS` (per-iteration A and FTLE, seconds of wall time).

    Raises
    ------
    ValueError
        If the tangent overflows float64 (``b1`` or ``b2`` far too small); names the point.
    """
    seed = point_seed(spec.seed, index)
    ensemble = Ensemble.sample(params, spec.points, spec.init, seed, threads=threads)
    start = time.perf_counter()
    ensemble.run(spec.steps)
    seconds = time.perf_counter() - start
    try:
        s = summarize(ensemble.state(), ensemble.step, spec.threshold)
    except FloatingPointError as exc:
        raise ValueError(
            f"sweep point {index} (K={params.K!r}, b1={params.b1!r}, b2={params.b2!r}): {exc}"
        ) from exc
    # theory.acceleration is exact only at K = 3 (Sec. IV); elsewhere the paper has no closed form.
    a_theory = theory.acceleration(params) if params.K == 3.0 else None
    return {
        "index": int(index),
        "K": params.K,
        "b1": params.b1,
        "b2": params.b2,
        "domain": theory.domain(params),
        "A_theory": math.nan if a_theory is None else float(a_theory),
        "A": s.A,
        "A_stderr": s.A_stderr,
        "lyapunov": s.lyapunov,
        "lyapunov_std": s.lyapunov_std,
        "lyapunov_min": s.lyapunov_min,
        "chaotic_fraction": s.chaotic_fraction,
        "chaotic_points": s.chaotic_points,
        "points": ensemble.points,
        "steps": ensemble.step,
        "seed": seed,
        "init": spec.init,
        "threshold": s.threshold,
        "seconds": seconds,
    }


# -- the sweep file -----------------------------------------------------------------------------
def _record(row: dict[str, Any]) -> np.ndarray:
    record = np.zeros((), dtype=ROW_DTYPE)
    for name in ROW_FIELDS:
        record[name] = row[name].encode("ascii") if name in _STRING_FIELDS else row[name]
    return record


def _row(record: np.void) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for name in ROW_FIELDS:
        value = record[name]
        if name in _STRING_FIELDS:
            row[name] = bytes(value).decode("ascii")
        elif name in _INT_FIELDS:
            row[name] = int(value)
        else:
            row[name] = float(value)
    return row


def _definition_mismatch(f: h5py.File, params: np.ndarray, spec: SweepSpec) -> str | None:
    """Why the sweep stored in ``f`` is not (params, spec), or None if it is the same sweep."""
    stored_spec = json.loads(f.attrs["spec"])
    for key, value in spec.as_dict().items():
        if stored_spec.get(key) != value:
            return f"{key} is {stored_spec.get(key)!r} in the file, {value!r} requested"
    stored = f["parameters"][()]
    if stored.shape != params.shape:
        return f"the file has {stored.shape[0]} points, {params.shape[0]} requested"
    differ = np.flatnonzero(np.any(stored != params, axis=1))
    if differ.size:
        i = int(differ[0])
        return (
            f"point {i} is (K, b1, b2) = {tuple(stored[i].tolist())} in the file, "
            f"{tuple(params[i].tolist())} requested"
        )
    return None


class _SweepFile:
    """An open sweep file: created, or reopened after checking it holds the same sweep."""

    def __init__(self, path: str | os.PathLike, params: np.ndarray, spec: SweepSpec, force: bool) -> None:
        self.path = os.fspath(path)
        if os.path.exists(self.path):
            if force:
                os.remove(self.path)
            else:
                self.file = self._reopen(params, spec)
                return
        # "w-" fails if the file appeared meanwhile: a user's file is never truncated.
        self.file = h5py.File(self.path, "w-")
        f = self.file
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["warpratchet_version"] = _version()
        f.attrs["spec"] = json.dumps(spec.as_dict())
        parameters = f.create_dataset("parameters", data=params)
        parameters.attrs["columns"] = "K, b1, b2"
        f.create_dataset("rows", shape=(0,), maxshape=(None,), dtype=ROW_DTYPE, chunks=(64,))
        f.create_dataset("rows_valid", data=np.int64(0))
        f.flush()

    def _reopen(self, params: np.ndarray, spec: SweepSpec) -> h5py.File:
        replace = "choose another file or pass force=True (CLI: --force) to replace it"
        if not h5py.is_hdf5(self.path):
            raise ValueError(f"{self.path} exists and is not an HDF5 sweep file; {replace}")
        try:
            f = h5py.File(self.path, "r+")
        except OSError as exc:
            # Typically a lock held by a sweep still writing it: never suggest replacing that one.
            raise ValueError(
                f"cannot open {self.path} for writing (is another sweep writing it?): {exc}"
            ) from None
        try:
            if f.attrs.get("format") != FORMAT or not {"parameters", "rows", "rows_valid"} <= set(f):
                raise ValueError(f"{self.path} exists and is not a warpratchet sweep file; {replace}")
            if f.attrs.get("format_version") != FORMAT_VERSION:
                raise ValueError(
                    f"{self.path} has sweep format version {f.attrs.get('format_version')!r}, "
                    f"this warpratchet writes {FORMAT_VERSION}; {replace}"
                )
            why = _definition_mismatch(f, params, spec)
            if why is not None:
                raise ValueError(f"{self.path} holds a different sweep ({why}); {replace}")
        except BaseException:
            f.close()
            raise
        return f

    def rows(self) -> list[dict[str, Any]]:
        """The complete records, in file order."""
        valid = int(self.file["rows_valid"][()])
        return [_row(record) for record in self.file["rows"][:valid]]

    def append(self, row: dict[str, Any]) -> None:
        rows, valid = self.file["rows"], self.file["rows_valid"]
        n = int(valid[()])
        # A record past rows_valid is the remnant of an interrupted write: overwrite it.
        if rows.shape[0] < n + 1:
            rows.resize((n + 1,))
        rows[n] = _record(row)
        self.file.flush()  # the record is on disk before it is declared valid
        valid[()] = n + 1
        self.file.flush()

    def close(self) -> None:
        self.file.close()


def _version() -> str:
    from . import __version__

    return __version__


def read_sweep(path: str | os.PathLike) -> list[dict[str, Any]]:
    """The finished rows of a sweep file, in sweep order (keys :data:`ROW_FIELDS`).

    An interrupted sweep gives only its finished points. Readable while a sweep is writing it
    (no file lock is taken; rows are flushed one by one).
    """
    with _open_for_reading(path) as f:
        valid = int(f["rows_valid"][()])
        rows = [_row(record) for record in f["rows"][:valid]]
    return sorted(rows, key=lambda row: row["index"])


def read_definition(path: str | os.PathLike) -> tuple[list[MapParams], SweepSpec]:
    """The points and spec a sweep file was created for (to resume it, or to plot what is missing)."""
    with _open_for_reading(path) as f:
        spec = SweepSpec(**json.loads(f.attrs["spec"]))
        params = [MapParams(*row) for row in f["parameters"][()].tolist()]
    return params, spec


def _open_for_reading(path: str | os.PathLike) -> h5py.File:
    path = os.fspath(path)
    try:
        f = h5py.File(path, "r", locking=False)
    except OSError as exc:
        raise ValueError(f"cannot read sweep file {path}: {exc}") from None
    if f.attrs.get("format") != FORMAT:
        f.close()
        raise ValueError(f"{path} is not a warpratchet sweep file")
    return f


# -- executors ----------------------------------------------------------------------------------
def _connect(client: Any) -> tuple[Any, bool]:
    """A Dask client and whether this module owns it (an address string opens one)."""
    try:
        import distributed
    except ImportError:
        raise ImportError("Dask sweeps need dask.distributed: pip install warpratchet[distributed]") from None
    if isinstance(client, str):
        return distributed.Client(client), True
    if isinstance(client, distributed.Client):
        return client, False
    raise ValueError(
        f"client = {client!r} is neither None, a dask.distributed.Client nor a scheduler address"
    )


def _run_local(todo, spec, threads, finish) -> None:
    for index, params in todo:
        finish(run_point(params, spec, index, threads))


def _run_dask(todo, spec, threads, client, finish) -> None:
    import distributed

    client, owned = _connect(client)
    try:
        # pure=False: each submission is a task of its own, even for a repeated (params, spec).
        futures = [
            client.submit(run_point, params, spec, index, threads, pure=False) for index, params in todo
        ]
        try:
            for future in distributed.as_completed(futures):
                finish(future.result())
        finally:
            client.cancel(futures)  # no-op for finished ones; stops the rest after an error
    finally:
        if owned:
            client.close()


def run_sweep(
    points: Sequence[MapParams],
    spec: SweepSpec,
    out: str | os.PathLike | None = None,
    client: Any = None,
    progress: bool = True,
    *,
    threads: int | None = None,
    force: bool = False,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run a sweep, writing each finished row to ``out``; resume ``out`` if it holds this sweep.

    Parameters
    ----------
    points : sequence of MapParams (or ``(K, b1, b2)`` triples)
        The sweep's points, e.g. from :func:`maximal_path` or :func:`grid_points`.
    spec : SweepSpec
        The ensemble run at every point.
    out : path, optional
        Sweep file (HDF5). If it exists and holds the same points and spec, only the missing
        points are computed; if it holds anything else, ``ValueError`` (unless ``force``).
        ``None`` keeps the rows in memory only.
    client : None, dask.distributed.Client or str
        ``None`` runs the points here, one after another, each on every core. A Client, or a
        scheduler address such as ``"tcp://host:8786"`` (connected and closed here), runs them
        on the Dask workers.
    progress : bool
        A tqdm bar over points on stderr.
    threads : int, optional
        CPU threads per point. Default: every core here; 1 on Dask, where each worker thread
        stands for one core (start workers with ``--nthreads`` = cores, or with ``--nthreads 1``
        and pass ``threads`` = cores per worker).
    force : bool
        Replace an existing ``out`` that holds another sweep or is not a sweep file.
    on_row : callable, optional
        Called with every newly computed row, after it is saved.

    Returns
    -------
    list of dict
        Every row, in sweep order (keys :data:`ROW_FIELDS`); rows read back from ``out`` and
        fresh rows are alike.
    """
    if not isinstance(spec, SweepSpec):
        raise ValueError(f"spec = {spec!r} is not a SweepSpec")
    params_list = [_as_params(p) for p in points]
    if not params_list:
        raise ValueError("a sweep needs at least 1 point; got 0")
    if threads is not None:
        threads = _check_int("threads", threads, 1)
    elif client is not None:
        threads = 1  # Dask: a worker thread stands for one core
    if client is not None and not isinstance(client, str):
        _connect(client)  # checks the type (and that Dask is installed) before any file is touched
    table = np.array([[p.K, p.b1, p.b2] for p in params_list], dtype=np.float64)

    sweep_file = _SweepFile(out, table, spec, force) if out is not None else None
    try:
        done = {row["index"]: row for row in sweep_file.rows()} if sweep_file is not None else {}
        todo = [(i, p) for i, p in enumerate(params_list) if i not in done]
        bar = _progress_bar(len(params_list), len(done), progress)

        def finish(row: dict[str, Any]) -> None:
            if sweep_file is not None:
                sweep_file.append(row)
            done[row["index"]] = row
            bar.update(1)
            bar.set_postfix_str(f"A={row['A']:.4g}+-{row['A_stderr']:.2g}", refresh=False)
            if on_row is not None:
                on_row(row)

        try:
            if todo and client is None:
                _run_local(todo, spec, threads, finish)
            elif todo:
                _run_dask(todo, spec, threads, client, finish)
        finally:
            bar.close()
    finally:
        if sweep_file is not None:
            sweep_file.close()
    return [done[i] for i in range(len(params_list))]


def _progress_bar(total: int, initial: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc="points",
        unit="point",
        file=sys.stderr,
        # None: tqdm draws only on a terminal, as the other bars of the CLI.
        disable=None if enabled else True,
        dynamic_ncols=True,
    )
