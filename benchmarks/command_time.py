"""What the ``warpratchet`` command costs a user around its work: start, import and exit.

Runs a command line in fresh processes, ``--rounds`` times each way, the ways alternated:

* **console**: as the ``warpratchet`` command runs it (``warpratchet.cli.console_main``: the
  command, then every object frozen out of the cycle collector before the interpreter ends);
* **main**: ``sys.exit(warpratchet.cli.main(argv))``, the command alone, then the interpreter's
  ordinary teardown.

Each process notes the system's monotonic clock when its script starts, after
``import warpratchet.cli`` and after the command; this process notes it before starting the child
and after it has exited. So a round splits into **start** (the interpreter's own start-up),
**import**, **command** (the command's work: sampling, Warp's start and kernel load, the run, the
report) and **exit** (from the command's return to the end of the process). Medians and ranges are
printed per way.

Usage::

    python benchmarks/command_time.py              # the README's main job, 5 rounds
    python benchmarks/command_time.py --rounds 9 -- run --K 3 --b1 0.1 --b2 0.01 --points 1000000 --steps 6000
    python benchmarks/command_time.py --quick --json   # smoke test
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

from end_to_end import median_range, spread_text

from warpratchet.cli import positive_int

MAP = ("--K", "3", "--b1", "0.1", "--b2", "0.01")
#: The README's main job, and the smoke test's.
MAIN_JOB = ("run", *MAP, "--points", "10000", "--steps", "120000", "--quiet")
QUICK_JOB = ("run", *MAP, "--points", "2000", "--steps", "600", "--quiet")
WAYS = ("console", "main")
PARTS = ("start", "import", "command", "exit", "total")


def child_source(way: str) -> str:
    """The child's script for ``way``: the command as :data:`WAYS` says, its clock readings on stderr."""
    run = "cli.console_main()" if way == "console" else "cli.main()"
    return (
        "import json, sys, time\n"
        "begun = time.monotonic()\n"
        "import warpratchet.cli as cli\n"
        "imported = time.monotonic()\n"
        f"status = {run}\n"
        "done = time.monotonic()\n"
        "print(json.dumps([begun, imported, done]), file=sys.stderr)\n"
        "sys.exit(status)\n"
    )


def one_round(way: str, argv: list[str]) -> dict[str, float]:
    """Seconds of each of :data:`PARTS` for one fresh process of ``way``."""
    start = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", child_source(way), *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    end = time.monotonic()
    if done.returncode != 0:
        raise SystemExit(f"warpratchet {' '.join(argv)} exited with {done.returncode}: {done.stderr.strip()}")
    begun, imported, returned = json.loads(done.stderr.strip().splitlines()[-1])
    return {
        "start": begun - start,
        "import": imported - begun,
        "command": returned - imported,
        "exit": end - returned,
        "total": end - start,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="command_time.py", description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=positive_int, default=5, help="processes per way (default 5)")
    parser.add_argument("--quick", action="store_true", help="a small job, 1 round (smoke test)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("command", nargs="*", help="the command line after --, default the README's main job")
    args = parser.parse_args(argv)
    job = list(args.command) or list(QUICK_JOB if args.quick else MAIN_JOB)
    rounds = 1 if args.quick else args.rounds
    seconds: dict[str, dict[str, list[float]]] = {way: {part: [] for part in PARTS} for way in WAYS}
    for r in range(rounds):
        for way in WAYS if r % 2 == 0 else WAYS[::-1]:
            for part, value in one_round(way, job).items():
                seconds[way][part].append(value)
    spread = {way: {part: median_range(values) for part, values in seconds[way].items()} for way in WAYS}
    report = {"command": ["warpratchet", *job], "rounds": rounds, "seconds": spread}
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"{' '.join(report['command'])}, {rounds} fresh processes a way, alternated")
    print("seconds: median [range]")
    print(f"{'way':8s}" + "".join(f"{part:>22s}" for part in PARTS))
    for way in WAYS:
        print(f"{way:8s}" + "".join(f"{spread_text(report['seconds'][way][part]):>22s}" for part in PARTS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
