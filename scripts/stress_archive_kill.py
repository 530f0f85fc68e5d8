"""Stress test of the archive's guarantee: SIGKILL an archive writer at random instants, read the file back.

A forked writer streams a small ensemble into an archive with short chunks (a series row every
millisecond or so, a snapshot every 5 rows, a checkpoint every 40) and publishes, after each
chunk, how many rows it has committed. The parent kills it with SIGKILL once it has committed a
random number of rows (spread over several 256-row chunks of ``/series``), after a further random
delay of up to 3 ms so that the kill lands anywhere inside a row write, a flush, a resize or a
checkpoint. Each killed file is then read twice:

* ``torn``: plain HDF5 reads (h5py, SWMR) of the committed rows of every ``/series`` dataset and
  of ``/snapshots/step``, so every chunk's Fletcher-32 checksum as HDF5 checks it: counts the
  files in which the kill tore a chunk holding committed rows;
* ``failed``: :class:`warpratchet.archive.Archive` must open it and give every committed row,
  with the right steps, the snapshots and a verified checkpoint (the archive's guarantee).

``--writer unpaged`` creates archives as warpratchet did before paged file space
(``warpratchet._h5.create_h5``), to measure the failure this script was written for. Failing
files are kept with ``--keep``.

Usage::

    python scripts/stress_archive_kill.py --trials 2000 [--load 1] [--writer unpaged] [--keep DIR]

``--load N`` runs N busy-looping processes meanwhile (the CI failure came on a loaded 2-core
machine). Prints one line per bad trial, progress every 100 trials and a summary; exits 1 if any
archive failed (or, with the paged writer, any file was torn).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import shutil
import signal
import sys
import tempfile
import time
import warnings

import h5py
import numpy as np

import warpratchet.archive._writer as archive_writer
from warpratchet import Ensemble, MapParams, Observer
from warpratchet._h5 import LIBVER, open_h5
from warpratchet.archive import SERIES_FIELDS, Archive, ArchiveSink, ArchiveWarning

CHUNK, SNAPSHOT, CHECKPOINT = 10, 50, 400


class _Report(Observer):
    """Publishes the rows the sink has committed (it runs after the sink)."""

    def __init__(self, sink: ArchiveSink, committed) -> None:
        self.sink = sink
        self.committed = committed

    def after_chunk(self, ensemble, seconds):
        self.committed.value = self.sink._series.count


def _writer(path: str, committed, unpaged: bool) -> None:
    if unpaged:  # the file creation before paged file space
        archive_writer.create_h5 = lambda p: h5py.File(p, "w", libver=LIBVER)
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 64, "strip", 1, threads=1)
    sink = ArchiveSink(
        path, ens, snapshot_every=SNAPSHOT, snapshot_points=16, checkpoint_every=CHECKPOINT, chunk_steps=CHUNK
    )
    ens.run(10**9, [sink, _Report(sink, committed)], chunk_steps=CHUNK)


def _busy() -> None:
    while True:
        pass


def _torn(path: str) -> str | None:
    """Which dataset's committed rows HDF5 refuses (a torn chunk), or None."""
    with open_h5(path) as f:
        for group, names, counter in (
            ("series", SERIES_FIELDS, "progress/series_rows"),
            ("snapshots", ("step",), "progress/snapshot_rows"),
        ):
            n = int(f[counter][0])
            for name in names:
                try:
                    f[group][name][:n]
                except OSError:
                    return f"/{group}/{name} (row {n - 1} of {n})"
    return None


def _check(path: str, committed: int) -> str | None:
    """None if the killed writer's archive holds what it must, else what is wrong."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ArchiveWarning)
            with Archive(path) as arc:
                series = arc.series
                rows = series["step"].size
                if rows < committed:
                    return f"{committed} rows committed, {rows} readable"
                if not np.array_equal(series["step"], CHUNK * np.arange(1, rows + 1)):
                    return "wrong steps"
                if any(series[name].size != rows for name in SERIES_FIELDS):
                    return "ragged series"
                snaps = arc.snapshots
                if not np.array_equal(snaps.steps, SNAPSHOT * np.arange(1, len(snaps) + 1)):
                    return "wrong snapshot steps"
                _, step = arc.checkpoint()
                if step % CHECKPOINT or step > rows * CHUNK:
                    return f"checkpoint at step {step}"
    except Exception as exc:  # noqa: BLE001 - any failure is what we are looking for
        return f"{type(exc).__name__}: {exc}"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=500)
    ap.add_argument("--load", type=int, default=0, help="busy-looping processes meanwhile")
    ap.add_argument("--writer", choices=("paged", "unpaged"), default="paged")
    ap.add_argument("--max-rows", type=int, default=700, help="kill after up to this many rows")
    ap.add_argument("--keep", default=None, help="folder for the failing archives")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    ctx = mp.get_context("fork")
    # Compile and load the kernel once, before forking writers.
    Ensemble.sample(MapParams(3.0, 0.1, 0.01), 64, "strip", 1, threads=1).run(CHUNK)
    load = [ctx.Process(target=_busy, daemon=True) for _ in range(args.load)]
    for p in load:
        p.start()
    work = tempfile.mkdtemp(prefix="stress_kill_")
    torn = failed = killed = 0
    start = time.monotonic()
    try:
        for trial in range(args.trials):
            path = os.path.join(work, "run.h5")
            committed = ctx.Value("q", 0, lock=False)
            child = ctx.Process(target=_writer, args=(path, committed, args.writer == "unpaged"))
            child.start()
            target = int(rng.integers(1, args.max_rows))
            deadline = time.monotonic() + 60
            while committed.value < target and child.is_alive() and time.monotonic() < deadline:
                time.sleep(0.0005)
            time.sleep(rng.uniform(0.0, 0.003))
            os.kill(child.pid, signal.SIGKILL)
            child.join()
            killed += child.exitcode == -signal.SIGKILL
            seen = committed.value  # rows committed before the kill (the writer may have done more)
            if os.path.exists(path):
                where = _torn(path)
                problem = _check(path, seen)
                torn += where is not None
                failed += problem is not None
                if where or problem:
                    outcome = problem or "ok"
                    print(f"trial {trial}: killed after {seen} rows: torn {where}; archive: {outcome}")
                    if args.keep:
                        os.makedirs(args.keep, exist_ok=True)
                        shutil.copy(path, os.path.join(args.keep, f"{args.writer}{trial}_{seen}.h5"))
            for name in os.listdir(work):  # the archive, and temporary files of a kill during creation
                os.unlink(os.path.join(work, name))
            if (trial + 1) % 100 == 0:
                minutes = (time.monotonic() - start) / 60
                print(f"{trial + 1} trials, {torn} torn, {failed} failed, {minutes:.1f} min", flush=True)
    finally:
        for p in load:
            p.kill()
        shutil.rmtree(work, ignore_errors=True)
    minutes = (time.monotonic() - start) / 60
    print(
        f"writer {args.writer}, load {args.load}: {args.trials} trials ({killed} killed mid-run), "
        f"{torn} with a torn chunk of committed rows, {failed} archives failing, {minutes:.1f} min"
    )
    return 1 if failed or (torn and args.writer == "paged") else 0


if __name__ == "__main__":
    sys.exit(main())
