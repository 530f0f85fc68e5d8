"""What a user's run costs beyond its kernel: ``warpratchet run`` against the kernel alone.

For each thread count, alternately (the order flips every round):

* **run**: ``warpratchet run --K 3 --b1 0.1 --b2 0.01 --points N --steps S --threads T --json
  --quiet``, in this process (Warp started and the kernel compiled beforehand): sampling, the
  run with its History (log-spaced rows, block gains), the progress observer, the convergence
  verdict and the report;
* **kernel**: the same sampling and one ``Ensemble.run(S, chunk_steps=S)`` with no observer
  (one launch per thread).

Both are timed from sampling to the end (wall and process CPU seconds). The ratio kernel / run of
each round is the run's throughput as a fraction of the kernel's (the target: >= 0.9); the
medians over rounds are printed with their ranges, per wall and per CPU second. The run's reported
A and Lyapunov exponent must equal the kernel-only ensemble's summary bit for bit (exit status 1
if not).

With ``--fresh`` each of them runs in a process of its own, after the same compile-or-load of the
kernel: a user's first run, whose first history row loads the row kernels and whose buffers and
copies of the state touch fresh pages, where the rounds in one process reuse them.

Usage::

    python benchmarks/end_to_end.py                      # 10^6 points x 6000 steps, 3 rounds, 1 and 2 threads
    python benchmarks/end_to_end.py --rounds 5 --json
    python benchmarks/end_to_end.py --fresh              # each run and kernel in a process of its own
    python benchmarks/end_to_end.py --quick --json       # smoke test: 20 000 points x 600 steps
    python benchmarks/end_to_end.py --device cuda:0      # on a GPU (one launch per chunk, no threads)
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import statistics
import sys

import warp as wp
from throughput_contenders import Clock, Timing, child_json

from warpratchet import Ensemble, MapParams
from warpratchet.cli import main as cli_main
from warpratchet.cli import positive_int
from warpratchet.ensemble import default_threads

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
INIT, SEED = "strip", 0  # the CLI's defaults


def run_cli(
    params: MapParams, points: int, steps: int, threads: int, device: str = "cpu"
) -> tuple[dict, Timing]:
    """``warpratchet run ... --json --quiet`` in this process: its report and its wall and CPU seconds."""
    argv = ["run", "--K", repr(params.K), "--b1", repr(params.b1), "--b2", repr(params.b2)]
    argv += ["--points", str(points), "--steps", str(steps), "--threads", str(threads)]
    argv += ["--device", device, "--json", "--quiet"]
    out = io.StringIO()
    with Clock() as clock, contextlib.redirect_stdout(out):
        status = cli_main(argv)
    if status not in (0, None):
        raise SystemExit(f"warpratchet run exited with {status}")
    return json.loads(out.getvalue()), clock.timing


def kernel_alone(points: int, steps: int, threads: int, device: str = "cpu") -> tuple[Ensemble, Timing]:
    """The run's ensemble (the CLI's sampling) advanced in one chunk, no observers: the ensemble
    and its wall and CPU seconds, sampling included."""
    with Clock() as clock:
        ens = Ensemble.sample(PARAMS, points, init=INIT, seed=SEED, threads=threads, device=device)
        ens.run(steps, chunk_steps=steps)
        wp.synchronize_device(device)
    return ens, clock.timing


def load_kernel(device: str) -> None:
    """Compile (or load) the kernel, outside the timings."""
    Ensemble.sample(PARAMS, 64, threads=1, device=device).run(16)


def measured(what: str, points: int, steps: int, threads: int, device: str) -> tuple[Timing, tuple]:
    """``what`` (``"run"`` or ``"kernel"``) in this process: its timing, and its A and Lyapunov
    exponent (the report's, or the kernel-only ensemble's summary)."""
    if what == "run":
        report, timing = run_cli(PARAMS, points, steps, threads, device)
        return timing, (report["A"], report["lyapunov"])
    ens, timing = kernel_alone(points, steps, threads, device)
    summary = ens.summary(warn=False)
    return timing, (summary.A, summary.lyapunov)


def measured_fresh(what: str, points: int, steps: int, threads: int, device: str) -> tuple[Timing, tuple]:
    """:func:`measured` in a process of its own (this script with the hidden ``--child``)."""
    args = ["--child", what, "--points", str(points), "--steps", str(steps)]
    measurement = child_json("end_to_end.py", [*args, "--threads", str(threads), "--device", device])
    if isinstance(measurement, str):
        raise SystemExit(f"end_to_end.py --child {what} failed: {measurement}")
    seconds, cpu_seconds, numbers = measurement
    return Timing(seconds, cpu_seconds), tuple(numbers)


def spread_text(d: dict[str, float]) -> str:
    """A :func:`median_range` as ``median [min, max]``."""
    return f"{d['median']:.3f} [{d['min']:.2f}, {d['max']:.2f}]"


def median_range(values: list[float]) -> dict[str, float]:
    """The median and range of ``values``."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def job_parser(prog: str, description: str, rounds: int) -> argparse.ArgumentParser:
    """The job's options (``--points``, ``--steps``, ``--rounds``, ``--quick``, ``--json``), which
    :func:`job_size` reads; ``rounds``: the default number of rounds."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--points", type=positive_int, default=None, help="ensemble size (default 10^6)")
    parser.add_argument("--steps", type=positive_int, default=None, help="iterations (default 6000)")
    parser.add_argument("--rounds", type=positive_int, default=rounds, help=f"rounds (default {rounds})")
    parser.add_argument("--quick", action="store_true", help="20 000 points x 600 steps, 1 round")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    return parser


def job_size(args: argparse.Namespace) -> tuple[int, int, int]:
    """``(points, steps, rounds)`` from :func:`job_parser`'s options."""
    points = args.points or (20_000 if args.quick else 1_000_000)
    steps = args.steps or (600 if args.quick else 6000)
    return points, steps, 1 if args.quick else args.rounds


