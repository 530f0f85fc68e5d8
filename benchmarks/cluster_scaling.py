"""One ensemble on a Dask cluster: 1 and 2 worker processes against one process, and the merge's cost.

The run is the strip ensemble (Eq. B) at K = 3, b1 = 0.1, b2 = 0.01, with its history, as
``warpratchet run`` makes it. Rows:

* ``single``: one process, :class:`~warpratchet.ensemble.Ensemble` with 1 thread;
* ``dask``: :func:`warpratchet.cluster.run_sharded` on a LocalCluster of 1 and of 2 worker
  processes with one thread each, one shard per worker (clusters are started and warmed up, every
  worker loading the Warp kernel, before the clock starts).

``cpu_seconds``: the CPU time of the single process, or of all the workers' processes (the shards'
runs and Dask's own threads), which a busy machine inflates much less than wall time.

Every row's summary and history must equal the single process's bit for bit; the script exits
with status 1 if not.

The merge. :class:`~warpratchet.cluster.ShardedRun` is timed on a LocalCluster of 2 worker
processes holding the records of the whole ensemble cut into S = 1, 4, 16, ..., 1024 shards (up
to 64 with ``--quick``; the records of one shard, sliced and scattered to the workers: the merge's
tasks see the same numbers as from S shards' runs, and each merge must equal the single process
bit for bit). A
least-squares line ``t(S) = a + b S`` gives the per-shard cost ``b`` (the merge's tasks and
their scheduling) and ``a`` (``a / (points x rows)``: the cost per point and history row); the
projection to 100 and 1,000 shards is ``a + b S`` at this ensemble's size (``a`` grows with the
points, ``b`` does not). ``gathered_bytes``: what the merge's tasks hand to the client. A Dask
row's ``fetch_seconds`` is its wall time less the slowest shard's run and the merge
(scheduling).

Usage::

    python benchmarks/cluster_scaling.py                  # 10^5 points x 2x10^4 steps, 2-3 min on 2 cores
    python benchmarks/cluster_scaling.py --json           # one JSON object on stdout
    python benchmarks/cluster_scaling.py --quick --json   # smoke test
"""

from __future__ import annotations

import dataclasses
import json
import logging
import struct
import sys
import time
from typing import Any

import numpy as np
from sweep_scaling import _log, _parser  # the sibling benchmark's one-line errors and progress lines

from warpratchet.cli import positive_int
from warpratchet.cluster import ShardedRun, ShardRecord, run_shard, run_sharded, shard_bounds
from warpratchet.ensemble import Ensemble
from warpratchet.history import History
from warpratchet.spec import RunSpec


def _exact(summary: dict, history: History) -> tuple:
    """A summary and history rows, floats by their bits."""
    values = [*summary.values(), *(v for rows in history.as_dict().values() for v in rows)]
    return tuple(struct.pack("<d", v) if isinstance(v, float) else v for v in values)


