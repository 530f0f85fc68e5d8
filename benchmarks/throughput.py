"""Throughput of warpratchet against NumPy, Numba and plain C on the same float64 arithmetic.

Every contender advances the same ensemble, 10^6 points uniform in the strip B of Eq. (B) at
K = 3, b1 = 0.1, b2 = 0.01 (seed 1) and then advanced by warpratchet for ``WARMUP_STEPS``
iterations (so that the tangents of chaotic points are large and get renormalised during every
measurement, as in a long run), by the map of Eq. (cpem) with the force of Eq. (fx)
(coefficients of Eq. (mmc)) *and* the tangent vector under DM, with the renormalisation rule of
:mod:`warpratchet.kernels` (a tangent with ``|dx| > RENORM_THRESHOLD`` is normalised after every
global step that is a multiple of ``RENORM_CHECK_EVERY``). The arithmetic is the same operation
by operation, so every contender's end state must equal warpratchet's bit for bit; the script
checks that for every measurement (against a Warp run advanced to the same step) and exits
with status 1 if any differs.

Contenders (rows):

* NumPy: :func:`warpratchet.reference.advance`, vectorised over points, a Python loop over
  steps; one thread.
* Numba: an ``@njit(parallel=True)`` twin (``prange`` over points, steps inside), 1 and all threads.
* C OpenMP: ``benchmarks/c/ratchet_map.c`` (OpenMP over points, steps inside), compiled here
  with the system gcc into a temporary directory and called through ctypes; 1 and all threads.
* warpratchet: :meth:`warpratchet.Ensemble.run`, 1 and all threads, after a warm-up launch
  (first-compile time excluded).

By default each measurement's step count is chosen from a short probe so that it takes about
``--seconds`` (3 s); the unit is point-steps per second, ``points * steps / seconds``, with
the best of ``--repeat`` timings (default 1). The ratios are between rows measured in the same
run, so they survive a busy machine better than the absolute rates.

Usage::

    python benchmarks/throughput.py                  # the table (about a minute on 2 cores)
    python benchmarks/throughput.py --json           # one JSON object on stdout
    python benchmarks/throughput.py --quick --json   # 20 000 points x 1000 steps (smoke test)
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from warpratchet import Ensemble, MapParams, reference
from warpratchet.cli import positive_int
from warpratchet.ensemble import (
    INTERLEAVE,
    RENORM_CHECK_EVERY,
    RENORM_THRESHOLD,
    STATE_FIELDS,
    default_threads,
)

#: The benchmark problem: the README's example (domain "LR" of Eq. (Aa)), strip ensemble.
PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
INIT, SEED = "strip", 1
#: State fields a run changes (p0 is read only), compared bit for bit.
EVOLVED = ("x", "q", "winding", "dx", "dp", "log_stretch")
#: Issue 2: at least this many point-steps/s for warpratchet on all cores of the 2-core machine.
TARGET_RATE = 600e6
#: Issue 2: at most this many bytes of state per point, and 10^8 points must fit in this memory.
STATE_BYTES_LIMIT = 80
MEMORY_GIB = 24.0
QUICK_POINTS, QUICK_STEPS = 20_000, 1000
#: Iterations before the measured ones (a multiple of RENORM_CHECK_EVERY). The FTLE is ~0.35 per
#: step here, so a tangent first passes RENORM_THRESHOLD = e^230 after ~660 steps: by step 1024, 98%
#: of the points have been renormalised, and a measurement exercises that branch as a long run does.
WARMUP_STEPS = 1024
#: A probe shorter than this says too little about the rate; it is repeated with 4x the steps.
PROBE_SECONDS = 0.25

C_SOURCE = Path(__file__).resolve().parent / "c" / "ratchet_map.c"
C_FLAGS = ("-O3", "-march=native", "-fopenmp", "-ffp-contract=off")

State = dict[str, np.ndarray]
#: ``advance(state, step0, steps) -> (new_state, seconds)``: ``steps`` iterations of ``state``,
#: which is at global step ``step0``. ``state`` is never modified and only the advancing itself is
#: timed (copies in and out are not).
Advance = Callable[[State, int, int], tuple[State, float]]


@dataclass
class Contender:
    """One row of the table."""

    key: str  # "numpy", "numba", "c", "warpratchet"
    label: str
    threads: int
    advance: Advance | None  # None: unavailable
    unavailable: str = ""


@dataclass
class Measurement:
    contender: Contender
    steps: int = 0
    seconds: float = math.nan
    state: State | None = None
    mismatched: dict[str, int] | None = None
    renormalised_points: int = 0

    @property
    def measured(self) -> bool:
        return self.steps > 0

    def rate(self, points: int) -> float:
        """Point-steps per second."""
        return points * self.steps / self.seconds if self.measured else math.nan


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _copy(state: State) -> State:
    return {name: np.array(state[name], copy=True) for name in EVOLVED}


# -- NumPy ------------------------------------------------------------------------------------------
def numpy_contenders(params: MapParams) -> tuple[list[Contender], str]:
    def advance(state: State, step0: int, steps: int) -> tuple[State, float]:
        start = time.perf_counter()
        out = reference.advance(params, state, steps, step0=step0)
        return out, time.perf_counter() - start

    build = f"numpy {np.__version__}: warpratchet.reference.advance (vectorised over points, steps in Python)"
    return [Contender("numpy", "NumPy", 1, advance)], build


# -- Numba ------------------------------------------------------------------------------------------
@functools.cache
def _numba_advance() -> Callable[..., None]:
    """The Numba twin of the kernel, compiled on first use (closure constants are frozen)."""
    import numba

    threshold = RENORM_THRESHOLD
    every = RENORM_CHECK_EVERY

    # fastmath=False (the default) keeps IEEE semantics: no FMA contraction, no reassociation.
    @numba.njit(parallel=True, fastmath=False, error_model="numpy")
    def advance(x, q, winding, dx, dp, lsum, step0, steps, K, b1, right, l1, l2, c):
        for i in numba.prange(x.size):
            xi, qi, dxi, dpi, si = x[i], q[i], dx[i], dp[i], lsum[i]
            w = 0.0
            for s in range(steps):
                # Eq. (fx) and its slope
                if xi <= b1:
                    f = l1 * xi
                    slope = l1
                elif xi < right:
                    f = c - xi
                    slope = -1.0
                else:
                    f = l2 * (xi - 1.0)
                    slope = l2
                t = qi + K * f
                fl = np.floor(t)  # math.floor would return an integer
                qi = t - fl
                wrap = qi >= 1.0
                if wrap:
                    qi = 0.0
                w = w + fl + (1.0 if wrap else 0.0)
                xi = xi + qi
                if xi >= 1.0:
                    xi = xi - 1.0
                dpi = dpi + (K * slope) * dxi
                dxi = dxi + dpi
                if (step0 + s + 1) % every == 0 and abs(dxi) > threshold:
                    h = math.sqrt(dxi * dxi + dpi * dpi)
                    si = si + math.log(h)
                    dxi = dxi / h
                    dpi = dpi / h
            x[i], q[i], dx[i], dp[i], lsum[i] = xi, qi, dxi, dpi, si
            winding[i] = winding[i] + np.int64(w)

    return advance


def numba_contenders(params: MapParams, threads: list[int]) -> tuple[list[Contender], str]:
    try:
        import numba
    except ImportError:
        reason = "unavailable: numba is not installed (pip install 'warpratchet[bench]')"
        return [Contender("numba", "Numba parallel", t, None, reason) for t in threads], reason
    kernel = _numba_advance()
    threads = [min(t, numba.config.NUMBA_NUM_THREADS) for t in threads]

    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, float]:
            out = _copy(state)
            numba.set_num_threads(n_threads)
            start = time.perf_counter()
            kernel(*(out[name] for name in EVOLVED), step0, steps, *_map_args(params))
            return out, time.perf_counter() - start

        return advance

    # Compile now (on a tiny copy) so that no measurement includes the JIT.
    tiny = {name: np.zeros(16, dtype=np.int64 if name == "winding" else np.float64) for name in EVOLVED}
    tiny["dx"][:] = 1.0
    make(1)(tiny, 0, 16)
    build = (
        f"numba {numba.__version__}: @njit(parallel=True, fastmath=False), prange over points, "
        f"threading layer {numba.threading_layer()}"
    )
    return [Contender("numba", "Numba parallel", t, make(t)) for t in threads], build


# -- plain C ----------------------------------------------------------------------------------------
def _build_c(workdir: Path) -> tuple[ctypes.CDLL | None, str]:
    """Compile ``c/ratchet_map.c`` into ``workdir``; ``(library, build)`` or ``(None, reason)``."""
    gcc = shutil.which("gcc")
    if gcc is None:
        return None, "unavailable: gcc not found on PATH"
    gcc_version = subprocess.run([gcc, "-dumpfullversion"], capture_output=True, text=True).stdout.strip()
    defines = (f"-DRENORM_THRESHOLD={RENORM_THRESHOLD!r}", f"-DRENORM_CHECK_EVERY={RENORM_CHECK_EVERY}")
    library = workdir / "ratchet_map.so"
    command = [gcc, *C_FLAGS, "-fPIC", "-shared", *defines, "-o", str(library), str(C_SOURCE), "-lm"]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        first = (done.stderr.strip().splitlines() or ["(no output)"])[0]
        return None, f"unavailable: gcc failed: {first}"
    lib = ctypes.CDLL(str(library))
    f64 = np.ctypeslib.ndpointer(dtype=np.float64, ndim=1, flags="C_CONTIGUOUS")
    i64 = np.ctypeslib.ndpointer(dtype=np.int64, ndim=1, flags="C_CONTIGUOUS")
    lib.advance_map.restype = None
    lib.advance_map.argtypes = [
        *[ctypes.c_int64] * 3,
        *[ctypes.c_double] * 6,
        f64,
        f64,
        i64,
        f64,
        f64,
        f64,
        ctypes.c_int,
    ]
    return lib, f"gcc {gcc_version}: {' '.join(C_FLAGS)}, OpenMP over points, called via ctypes"


def c_contenders(params: MapParams, threads: list[int], workdir: Path) -> tuple[list[Contender], str]:
    lib, build = _build_c(workdir)
    if lib is None:
        return [Contender("c", "C OpenMP", t, None, build) for t in threads], build

    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, float]:
            out = _copy(state)
            n = out["x"].size
            start = time.perf_counter()
            lib.advance_map(n, step0, steps, *_map_args(params), *(out[name] for name in EVOLVED), n_threads)
            return out, time.perf_counter() - start

        return advance

    return [Contender("c", "C OpenMP", t, make(t)) for t in threads], build


# -- warpratchet ------------------------------------------------------------------------------------
def warp_contenders(params: MapParams, threads: list[int]) -> tuple[list[Contender], str]:
    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, float]:
            ens = Ensemble.from_state(params, state, step0, threads=n_threads)
            start = time.perf_counter()
            ens.run(steps)
            seconds = time.perf_counter() - start
            out = ens.state()
            return {name: out[name] for name in EVOLVED}, seconds

        return advance

    # Warm-up: compiles the kernel (or loads it from Warp's cache) outside every measurement.
    Ensemble.sample(params, 64, init=INIT, seed=SEED, threads=1).run(16)
    build = (
        f"warp {version('warp-lang')} CPU: Ensemble.run, {INTERLEAVE} points per Warp thread, "
        "one Warp launch per Python thread"
    )
    return [Contender("warpratchet", "warpratchet", t, make(t)) for t in threads], build


def _map_args(params: MapParams) -> tuple[float, ...]:
    """The kernel's scalar arguments ``K, b1, right = 1 - b2, l1, l2, c`` (Eqs. fx, mmc)."""
    return (params.K, params.b1, 1.0 - params.b2, params.l1, params.l2, params.c)


