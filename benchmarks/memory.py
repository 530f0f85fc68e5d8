"""Peak resident memory of a run against the size of its state.

The state is 56 bytes per point (x, q, winding, p0, dx, dp, log_stretch). For each ensemble
size, three child processes are measured, each on its own (``os.wait4`` gives the peak resident
set, ``ru_maxrss``, of that one child):

* ``baseline``: Python importing warpratchet and starting Warp, the fixed cost of any run;
* ``api``: ``Ensemble.sample(...)`` and ``Ensemble.run(steps)``, what the ensemble layer costs;
* ``cli``: ``warpratchet run --points N --steps S --quiet --json``, the whole command
  (ensemble, run, and the summary of A and the FTLE that it prints).

Reported per size: each peak, ``peak / state`` and ``(peak - baseline) / state``, and whether the
peak is within ``1.3 x state + 300 MiB`` (the bound: 1.3 times the state plus a fixed few
hundred MB). A few steps suffice: memory does not grow with the steps.

Usage::

    python benchmarks/memory.py                       # 10^6, 10^7 and 10^8 points (~6 GiB, a minute)
    python benchmarks/memory.py --points 1000000 --json
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from typing import Any, NoReturn

from warpratchet.cli import positive_int

#: Six float64 fields and one int64 (``warpratchet.ensemble.STATE_FIELDS``).
BYTES_PER_POINT = 56
RATIO_BOUND, FIXED_MIB = 1.3, 300
MIB = 2**20
PARAMS = ("--K", "3", "--b1", "0.1", "--b2", "0.01")

_BASELINE = "import warpratchet, warpratchet.cli; from warpratchet import kernels; kernels.init_warp()"
_API = (
    "import sys; from warpratchet import Ensemble, MapParams; "
    "Ensemble.sample(MapParams(3.0, 0.1, 0.01), int(sys.argv[1]), 'strip', seed=1).run(int(sys.argv[2]))"
)


def peak_rss(command: list[str]) -> int:
    """Peak resident set of one child process, in bytes (it must exit 0)."""
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    stderr = child.stderr.read().decode(errors="replace") if child.stderr else ""
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise RuntimeError(f"{' '.join(command[:4])} ... exited {child.returncode}: {stderr.strip()[-500:]}")
    return usage.ru_maxrss * 1024  # kilobytes on Linux


def measure(points: int, steps: int) -> dict[str, Any]:
    state = BYTES_PER_POINT * points
    python = sys.executable
    peaks = {
        "baseline": peak_rss([python, "-c", _BASELINE]),
        "api": peak_rss([python, "-c", _API, str(points), str(steps)]),
        "cli": peak_rss(
            [python, "-m", "warpratchet", "run", *PARAMS, "--points", str(points), "--steps", str(steps)]
            + ["--quiet", "--json"]
        ),
    }
    bound = RATIO_BOUND * state + FIXED_MIB * MIB
    return {
        "points": points,
        "steps": steps,
        "state_bytes": state,
        "bound_bytes": bound,
        "peak_bytes": peaks,
        "peak_over_state": {k: v / state for k, v in peaks.items()},
        "above_baseline_over_state": {
            k: (v - peaks["baseline"]) / state for k, v in peaks.items() if k != "baseline"
        },
        "within_bound": {k: v <= bound for k, v in peaks.items() if k != "baseline"},
    }


def print_table(rows: list[dict[str, Any]]) -> None:
    print(
        f"Peak resident memory (ru_maxrss of one child each); state = {BYTES_PER_POINT} B/point; "
        f"bound = {RATIO_BOUND} x state + {FIXED_MIB} MiB"
    )
    head = (
        f"{'points':>12}{'state MiB':>11}{'what':>10}{'peak MiB':>10}{'peak/state':>12}"
        f"{'(peak-base)/state':>19}  within bound"
    )
    print(head)
    print("-" * len(head))
    for row in rows:
        for what in ("baseline", "api", "cli"):
            peak = row["peak_bytes"][what]
            extra = row["above_baseline_over_state"].get(what)
            within = row["within_bound"].get(what)
            print(
                f"{row['points']:>12,}{row['state_bytes'] / MIB:>11.0f}{what:>10}{peak / MIB:>10.0f}"
                f"{row['peak_over_state'][what]:>12.2f}{'-' if extra is None else f'{extra:.2f}':>19}  "
                f"{'-' if within is None else ('yes' if within else 'no')}"
            )


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line on stderr, exit 2
        print(f"{self.prog}: {message}", file=sys.stderr)
        sys.exit(2)


def main(argv: list[str] | None = None) -> int:
    parser = _Parser(prog="memory.py", description="Peak resident memory of runs against their state size.")
    parser.add_argument("--points", type=positive_int, nargs="+", default=[10**6, 10**7, 10**8])
    parser.add_argument("--steps", type=positive_int, default=16, help="steps per run (default 16)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    rows = []
    for points in args.points:
        print(f"measuring {points:,} points ...", file=sys.stderr, flush=True)
        rows.append(measure(points, args.steps))
    if args.json:
        print(json.dumps({"benchmark": "memory", "results": rows}))
    else:
        print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