def _slice(record: ShardRecord, lo: int, hi: int) -> ShardRecord:
    """The records of points ``lo <= i < hi`` of a whole-ensemble ``record`` (blocks: all in the first)."""
    first = lo == 0
    keep = slice(None) if first else slice(0, 0)
    return dataclasses.replace(
        record, lo=lo, hi=hi, gain=record.gain[:, lo:hi], stretch=record.stretch[:, lo:hi],
        block_gain=record.block_gain[:, keep], block_ftle=record.block_ftle[:, keep],
    )  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = _parser(__doc__, "small run (smoke test)")
    parser.add_argument("--points", type=positive_int, default=None, help="ensemble size (10^5)")
    parser.add_argument("--steps", type=positive_int, default=None, help="iterations (2x10^4)")
    args = parser.parse_args(argv)

    import distributed

    spec = RunSpec(
        K=3.0, b1=0.1, b2=0.01, seed=1, threads=1,
        points=args.points or (4_000 if args.quick else 100_000),
        steps=args.steps or (2_000 if args.quick else 20_000),
    )  # fmt: skip
    _log(f"single process: {spec.points} points x {spec.steps} steps")
    start, cpu = time.perf_counter(), time.process_time()
    ensemble = Ensemble.sample(spec.params, spec.points, spec.init, spec.seed, threads=1)
    history = History(spec.threshold, spec.threshold_rule)
    ensemble.run(spec.steps, [history])
    single = time.perf_counter() - start
    single_cpu = time.process_time() - cpu
    reference = _exact(ensemble.summary(warn=False).as_dict(), history)
    rows: list[dict[str, Any]] = [
        {"executor": "single", "workers": None, "shards": 1, "seconds": single, "cpu_seconds": single_cpu}
    ]
    identical = True
    for workers in (1, 2):
        with (
            distributed.LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None, silence_logs=logging.ERROR,
            ) as cluster,
            distributed.Client(cluster) as client,
        ):  # fmt: skip
            client.run(run_shard, RunSpec(K=3.0, b1=0.1, b2=0.01, points=8, steps=8, threads=1), 0, 8)
            _log(f"dask: {workers} worker(s)")
            before = client.run(time.process_time)
            merged = run_sharded(spec, client, workers)
            after = client.run(time.process_time)
        cpu = sum(after[w] - before[w] for w in before)
        same = _exact(merged.summary(warn=False).as_dict(), merged.history) == reference
        identical &= same
        rows.append(
            {
                "executor": "dask", "workers": workers, "shards": workers, "seconds": merged.seconds,
                "cpu_seconds": cpu,
                "merge_seconds": merged.merge_seconds, "identical": same,
                "shard_seconds": merged.shard_seconds,
                "fetch_seconds": merged.seconds - merged.merge_seconds - max(merged.shard_seconds),
            }
        )  # fmt: skip

    _log("merge: one record cut into S shards, on 2 worker processes")
    whole = run_shard(spec, 0, spec.points)
    merges = []
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None, silence_logs=logging.ERROR,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):  # fmt: skip
        for shards in (1, 4, 16, 64) if args.quick else (1, 4, 16, 64, 256, 1024):
            records = [_slice(whole, lo, hi) for lo, hi in shard_bounds(spec.points, shards)]
            futures = client.scatter(records)
            small = [dataclasses.replace(r, gain=None, stretch=None) for r in records]
            merged = ShardedRun(spec, small, False, futures, client)
            same = _exact(merged.summary(warn=False).as_dict(), merged.history) == reference
            identical &= same
            merges.append({"shards": shards, "seconds": merged.merge_seconds,
                           "gathered_bytes": merged.gathered_bytes, "identical": same})  # fmt: skip
            client.cancel(futures)
    s = np.array([m["shards"] for m in merges], dtype=float)
    t = np.array([m["seconds"] for m in merges])
    per_shard, base = np.polyfit(s, t, 1)
    history_rows = len(whole.steps)
    report = {
        "problem": {**spec.as_dict(), "history_rows": history_rows, "quick": args.quick},
        "rows": rows,
        "speedup_2_vs_1_workers": rows[1]["seconds"] / rows[2]["seconds"],
        "dask_1_worker_vs_single": rows[1]["seconds"] / single,
        "workers_cpu_vs_single": [r["cpu_seconds"] / single_cpu for r in rows[1:]],
        "merge": merges,
        "merge_base_seconds": float(base),
        "merge_per_shard_seconds": float(per_shard),
        "merge_per_point_row_ns": float(base) / (spec.points * history_rows) * 1e9,
        "merge_projected_seconds": {str(n): float(base + per_shard * n) for n in (100, 1000)},
        "identical": identical,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"{spec.points} points x {spec.steps} steps, {history_rows} history rows")
        for r in rows:
            print(
                f"  {r['executor']:>6} workers={r['workers']!s:>4}  {r['seconds']:8.2f} s, "
                f"{r['cpu_seconds']:8.2f} s CPU"
            )
        print(f"  2 workers vs 1: x{report['speedup_2_vs_1_workers']:.2f}")
        print(f"  merge: {base:.3f} s + {per_shard * 1e3:.3f} ms per shard")
        print(f"  merge of {merges[-1]['shards']} shards: {merges[-1]['gathered_bytes']} B to the client")
        for n, v in report["merge_projected_seconds"].items():
            print(f"  merge at {n} shards: {v:.3f} s")
        print(f"  identical to the single process: {identical}")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