# -- measuring --------------------------------------------------------------------------------------
def _two_digits(x: float) -> int:
    return int(float(f"{x:.2g}"))


def calibrate(advance: Advance, init: State, step0: int, seconds: float) -> int:
    """Steps that take about ``seconds``, from probes of 8, 32, 128, ... steps."""
    steps = 8
    while True:
        _, took = advance(init, step0, steps)
        if took >= PROBE_SECONDS or steps >= 1 << 24:
            break
        steps *= 4
    return max(8, _two_digits(seconds * steps / took))


def verify(measurements: list[Measurement], init: State, step0: int, params: MapParams, threads: int) -> None:
    """Compare every end state, bit for bit, with a Warp ensemble advanced to the same step.

    The reference ensemble is advanced through the distinct step counts in increasing order;
    warpratchet's results do not depend on how a run is chunked, so its state after each stop
    is the state a single run of that many steps would give. Also counts the points whose
    tangent was renormalised during the measured steps (so the check covered that branch).
    """
    ref = Ensemble.from_state(params, init, step0, threads=threads)
    for m in sorted((m for m in measurements if m.measured), key=lambda m: m.steps):
        ref.run(step0 + m.steps - ref.step)
        mismatched = {}
        for name in EVOLVED:
            mine = np.ascontiguousarray(m.state[name]).view(np.int64)
            theirs = ref.array(name).view(np.int64)  # bits, so -0.0 and NaN payloads count too
            count = int(np.count_nonzero(mine != theirs))
            if count:
                mismatched[name] = count
        m.mismatched = mismatched
        m.renormalised_points = int(np.count_nonzero(ref.array("log_stretch") != init["log_stretch"]))
        m.state = None  # free the memory


