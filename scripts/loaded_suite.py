"""Run the tests that start processes or send signals on a busy machine, several times.

Beside each run, two busy processes per core spin (pure Python loops), so the tests see the
load of a shared CI machine. Each run is one ``pytest`` process; the script prints one line per
run and a last line with the pass count, and exits 1 if any run failed.

Usage::

    .venv/bin/python scripts/loaded_suite.py --runs 10
    .venv/bin/python scripts/loaded_suite.py --runs 3 -- tests/run/test_interrupt.py -k sigterm
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

#: The tests that start processes or send signals (the ones a loaded machine breaks first).
DEFAULT_TESTS = [
    "tests/run/test_interrupt.py",
    "tests/run/test_checkpoint_cadence.py",
    "tests/cli/test_hangs_and_refusals.py",
]
ROOT = Path(__file__).resolve().parents[1]


def _busy(count: int) -> list[subprocess.Popen]:
    # Each spins until its parent (this script) is gone, however the script ends.
    spin = "import os\nparent = os.getppid()\nwhile os.getppid() == parent:\n    pass"
    return [subprocess.Popen([sys.executable, "-c", spin]) for _ in range(count)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10, help="pytest runs (default 10)")
    parser.add_argument("--per-core", type=int, default=2, help="busy processes per core (default 2)")
    parser.add_argument("--timeout", type=float, default=3600, help="seconds a run may take (default 3600)")
    parser.add_argument("pytest_args", nargs="*", help="what pytest runs (default: the process/signal tests)")
    args = parser.parse_args(argv)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    spinners = _busy(args.per_core * cores)
    passed = 0
    try:
        for run in range(1, args.runs + 1):
            start = time.monotonic()
            load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
            command += args.pytest_args or DEFAULT_TESTS
            try:
                proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=args.timeout)
            except subprocess.TimeoutExpired as exc:  # a hang: the run fails, naming the command
                proc = subprocess.CompletedProcess(
                    command, 1, f"{' '.join(command)}: no end within {exc.timeout:.0f} s", ""
                )
            summary = (proc.stdout.strip().splitlines() or ["(no output)"])[-1]
            ok = proc.returncode == 0
            passed += ok
            print(
                f"run {run}: {'pass' if ok else 'FAIL'} ({summary}; load {load:.1f} at start, "
                f"{len(spinners)} busy processes on {cores} cores, {time.monotonic() - start:.0f} s)",
                flush=True,
            )
            if not ok:
                print(proc.stdout[-4000:], proc.stderr[-2000:], sep="\n", flush=True)
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    print(f"{passed} of {args.runs} runs passed")
    return 0 if passed == args.runs else 1


if __name__ == "__main__":
    sys.exit(main())
