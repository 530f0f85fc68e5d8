"""Sweep scaling: points per minute locally and on 1 and 2 local Dask workers, and Dask's per-point overhead.

The sweep is the maximal path of Eq. (b2max) at K = 3 with ``b2`` uniform on the interval of
Fig. 7, ``0.005 <= b2 <= 0.165``, each point a strip ensemble (Eq. B) written to a fresh HDF5
sweep file, exactly what ``warpratchet sweep --path maximal`` does. Executors (rows):

* ``local``: :func:`warpratchet.sweep.run_sweep` without a client, points one after another,
  with every core per point (the default) and with 1 thread per point;
* ``dask``: a ``dask.distributed.LocalCluster`` of 1 and of 2 worker processes with one thread
  each (one point per worker at a time, 1 thread per point), through a Client.

Clusters are started and warmed up (every worker imports warpratchet and loads the Warp kernel
once) before the clock starts: a cluster is long-lived, its start-up time is reported apart.

Two problems are run with every executor:

* ``work``: ensembles large enough that the map dominates; gives points per minute, and the
  speed-up of 2 workers over 1;
* ``tiny``: 64 points x 8 steps per sweep point, so that almost all wall time is per-point
  overhead (sampling, summary, the HDF5 row, and for Dask scheduling and transfer).

Per-point overhead = (slots x wall time - sum of the rows' ``seconds``, the time inside
``Ensemble.run``) / points, where slots is the number of points run at a time (1 locally, the
number of workers on Dask); Dask's overhead against the local executor is the difference of
the two at 1 thread per point, on the ``tiny`` problem. All executors must produce the same
rows bit for bit (timing excluded); the script exits with status 1 if not. Timings on the
shared 2-core machine are noisy: read the ratios, taken within one run.

Usage::

    python benchmarks/sweep_scaling.py                  # 24 points x (10^4 x 2x10^4), ~1 min on 2 cores
    python benchmarks/sweep_scaling.py --json           # one JSON object on stdout
    python benchmarks/sweep_scaling.py --quick --json   # smoke test, ~15 s
"""

from __future__ import annotations

import argparse
import json
import logging
import struct
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from warpratchet.cli import positive_int
from warpratchet.ensemble import default_threads
from warpratchet.sweep import TIMING_FIELDS, SweepSpec, maximal_path, run_point, run_sweep

B2_RANGE = (0.005, 0.165)  # Fig. 7
TINY = SweepSpec(points=64, steps=8, seed=3)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def _parser(doc: str, quick: str) -> _Parser:
    """A scaling benchmark's parser: ``--quick`` (help ``quick``) and ``--json``; sizes come after."""
    parser = _Parser(description=doc.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=quick)
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    return parser


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _physics(rows: list[dict[str, Any]]) -> list[tuple]:
    """Rows without timing, floats by their bits (NaN equals NaN)."""
    return [
        tuple(
            struct.pack("<d", v) if isinstance(v, float) else v
            for k, v in r.items()
            if k not in TIMING_FIELDS
        )
        for r in rows
    ]


def _measure(
    label: str, points, spec: SweepSpec, folder: Path, slots: int, **kwargs: Any
) -> tuple[dict, list]:
    """Run one sweep; ``slots`` points run at a time (1 locally, one per Dask worker thread)."""
    _log(f"measuring {label}: {len(points)} points of {spec.points} x {spec.steps}")
    out = folder / f"{label}-{spec.points}x{spec.steps}.h5"
    start = time.perf_counter()
    rows = run_sweep(points, spec, out=out, progress=False, **kwargs)
    wall = time.perf_counter() - start
    inside = sum(r["seconds"] for r in rows)
    n = len(rows)
    return {
        "sweep_points": n,
        "seconds": wall,
        "points_per_minute": 60.0 * n / wall,
        "ensemble_seconds": inside,
        # Slot time not spent inside Ensemble.run, per point.
        "overhead_per_point_seconds": (slots * wall - inside) / n,
    }, rows


