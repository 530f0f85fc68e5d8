"""Whether two threads here share one core's floating-point pipes: an FMA-bound loop on 1 and 2 threads.

A kernel whose step loop fills the pipes (``benchmarks/README.md``, "Roofline") scales from one
thread to two only if the two threads run on separate cores. Inside a virtual machine the guest
cannot see that (``lscpu`` reports what the hypervisor says); this measures it. Each thread runs
``c/fma_bound.c``: independent chains of 4-wide fused multiply-adds, bound by the FMA pipes. Its
rate per second of its own CPU time is the core's FMA throughput where the thread has the core,
about half where another thread shares its pipes. The script times 1 thread, then 2, alternately,
``--rounds`` times, and prints each thread's rate and the ratio of the 2-thread rates to the
1-thread rate of the same round (about 1: separate pipes; about 0.5: shared).

Usage::

    python benchmarks/core_sharing.py            # 5 rounds of ~0.5 s per thread count
    python benchmarks/core_sharing.py --json
    python benchmarks/core_sharing.py --quick --json   # smoke test

Needs gcc and an x86-64 CPU with AVX2 and FMA; exits 2 with the reason otherwise.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parent / "c" / "fma_bound.c"
ITERATIONS = 200_000_000  # ~0.5 s of one thread at ~5 G vector FMAs a second (10 chains)


def unavailable() -> str | None:
    """Why the probe cannot run here, or None."""
    if shutil.which("gcc") is None or platform.machine() not in ("x86_64", "AMD64"):
        return "needs gcc and an x86-64 CPU"
    cpuinfo = Path("/proc/cpuinfo")
    flags = cpuinfo.read_text().split() if cpuinfo.exists() else []
    if "avx2" not in flags or "fma" not in flags:
        return "needs a CPU with AVX2 and FMA (/proc/cpuinfo)"
    return None


def build(folder: Path) -> ctypes.CDLL:
    """``c/fma_bound.c`` compiled into ``folder`` and loaded."""
    library = folder / "fma_bound.so"
    command = [
        "gcc",
        "-O2",
        "-mavx2",
        "-mfma",
        "-fopenmp",
        "-fPIC",
        "-shared",
        str(SOURCE),
        "-o",
        str(library),
    ]
    subprocess.run(command, check=True, capture_output=True)
    lib = ctypes.CDLL(str(library))
    lib.fma_rates.argtypes = [ctypes.c_long, ctypes.c_int, ctypes.POINTER(ctypes.c_double)]
    lib.fma_rates.restype = ctypes.c_double
    return lib


def rates(lib: ctypes.CDLL, iterations: int, threads: int) -> list[float]:
    """Each thread's vector FMAs per second of its own CPU time."""
    out = (ctypes.c_double * threads)()
    lib.fma_rates(iterations, threads, out)
    return list(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="core_sharing.py", description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=None, help="rounds (default 5)")
    parser.add_argument("--quick", action="store_true", help="2 rounds of a few milliseconds")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    rounds = args.rounds if args.rounds is not None else (2 if args.quick else 5)
    if rounds < 1:
        print(f"core_sharing.py: error: --rounds = {rounds}: must be at least 1", file=sys.stderr)
        return 2
    reason = unavailable()
    if reason:
        print(f"core_sharing.py: error: {reason}", file=sys.stderr)
        return 2
    iterations = ITERATIONS // 100 if args.quick else ITERATIONS
    one, two, ratios = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        lib = build(Path(tmp))
        for _ in range(rounds):
            single = rates(lib, iterations, 1)[0]
            pair = rates(lib, iterations, 2)
            if min(pair) <= 0.0:  # a rate left unwritten: OpenMP gave the pair one thread
                print(
                    "core_sharing.py: error: OpenMP ran fewer than 2 threads (OMP_THREAD_LIMIT?)",
                    file=sys.stderr,
                )
                return 2
            one.append(single)
            two.append(pair)
            ratios.append([rate / single for rate in pair])
    report = {
        "rounds": rounds,
        "one_thread": one,
        "two_threads": two,
        "two_over_one": ratios,
        "median_two_over_one": statistics.median(r for pair in ratios for r in pair),
    }
    if args.json:
        print(json.dumps(report))
        return 0
    print("vector FMAs per second of each thread's CPU time (G):")
    for single, pair, ratio in zip(one, two, ratios, strict=True):
        shown = ", ".join(f"{r / 1e9:.2f}" for r in pair)
        print(
            f"  1 thread {single / 1e9:.2f}   2 threads {shown}   2/1: {', '.join(f'{r:.2f}' for r in ratio)}"
        )
    verdict = "separate pipes" if report["median_two_over_one"] > 0.75 else "shared pipes"
    print(f"median 2/1 {report['median_two_over_one']:.2f}: {verdict} (about 1: separate; about 0.5: shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
