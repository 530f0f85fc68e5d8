"""Work lost when a ``warpratchet run --out`` is stopped by SIGINT, SIGTERM or SIGKILL.

Starts the run in a child process, waits ``--after`` seconds of running (counted from its first
series row), sends the signal, and reads the archive: the work lost is the steps between the
newest series row (where the run had got to, within one chunk) and the checkpoint (where a
rerun continues), and those steps in seconds at the run's measured speed.

With ``--checkpoint-cost`` it times instead one checkpoint of ``--points`` points
(``ArchiveSink.checkpoint``: the state, two fsyncs; median of 10) and reports it as a share of
the kernel time between two checkpoints at the wall-clock cadence (``checkpoint_seconds``).

Usage::

    .venv/bin/python benchmarks/interrupt_loss.py --points 100000 --after 100
    .venv/bin/python benchmarks/interrupt_loss.py --points 100000 --checkpoint-cost
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from warpratchet.archive import open_archive


def _rows(path: Path) -> int:
    try:
        with open_archive(path) as arc:
            return int(arc.series["step"].size)
    except (OSError, ValueError):
        return 0


def measure(signum: int, points: int, after: float, folder: Path) -> dict:
    path = folder / f"{signal.Signals(signum).name}.h5"
    argv = [sys.executable, "-m", "warpratchet.cli", "run", "--K", "3", "--b1", "0.1", "--b2", "0.01"]
    argv += ["--points", str(points), "--steps", "100000000", "--out", str(path), "--quiet"]
    # A shell without job control starts background jobs with SIGINT ignored; the run must see it.
    restore = (lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)) if hasattr(signal, "SIGKILL") else None
    proc = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=restore
    )
    while _rows(path) == 0:
        if proc.poll() is not None:
            raise SystemExit(f"{argv} ended: {proc.communicate()[1]}")
        time.sleep(0.05)
    time.sleep(after)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=900)
    with open_archive(path) as arc:
        info = arc.info()
        rows = arc.series
    newest, kept = int(rows["step"][-1]), info["checkpoint_step"]
    speed = info["steps_per_second"]
    return {
        "signal": signal.Signals(signum).name,
        "status": proc.returncode,
        "newest_row": newest,
        "checkpoint": kept,
        "steps_lost": newest - kept,
        "seconds_lost": (newest - kept) / speed if speed else None,
        "chunk_steps": info["settings"]["chunk_steps"],
        "chunk_seconds": info["settings"]["chunk_steps"] / speed if speed else None,
        "message": err.strip().splitlines()[-1] if err.strip() else "",
    }


def checkpoint_cost(points: int, folder: Path, repeat: int = 10) -> dict:
    import statistics

    from warpratchet import Ensemble, MapParams
    from warpratchet.archive import ArchiveSink
    from warpratchet.spec import CHECKPOINT_SECONDS

    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), points, seed=1).run(1000)
    times = []
    with ArchiveSink(folder / "cost.h5", ens) as sink:
        for _ in range(repeat):
            start = time.perf_counter()
            sink.checkpoint()
            times.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {
        "points": points,
        "checkpoint_seconds_median": median,
        "checkpoint_seconds_max": max(times),
        "cadence_seconds": CHECKPOINT_SECONDS,
        "share_of_kernel_time": median / (CHECKPOINT_SECONDS - median),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--after", type=float, default=100.0, help="seconds of running before the signal")
    parser.add_argument("--signals", default="SIGINT,SIGTERM,SIGKILL")
    parser.add_argument("--checkpoint-cost", action="store_true", help="time one checkpoint instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.checkpoint_cost:
            print(json.dumps(checkpoint_cost(args.points, Path(folder))))
            return 0
        for name in args.signals.split(","):
            print(
                json.dumps(measure(signal.Signals[name], args.points, args.after, Path(folder))), flush=True
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