def main(argv: list[str] | None = None) -> int:
    parser = job_parser("end_to_end.py", __doc__.splitlines()[0], rounds=3)
    parser.add_argument("--device", default="cpu", help="Warp device, e.g. cuda:0 (default cpu)")
    parser.add_argument("--fresh", action="store_true", help="each run and kernel in a process of its own")
    parser.add_argument("--child", choices=("run", "kernel"), help=argparse.SUPPRESS)
    parser.add_argument("--threads", type=positive_int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    points, steps, rounds = job_size(args)
    try:
        load_kernel(args.device)
    except ValueError as error:  # e.g. device = 'cuda:7' is not available (Warp sees: cpu)
        parser.error(str(error))
    if args.child:  # one measurement for a --fresh parent
        timing, numbers = measured(args.child, points, steps, args.threads, args.device)
        print(json.dumps([timing.seconds, timing.cpu_seconds, numbers]))
        return 0
    measure = measured_fresh if args.fresh else measured
    on_cpu = wp.get_device(args.device).is_cpu
    results, equal = [], True
    for threads in sorted({1, default_threads()}) if on_cpu else [1]:
        wall, cpu = [], []
        for r in range(rounds):
            order = ("run", "kernel") if r % 2 == 0 else ("kernel", "run")
            timing, numbers = {}, {}
            for what in order:
                print(f"{threads} thread(s), round {r + 1}: {what}", file=sys.stderr, flush=True)
                timing[what], numbers[what] = measure(what, points, steps, threads, args.device)
            equal &= numbers["run"] == numbers["kernel"]
            wall.append(timing["kernel"].seconds / timing["run"].seconds)
            cpu.append(timing["kernel"].cpu_seconds / timing["run"].cpu_seconds)
        results.append(
            {
                "threads": threads,
                "run_over_kernel_wall": median_range(wall),
                "run_over_kernel_cpu": median_range(cpu),
                "kernel_point_steps_per_second": points * steps / timing["kernel"].seconds,
                "run_point_steps_per_second": points * steps / timing["run"].seconds,
                "kernel_cpu_use": timing["kernel"].cpu_seconds / (timing["kernel"].seconds * threads),
                "run_cpu_use": timing["run"].cpu_seconds / (timing["run"].seconds * threads),
            }
        )
    report = {"points": points, "steps": steps, "rounds": rounds, "device": args.device, "fresh": args.fresh}
    report |= {"results": results, "bitwise_equal": equal}
    if args.json:
        print(json.dumps(report))
    else:
        print(
            f"warpratchet run / kernel alone, {points:,} points x {steps:,} steps, {rounds} rounds"
            f" on {args.device}{', each in a fresh process' if args.fresh else ''}"
        )
        head = f"{'threads':>7}  {'wall: median [range]':<24}{'CPU: median [range]':<24}"
        print(head + f"{'CPU use (kernel, run)':>22}")
        for row in results:
            spreads = [spread_text(row[key]) for key in ("run_over_kernel_wall", "run_over_kernel_cpu")]
            uses = f"{row['kernel_cpu_use']:>10.2f}{row['run_cpu_use']:>8.2f}"
            print(f"{row['threads']:>7}  " + "".join(f"{s:<24}" for s in spreads) + uses)
        same = "yes" if equal else "NO"
        print(f"reported A and Lyapunov exponent equal to the kernel-only ensemble's: {same}")
    return 0 if equal else 1


if __name__ == "__main__":
    sys.exit(main())
