"""Running a sweep: one ensemble per point, here or on a Dask cluster, rows to the sweep file.

Reproducibility. Point ``i`` samples its ensemble with the seed :func:`point_seed`
``(spec.seed, i)``, the ``i``-th child of ``numpy.random.SeedSequence(spec.seed)``: points get
independent streams (their errors are uncorrelated along a path) and a row depends only on
``(params, spec, i)``, never on which executor ran it, in which order, or with how many threads
(the ensemble is bitwise independent of threads). The row stores the derived seed, so
``Ensemble.sample(params, points, init, seed=row["seed"])`` (or ``warpratchet run --seed``)
rebuilds that point's ensemble exactly: the point's :class:`~warpratchet.spec.RunSpec` is
``spec.at(params, row["seed"])``.

Executors. ``client=None`` runs the points one after another in this process, each on every
core. A ``dask.distributed.Client`` (or a scheduler address) runs :func:`run_point` on the
workers, one point per Dask worker thread; workers need only ``pip install
warpratchet[distributed]``.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import theory
from ..ensemble import Ensemble
from ..errors import ParameterError, check_count
from ..history import History
from ..limits import kernel_range_error
from ..params import MapParams
from ..progress import ProgressBar
from ..spec import SweepSpec, check_setting
from ._file import ROW_FIELDS, SweepFile
from ._paths import check_sweep_size

__all__ = ["point_seed", "run_point", "run_sweep"]


def point_seed(seed: int, index: int) -> int:
    """Seed of point ``index``: the ``index``-th child of ``SeedSequence(seed)``, as a 53-bit integer.

    Children of one SeedSequence are NumPy's recommended independent streams. 53 bits keep the
    seed exact in JSON readers that hold numbers as doubles.
    """
    child = np.random.SeedSequence(check_setting("seed", seed), spawn_key=(check_count("index", index, 0),))
    return int(child.generate_state(1, np.uint64)[0] >> np.uint64(11))


def _as_params(point: MapParams | Sequence[float]) -> MapParams:
    if isinstance(point, MapParams):
        return point
    try:
        K, b1, b2 = point
    except (TypeError, ValueError):
        raise ParameterError(f"sweep point {point!r} is neither MapParams nor a (K, b1, b2) triple") from None
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
        One row, keys :data:`~warpratchet.sweep._file.ROW_FIELDS` (per-iteration A and FTLE,
        the convergence verdict of the run's :class:`~warpratchet.history.History`: robust
        standard error, drift of A between n/2 and n, verdict; seconds of wall time, including
        the history's rows).

    Raises
    ------
    ValueError
        If the tangent overflows float64 (``b1`` or ``b2`` far too small); names the point.
    """
    run = spec.at(params, point_seed(spec.seed, index), threads)
    ensemble = Ensemble.sample(run.params, run.points, run.init, run.seed, threads=run.threads)
    history = History(run.threshold, run.threshold_rule)
    start = time.perf_counter()
    try:
        ensemble.run(run.steps, [history])
        s = ensemble.summary(run.threshold, run.threshold_rule, warn=False)  # the history's last row's
    except FloatingPointError as exc:
        raise ValueError(
            f"sweep point {index} (K={params.K!r}, b1={params.b1!r}, b2={params.b2!r}): {exc}"
        ) from exc
    seconds = time.perf_counter() - start
    verdict = history.convergence()
    # theory.acceleration is exact only at K = 3 (Sec. IV); elsewhere the paper has no closed form,
    # and another force than Eq. (fx) none at all (its row has NaN b1, b2 and domain "n/a").
    a_theory = theory.acceleration(params) if params.K == 3.0 and params.is_paper else None
    row = {
        **run.as_dict(),  # K, b1, b2, seed, init (and settings the row does not keep)
        **({} if params.is_paper else {"b1": math.nan, "b2": math.nan}),
        # A, A_stderr, lyapunov (+ _std, _min), chaotic_fraction, chaotic_points, and the threshold used
        **s.as_dict(),
        "index": int(index),
        "domain": theory.domain(params) if params.is_paper else "n/a",
        "A_theory": math.nan if a_theory is None else float(a_theory),
        "points": ensemble.points,  # as run: a grid rounds down to a square
        "steps": ensemble.step,
        "A_stderr_robust": verdict.A_stderr_robust,
        "drift": verdict.drift,
        "drift_z": verdict.drift_z,
        "verdict": verdict.verdict,
        "diffusion_exponent": verdict.exponent,
        "seconds": seconds,
    }
    return {name: row[name] for name in ROW_FIELDS}


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
    raise ParameterError(
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
        A progress bar over points on stderr (:class:`~warpratchet.progress.ProgressBar`).
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
        raise ParameterError(f"spec = {spec!r} is not a SweepSpec")
    if isinstance(points, (str, bytes)) or not hasattr(points, "__iter__"):
        raise ParameterError(f"points = {points!r} is not a sequence of MapParams or (K, b1, b2) triples")
    params_list = [_as_params(p) for p in points]
    if not params_list:
        raise ParameterError("a sweep needs at least 1 point; got 0")
    check_sweep_size(len(params_list), f"a sweep of {len(params_list)} points")
    for index, params in enumerate(params_list):  # every point before the first runs
        why = kernel_range_error(params)
        if why is not None:
            raise ParameterError(
                f"sweep point {index} (K={params.K!r}, b1={params.b1!r}, b2={params.b2!r}): {why}"
            )
    if threads is not None:
        threads = check_setting("threads", threads)
    elif client is not None:
        threads = 1  # Dask: a worker thread stands for one core
    if client is None:  # here: every point's ensemble must fit this machine (Dask workers check theirs)
        Ensemble.check_fits(spec.points)
    if client is not None and not isinstance(client, str):
        _connect(client)  # checks the type (and that Dask is installed) before any file is touched
    forces = {p.table for p in params_list if not p.is_paper}
    if out is not None and (len(forces) > 1 or (forces and any(p.is_paper for p in params_list))):
        raise ParameterError(
            "a sweep file holds the paper's force (b1, b2 per point) or one other force (K per point); "
            f"these points have {len(forces) + any(p.is_paper for p in params_list)} forces"
        )
    table = np.array([[p.K, p.b1, p.b2] for p in params_list], dtype=np.float64)

    other = forces.pop().as_strings() if forces else None
    sweep_file = SweepFile(out, table, spec, force, other) if out is not None else None
    try:
        done = {row["index"]: row for row in sweep_file.rows()} if sweep_file is not None else {}
        todo = [(i, p) for i, p in enumerate(params_list) if i not in done]
        bar = ProgressBar("points", disable=not progress, unit="point")
        bar.open(len(params_list), len(done))

        def finish(row: dict[str, Any]) -> None:
            if sweep_file is not None:
                sweep_file.append(row)
            done[row["index"]] = row
            bar.advance(postfix=f"A={row['A']:.4g}+-{row['A_stderr']:.2g}")
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
