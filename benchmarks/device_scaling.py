"""Throughput of ``Ensemble.run`` on one Warp device as the ensemble grows.

A GPU needs many more points than a CPU to fill its cores: this script times the same run
(K = 3, b1 = 0.1, b2 = 0.01, points uniform in the strip B, seed 1) at several ensemble sizes on
one device and prints point-steps per second for each. Each size is first advanced
``--warmup`` steps untimed (kernel compilation, and tangents that are renormalised during the
timed steps, as in a long run), then ``--steps`` steps in one chunk are timed.

    python benchmarks/device_scaling.py --device cuda:0 --points 1e6,1e7,1e8 --steps 2000
    python benchmarks/device_scaling.py --device cpu --points 1e5,1e6 --steps 500 --json
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from warpratchet import Ensemble, MapParams

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)


def _counts(text: str) -> list[int]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"points = {text!r} is not a comma-separated list of counts"
        ) from None
    if any(v < 1 or v != int(v) for v in values):
        raise argparse.ArgumentTypeError(f"points = {text!r}: every count must be an integer >= 1")
    return [int(v) for v in values]


def measure(device: str, points: int, steps: int, warmup: int, seed: int = 1) -> dict:
    """Time ``steps`` steps of ``points`` points on ``device`` after ``warmup`` untimed steps."""
    ens = Ensemble.sample(PARAMS, points, init="strip", seed=seed, device=device)
    ens.run(warmup, chunk_steps=max(warmup, 1))
    start = time.perf_counter()
    ens.run(steps, chunk_steps=steps)
    seconds = time.perf_counter() - start
    return {
        "device": ens.device,
        "points": points,
        "steps": steps,
        "seconds": seconds,
        "point_steps_per_second": points * steps / seconds,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cpu", help="Warp device, e.g. cuda:0 (default cpu)")
    parser.add_argument("--points", type=_counts, default=[10**5, 10**6], help="comma-separated sizes")
    parser.add_argument("--steps", type=int, default=1000, help="timed steps per size (default 1000)")
    parser.add_argument("--warmup", type=int, default=1024, help="untimed steps first (default 1024)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    args = parser.parse_args(argv)
    rows = []
    for points in args.points:
        row = measure(args.device, points, args.steps, args.warmup)
        rows.append(row)
        if not args.json:
            print(
                f"{row['device']}: {points:>12,} points x {args.steps:,} steps: {row['seconds']:8.3f} s, "
                f"{row['point_steps_per_second'] / 1e9:9.2f} G point-steps/s",
                flush=True,
            )
    if args.json:
        print(json.dumps({"rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