def main(argv: list[str] | None = None) -> int:
    parser = _parser(__doc__, "small sweep (smoke test)")
    parser.add_argument("--sweep-points", type=positive_int, default=None, help="points on the path (24)")
    parser.add_argument("--points", type=positive_int, default=None, help="ensemble size per point (10^4)")
    parser.add_argument("--steps", type=positive_int, default=None, help="iterations per point (2x10^4)")
    args = parser.parse_args(argv)

    import distributed

    n_path = args.sweep_points or (6 if args.quick else 24)
    work = SweepSpec(
        points=args.points or (2_000 if args.quick else 10_000),
        steps=args.steps or (5_000 if args.quick else 20_000),
        seed=1,
    )
    tiny_path = 40 if args.quick else 200
    path = maximal_path(np.linspace(*B2_RANGE, n_path))
    tiny_points = maximal_path(np.linspace(*B2_RANGE, tiny_path))
    cores = default_threads()

    results: list[dict[str, Any]] = []
    reference: dict[str, list] = {}
    identical = True
    cluster_start: dict[str, float] = {}

    def record(
        problem: str, executor: str, workers: int | None, threads: int, timing: dict, rows: list
    ) -> None:
        nonlocal identical
        same = reference.setdefault(problem, _physics(rows)) == _physics(rows)
        identical &= same
        row = {"problem": problem, "executor": executor, "workers": workers, "threads_per_point": threads}
        row.update(timing, rows_identical=same)
        results.append(row)

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        # Warm-up here too: the first ensemble loads (or compiles) the Warp kernel.
        run_point(path[0], TINY)
        for problem, points, spec in (("work", path, work), ("tiny", tiny_points, TINY)):
            for threads in sorted({cores, 1}, reverse=True):
                timing, rows = _measure(f"local{threads}", points, spec, folder, 1, threads=threads)
                record(problem, "local", None, threads, timing, rows)
        for workers in (1, 2):
            start = time.perf_counter()
            with (
                distributed.LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                ) as cluster,
                distributed.Client(cluster) as client,
            ):
                client.run(run_point, path[0], TINY)  # every worker imports and loads the kernel
                cluster_start[str(workers)] = time.perf_counter() - start
                for problem, points, spec in (("work", path, work), ("tiny", tiny_points, TINY)):
                    timing, rows = _measure(f"dask{workers}", points, spec, folder, workers, client=client)
                    record(problem, "dask", workers, 1, timing, rows)

    def find(problem: str, executor: str, workers: int | None, threads: int) -> dict[str, Any]:
        return next(
            r
            for r in results
            if (r["problem"], r["executor"], r["workers"], r["threads_per_point"])
            == (problem, executor, workers, threads)
        )

    dask1, dask2 = find("work", "dask", 1, 1), find("work", "dask", 2, 1)
    tiny_dask, tiny_local = find("tiny", "dask", 1, 1), find("tiny", "local", None, 1)
    report = {
        "problem": {
            "path": "maximal (Eq. b2max), K = 3",
            "b2_range": list(B2_RANGE),
            "work": {"sweep_points": n_path, **work.as_dict()},
            "tiny": {"sweep_points": tiny_path, **TINY.as_dict()},
            "quick": args.quick,
        },
        "machine": {"cores": cores},
        "results": results,
        "cluster_start_seconds": cluster_start,
        "speedup_2_vs_1_workers": dask2["points_per_minute"] / dask1["points_per_minute"],
        "dask_1_worker_vs_local_1_thread": dask1["points_per_minute"]
        / find("work", "local", None, 1)["points_per_minute"],
        "dask_overhead_per_point_seconds": tiny_dask["overhead_per_point_seconds"]
        - tiny_local["overhead_per_point_seconds"],
        "rows_identical": identical,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"maximal path, {n_path} points of {work.points} x {work.steps} ({cores} cores)")
        header = ("problem", "executor", "workers", "threads", "points/min", "overhead ms")
        print(" ".join(f"{h:>{w}}" for h, w in zip(header, (7, 8, 7, 7, 10, 11), strict=True)))
        for r in results:
            print(
                f"{r['problem']:>7} {r['executor']:>8} {r['workers']!s:>7} {r['threads_per_point']:>7} "
                f"{r['points_per_minute']:>10.1f} {1e3 * r['overhead_per_point_seconds']:>11.2f}"
            )
        print(f"2 workers / 1 worker: {report['speedup_2_vs_1_workers']:.2f}x points per minute")
        print(
            f"Dask overhead against local: {1e3 * report['dask_overhead_per_point_seconds']:.2f} ms per point"
        )
        print(
            "cluster start + warm-up: "
            + ", ".join(f"{k} worker(s) {v:.1f} s" for k, v in cluster_start.items())
        )
        print(f"rows identical across executors: {identical}")
    if not identical:
        _log("error: executors produced different rows")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
