""":func:`run_sharded`: a run's shards submitted to a Dask cluster, merged, written to ``out``.

The run is checked first (the shards against the workers' memory, the merge against this
machine's, the workdir against the run it holds); the shards are submitted, gathered in the
order they finish (a failure is reported at once) and merged in shard order
(:class:`~warpratchet.cluster.ShardedRun`), and with ``out`` written as one archive
(:func:`warpratchet._cluster_archive.write_merged`).
"""

from __future__ import annotations

import os
import time
from typing import Any

from ..errors import ParameterError, check_count
from ..history import history_steps
from ..spec import RunSpec
from ._merge import ShardedRun
from ._plan import _check_workers, _ensemble_size, check_merge, shard_bounds
from ._shard import ShardRecord, _without_rows, run_shard
from ._workdir import _claim_workdir, _manifest, _remove_other_runs, _run_folder


def run_sharded(
    spec: RunSpec,
    client: Any,
    shards: int | None = None,
    *,
    transport: bool = False,
    observers=(),
    workdir: str | os.PathLike | None = None,
    checkpoint_every: int | None = None,
    out: str | os.PathLike | None = None,
    progress: bool = False,
    snapshot_every: int = 0,
    snapshot_points: int = 1000,
    force: bool = False,
) -> ShardedRun:
    """Run the ensemble of ``spec`` as ``shards`` Dask tasks and merge them (:mod:`warpratchet.cluster`).

    Parameters
    ----------
    spec : RunSpec
        The run; ``threads`` is each shard's (None: every core of its worker process).
    client : dask.distributed.Client or str
        The cluster, or its scheduler's address (connected and closed here).
    shards : int, optional
        Shards, ``1..points``; default one per worker.
    transport : bool
        Count return times and flights too (:class:`~warpratchet.transport.TransportEnsemble`).
    observers : sequence of Observer
        Added to every shard's run (pickled to the workers).
    workdir : path, optional
        A folder on storage every worker shares: each shard keeps an archive of its points and
        its records there (:func:`run_shard`), so that a shard whose worker dies is retried from
        its last checkpoint rather than from step 0. The folder is made if missing.
    checkpoint_every : int, optional
        Steps between the shards' checkpoints (with ``workdir``; default: the archive's).
    out : path, optional
        One archive of the whole run, written when it is merged (a new file; ``workdir``
        defaults to the run's own folder in ``out`` + ``".shards"``, named by the run,
        :func:`_run_folder`): the merged series and history, and the shards' per-point data as
        virtual datasets over their archives (:mod:`warpratchet._cluster_archive`).
    progress : bool
        A progress bar over the shards done, on stderr.
    snapshot_every, snapshot_points : int
        Steps between snapshots (0: none) of a fixed subsample of ``snapshot_points`` points, as
        :class:`~warpratchet.archive.ArchiveSink` takes them: each shard takes those of its points
        (with ``workdir``), and ``out`` exposes them as the single machine's ``/snapshots``.
    force : bool
        Replace an existing ``out``. It stays as it is, reading its own shards, until the new one
        is complete and takes its name in one rename; with the default ``workdir`` the new run's
        shards are in their own folder, and the other runs' folders in ``out`` + ``".shards"``
        are removed after.

    Raises
    ------
    ResourceError
        The largest shard does not fit the smallest worker's memory limit (checked before any work).
    RuntimeError
        A shard failed for good (after Dask's retries of a lost worker): names the shard and why.
    """
    from ..sweep._run import _connect

    if not isinstance(spec, RunSpec):
        raise ParameterError(f"spec = {spec!r} is not a RunSpec")
    from ..limits import check_kernel_range

    check_kernel_range(spec.params)
    from ..archive import schedule

    if snapshot_every:  # chunk ends on the snapshots, as on one machine (ParameterError if not)
        schedule(spec.points, spec.chunk_steps, snapshot_every, checkpoint_every)
    points = _ensemble_size(spec)
    snapshots = (snapshot_every, min(check_count("snapshot_points", snapshot_points, 1), points))
    shared = workdir is None  # the default folder, beside out
    if out is not None:
        out = os.fspath(out)
        if os.path.lexists(out) and not force:
            raise ParameterError(
                f"out = {out} exists; choose a new path or replace it with force=True (nothing was run)"
            )
        if workdir is None:
            workdir = out + ".shards"
    if snapshot_every and workdir is None:
        raise ParameterError(
            f"snapshot_every = {snapshot_every} needs out (or workdir): the snapshots go to files"
        )
    client, owned = _connect(client)
    try:
        if shards is None:
            shards = max(1, len(client.scheduler_info()["workers"]))
        bounds = shard_bounds(points, min(check_count("shards", shards, 1, points), points))
        _check_workers(client, spec, bounds, transport, workdir is not None, snapshots)
        check_merge(points, transport, len(history_steps(0, spec.steps)))
        if workdir is not None:
            run = _manifest(spec, bounds, transport, snapshots)
            if shared:  # each run its own folder: a replaced out reads its own until the new one is out
                workdir = os.path.join(workdir, _run_folder(run))
            workdir = _claim_workdir(workdir, run)
        start = time.perf_counter()
        futures = [
            client.submit(
                run_shard,
                spec,
                lo,
                hi,
                transport,
                list(observers),
                workdir,
                k,
                checkpoint_every,
                snapshot_every,
                snapshots[1],
                pure=False,
            )  # fmt: skip
            for k, (lo, hi) in enumerate(bounds)
        ]
        import distributed

        from ..progress import ProgressBar

        records: dict[int, ShardRecord] = {}
        index = {future.key: k for k, future in enumerate(futures)}
        # the records stay where they are; this process receives each shard's counts and block gains
        bar = ProgressBar("shards", disable=not progress, unit="shard")
        bar.open(len(bounds))
        try:
            # In the order they finish (a failure is reported at once), merged in shard order.
            for future in distributed.as_completed(futures):
                k = index[future.key]
                try:
                    records[k] = client.submit(_without_rows, future, pure=False).result()
                except Exception as exc:
                    lo, hi = bounds[k]
                    why = f"{type(exc).__name__}: {exc}"
                    raise RuntimeError(
                        f"shard {k} of {len(bounds)} (points {lo}..{hi - 1}) failed: {why}"
                    ) from exc
                bar.advance()
            records = [records[k] for k in range(len(bounds))]
            merged = ShardedRun(spec, records, transport, futures, client)
            merged.seconds = time.perf_counter() - start
        finally:
            bar.close()
            client.cancel(futures)
        if out is not None:
            from .._cluster_archive import write_merged

            write_merged(out, merged, workdir, bounds, snapshots, replace=force)
            if shared:
                _remove_other_runs(workdir)
        return merged
    finally:
        if owned:
            client.close()