# -- report -----------------------------------------------------------------------------------------
def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def build_report(
    measurements: list[Measurement],
    points: int,
    builds: dict[str, str],
    bytes_per_point: int,
    quick: bool,
    repeat: int,
    load_average: tuple[float, float, float],
) -> dict[str, Any]:
    """The JSON object of ``--json`` (rates in point-steps per second)."""
    by_key = {(m.contender.key, m.contender.threads): m for m in measurements}
    numpy_rate = by_key[("numpy", 1)].rate(points)
    warp_all = max(
        (m for m in measurements if m.contender.key == "warpratchet"), key=lambda m: m.contender.threads
    )
    warp_rate = warp_all.rate(points)
    rows = []
    for m in measurements:
        c = m.contender
        measured = m.measured
        rate = m.rate(points)
        rows.append(
            {
                "implementation": c.key,
                "label": c.label,
                "threads": c.threads,
                "status": "ok" if measured else c.unavailable,
                "steps": m.steps if measured else None,
                "seconds": m.seconds if measured else None,
                "point_steps_per_second": rate if measured else None,
                "vs_numpy": rate / numpy_rate if measured else None,
                "vs_warpratchet": rate / warp_rate if measured else None,
                "bitwise_equal_to_warpratchet": (not m.mismatched) if measured else None,
                "mismatched_points": m.mismatched if measured else None,
                "renormalised_points": m.renormalised_points if measured else None,
            }
        )
    gib_1e8 = 1e8 * bytes_per_point / 2**30
    return {
        "benchmark": "throughput",
        "problem": {
            "K": PARAMS.K,
            "b1": PARAMS.b1,
            "b2": PARAMS.b2,
            "init": INIT,
            "seed": SEED,
            "points": points,
            "quick": quick,
            "repeat": repeat,
            "warmup_steps": WARMUP_STEPS,
            "renorm_threshold": RENORM_THRESHOLD,
            "renorm_check_every": RENORM_CHECK_EVERY,
        },
        "machine": {
            "cpu": _cpu_name(),
            "cores": default_threads(),
            "load_average_at_start": list(load_average),
            "python": platform.python_version(),
        },
        "builds": builds,
        "results": rows,
        "all_bitwise_equal": all(not m.mismatched for m in measurements if m.measured),
        "warpratchet_threads": warp_all.contender.threads,
        "warpratchet_point_steps_per_second": warp_rate,
        "target_point_steps_per_second": TARGET_RATE,
        "target_met": bool(warp_rate >= TARGET_RATE),
        "state_bytes_per_point": bytes_per_point,
        "state_bytes_limit": STATE_BYTES_LIMIT,
        "state_gib_at_1e8_points": gib_1e8,
        "fits_1e8_points_in_gib": MEMORY_GIB,
        "fits_1e8_points": bool(bytes_per_point <= STATE_BYTES_LIMIT and gib_1e8 <= MEMORY_GIB),
    }


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def print_table(report: dict[str, Any]) -> None:
    prob, mach = report["problem"], report["machine"]
    print(
        f"Throughput, float64 map (Eq. cpem) + tangent: {prob['points']:,} points, K={prob['K']:g} "
        f"b1={prob['b1']:g} b2={prob['b2']:g}, {prob['init']} ensemble (seed {prob['seed']}) after "
        f"{prob['warmup_steps']} steps"
    )
    load = ", ".join(f"{x:.2f}" for x in mach["load_average_at_start"])
    print(f"Machine: {mach['cpu']}, {mach['cores']} cores, load average at start {load}")
    if prob["repeat"] > 1:
        print(f"Seconds: best of {prob['repeat']} runs per row")
    print()
    head = (
        f"{'implementation':<16}{'threads':>7}{'steps':>8}{'seconds':>9}{'M pt-steps/s':>14}"
        f"{'x NumPy':>9}{'x warpratchet':>15}  bitwise = warpratchet"
    )
    print(head)
    print("-" * len(head))
    for row in report["results"]:
        if row["status"] != "ok":
            print(f"{row['label']:<16}{row['threads']:>7}  {row['status']}")
            continue
        rate = row["point_steps_per_second"] / 1e6
        same = "yes" if row["bitwise_equal_to_warpratchet"] else f"NO {row['mismatched_points']}"
        print(
            f"{row['label']:<16}{row['threads']:>7}{row['steps']:>8}{row['seconds']:>9.2f}{rate:>14.1f}"
            f"{_fmt(row['vs_numpy'], '.2f'):>9}{_fmt(row['vs_warpratchet'], '.3f'):>15}  {same}"
        )
    print()
    print("Builds:")
    for key, build in report["builds"].items():
        print(f"  {key:<12} {build}")
    print()
    met = "met" if report["target_met"] else "NOT met"
    print(
        f"Target: warpratchet >= {report['target_point_steps_per_second'] / 1e6:.0f} M point-steps/s on "
        f"{report['warpratchet_threads']} threads: {met} "
        f"({report['warpratchet_point_steps_per_second'] / 1e6:.0f} M/s)"
    )
    fits = "fits" if report["fits_1e8_points"] else "does NOT fit"
    print(
        f"State: {report['state_bytes_per_point']} bytes per point (limit {report['state_bytes_limit']}); "
        f"10^8 points = {report['state_gib_at_1e8_points']:.2f} GiB, {fits} in "
        f"{report['fits_1e8_points_in_gib']:g} GiB"
    )
    renorm = [r["renormalised_points"] for r in report["results"] if r["status"] == "ok"]
    print(
        f"Bitwise check against a Warp run to the same step: "
        f"{'all equal' if report['all_bitwise_equal'] else 'SOME DIFFER'}; tangents renormalised "
        f"in {min(renorm):,} to {max(renorm):,} of {prob['points']:,} points"
    )


