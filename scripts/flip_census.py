"""The full single-bit flip census of an archive and of a sweep file: every byte, one bit each.

The suite flips a deterministic sample of offsets (tests/archive/test_verify.py,
tests/sweep/test_sweep_file.py); this script flips every ``--stride``-th byte (bit ``i % 8`` of
the i-th; ``--all-bits`` flips each of the 8 bits) of files made as those tests make them:

* ``archive``: 300 points, 1000 steps, snapshots every 200 steps, checkpoints every 400. Each
  flip is either reported by ``verify`` or leaves what a reader returns unchanged or announced
  (an older checkpoint, equal to an uninterrupted run's); every flip in stored data is reported.
* ``sweep``: the maximal path at b2 = 0.01, 0.05, 0.1, 60 points, 200 steps. Each flip is an
  error or leaves the rows unchanged.

Usage::

    python scripts/flip_census.py                  # both files, every byte
    python scripts/flip_census.py archive --stride 7
    python scripts/flip_census.py sweep --all-bits

Prints each census; exits 1 if any flip changed a number silently, escaped ``verify`` in stored
data or recovered a wrong checkpoint.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from support import archive_flip_census, stored_chunks, sweep_flip_census  # noqa: E402

from warpratchet import Ensemble, MapParams  # noqa: E402
from warpratchet.archive import ArchiveSink  # noqa: E402
from warpratchet.sweep import SweepSpec, maximal_path, run_sweep  # noqa: E402


def _fresh() -> Ensemble:
    return Ensemble.sample(MapParams(3.0, 0.1, 0.01), 300, "strip", 5)


def _archive(folder: Path) -> Path:
    path = folder / "run.h5"
    ens = _fresh()
    schedule = {"snapshot_every": 200, "snapshot_points": 40, "checkpoint_every": 400, "chunk_steps": 100}
    with ArchiveSink(path, ens, **schedule) as sink:
        ens.run(1000, [sink], chunk_steps=sink.chunk_steps)
    return path


def _sweep(folder: Path) -> Path:
    path = folder / "sweep.h5"
    run_sweep(
        maximal_path([0.01, 0.05, 0.1]), SweepSpec(points=60, steps=200, seed=2), out=path, progress=False
    )
    return path


def _offsets(path: Path, stride: int, all_bits: bool) -> list[int]:
    every = range(0, os.path.getsize(path), stride)
    # bit i % 8 of the i-th offset: repeating each offset 8 times flips each of its bits once
    return [o for o in every for _ in range(8)] if all_bits else list(every)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", metavar="archive|sweep", help="which census (default both)")
    ap.add_argument("--stride", type=int, default=1, help="flip every STRIDE-th byte (default 1: every byte)")
    ap.add_argument("--all-bits", action="store_true", help="flip each of the 8 bits of every byte tried")
    args = ap.parse_args(argv)
    for name in args.files:
        if name not in ("archive", "sweep"):
            ap.error(f"{name!r} is not one of archive, sweep")
    if args.stride < 1:
        ap.error(f"--stride {args.stride} is outside the allowed range (1 or more)")
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if "archive" in (args.files or ["archive"]):
            path = _archive(folder)
            offsets = _offsets(path, args.stride, args.all_bits)
            census = archive_flip_census(
                path, offsets, folder, lambda step: _fresh().run(step, chunk_steps=100).state()
            )
            in_data = [(s, n) for _, s, n in stored_chunks(path)]
            print(f"archive ({os.path.getsize(path)} bytes, {len(in_data)} stored chunks): {census}")
            failed |= bool(census["silent"] or census["missed"] or census["wrong"])
        if "sweep" in (args.files or ["sweep"]):
            path = _sweep(folder)
            outcomes = sweep_flip_census(path, _offsets(path, args.stride, args.all_bits), folder)
            print(f"sweep file ({os.path.getsize(path)} bytes): {outcomes}")
            failed |= bool(outcomes["silent"])
    print("FAILED: see the lists above" if failed else "every flip detected or harmless")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