# -- command line -----------------------------------------------------------------------------------
def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number: {text!r}") from None
    if not 0.0 < value <= 600.0:
        raise argparse.ArgumentTypeError(f"{value} is outside the allowed range 0 < seconds <= 600")
    return value


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line on stderr, exit 2 (no usage block)
        print(f"{self.prog}: {message}", file=sys.stderr)
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="throughput.py",
        description="Point-steps per second of warpratchet, NumPy, Numba and plain C on the same map.",
    )
    parser.add_argument("--points", type=positive_int, help="ensemble size (default 10^6; --quick: 20000)")
    parser.add_argument(
        "--steps",
        type=positive_int,
        help="steps for every row (default: chosen per row to take --seconds; --quick: 1000)",
    )
    parser.add_argument(
        "--seconds", type=_positive_seconds, default=3.0, help="target seconds per measurement (default 3)"
    )
    parser.add_argument(
        "--repeat", type=positive_int, default=1, help="time each row this many times, keep the best"
    )
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_POINTS} points x {QUICK_STEPS} steps")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    points = args.points or (QUICK_POINTS if args.quick else 1_000_000)
    steps = args.steps or (QUICK_STEPS if args.quick else None)
    every = default_threads()
    threads = sorted({1, every})
    load_average = os.getloadavg()

    _log(f"sampling {points:,} points and advancing them {WARMUP_STEPS} steps ...")
    ens = Ensemble.sample(PARAMS, points, init=INIT, seed=SEED, threads=every).run(WARMUP_STEPS)
    init, step0 = ens.state(), ens.step
    bytes_per_point = sum(ens.array(name).itemsize for name in STATE_FIELDS)
    del ens

    with tempfile.TemporaryDirectory(prefix="warpratchet-bench-") as workdir:
        _log("building contenders (Numba JIT, gcc, Warp warm-up) ...")
        builds = {}
        contenders = []
        for key, (rows, build) in {
            "numpy": numpy_contenders(PARAMS),
            "numba": numba_contenders(PARAMS, threads),
            "c": c_contenders(PARAMS, threads, Path(workdir)),
            "warpratchet": warp_contenders(PARAMS, threads),
        }.items():
            builds[key] = build
            contenders.extend(rows)

        measurements = []
        for c in contenders:
            m = Measurement(c)
            measurements.append(m)
            if c.advance is None:
                _log(f"{c.label}, {c.threads} thread(s): {c.unavailable}")
                continue
            m.steps = steps or calibrate(c.advance, init, step0, args.seconds)
            _log(f"{c.label}, {c.threads} thread(s): {points:,} points x {m.steps:,} steps ...")
            timings = []
            for _ in range(args.repeat):
                m.state, seconds = c.advance(init, step0, m.steps)
                timings.append(seconds)
            m.seconds = min(timings)  # the least disturbed run

    _log("checking every end state against warpratchet, bit for bit ...")
    verify(measurements, init, step0, PARAMS, every)
    report = build_report(
        measurements, points, builds, bytes_per_point, args.quick, args.repeat, load_average
    )
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        print_table(report)
    return 0 if report["all_bitwise_equal"] else 1


if __name__ == "__main__":
    sys.exit(main())
