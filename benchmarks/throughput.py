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
* C, hand-vectorised (AVX2): ``benchmarks/c/ratchet_map_avx2.c``, AVX2 intrinsics, 3, 4 or 8
  independent 4-wide vectors per OpenMP thread (all built; the fastest counts), without AVX-512's
  registers where the CPU has them (``-mno-avx512f``): the ceiling of a CPU without AVX-512 for
  this arithmetic.
* C, hand-vectorised (AVX-512): ``benchmarks/c/ratchet_map_avx512.c``, AVX-512 intrinsics, 6 or
  8 independent 8-wide vectors per OpenMP thread, the ceiling where the CPU has AVX-512; skipped
  with a reason on a CPU without it.
* warpratchet: :meth:`warpratchet.Ensemble.run` (kernel ``advance_map``), 1 and all threads,
  after a warm-up launch (first-compile time excluded), on the code path of
  ``warpratchet.kernels.CPU_ISA``.
* warpratchet + indicators: :class:`warpratchet.sumrule.IndicatorEnsemble` (kernel
  ``advance_map_indicators``: the same orbit plus MEGNO and FLI), 1 and all threads.
* The same two on the kernels' other code path (AVX2 on an AVX-512 CPU; AVX-512 on an AVX2 one,
  where they are unavailable), built and run in a child process with ``WARPRATCHET_CPU_ISA`` set
  (a process builds one path), each against the hand-vectorised C of its own path; their end
  states too must equal warpratchet's bit for bit.

The code of the rows is in ``throughput_contenders.py``. Each row's step count is chosen from a
short probe so that a measurement takes about ``--seconds`` (3 s); then the rows are timed in
``--repeat`` rounds (default 1), every row once per round, and each keeps its best time: rows
measured in the same rounds see the same machine, so their ratios (to NumPy, to warpratchet and
to the hand-vectorised C) survive a busy machine better than the absolute rates. The unit is
point-steps per second, ``points * steps / seconds``. The *ceiling* of a row is the
hand-vectorised C of the warpratchet rows' code path, on as many threads.

With ``--targets`` it then measures, in child processes, what this table does not: the transport
kernel against the same C (``kernel_ceilings.py``, on each code path this CPU runs) and the run a
user types against its kernel alone (``end_to_end.py``, at 10^6 points x 6,000 steps and at the
README's main job), and prints every throughput target with its measured ratio: ``advance_map``
>= 0.8 and the indicators and transport >= 0.7 of the hand-vectorised C of their code path, the
run >= 0.9 of its kernel (the medians of each script's rounds).

Usage::

    python benchmarks/throughput.py                  # the table (about a minute on 2 cores)
    python benchmarks/throughput.py --json           # one JSON object on stdout
    python benchmarks/throughput.py --quick --json   # 20 000 points x 1000 steps (smoke test)
    python benchmarks/throughput.py --repeat 2 --targets   # and every target, from child processes
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import indicators_overhead
import numpy as np
from throughput_contenders import (
    EVOLVED,
    INIT,
    PATH_LABELS,
    SEED,
    Advance,
    Contender,
    State,
    c_contenders,
    c_simd_contenders,
    child_json,
    numba_contenders,
    numpy_contenders,
    other_path_contenders,
    path_key,
    warp_contenders,
    warp_indicator_contenders,
)

from warpratchet import Ensemble, MapParams
from warpratchet.cli import positive_int
from warpratchet.ensemble import RENORM_CHECK_EVERY, RENORM_THRESHOLD, STATE_FIELDS, default_threads
from warpratchet.kernels import CPU_ISA

#: The benchmark problem: the README's example (domain "LR" of Eq. (Aa)), strip ensemble (seed
#: and sampler: ``throughput_contenders.INIT, SEED``).
PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
#: warpratchet's ``advance_map`` at least this fraction of the hand-vectorised C of its code path
#: on every thread count, the indicators kernel at least :data:`INDICATORS_TARGET_RATIO` (its
#: fraction of ``advance_map``, printed as information: indicators_overhead.TARGET).
TARGET_RATIO = 0.8
INDICATORS_TARGET_RATIO = 0.7
#: The ceiling rows: the hand-vectorised C of the warpratchet rows' code path.
CEILING = f"c_{CPU_ISA}"
#: The kernels' other code path, whose rows run in a child process built for it.
OTHER_PATHS = tuple(isa for isa in PATH_LABELS if isa != CPU_ISA)
#: The target: at most this many bytes of state per point, and 10^8 points must fit in this memory.
STATE_BYTES_LIMIT = 80
MEMORY_GIB = 24.0
QUICK_POINTS, QUICK_STEPS = 20_000, 1000
#: Iterations before the measured ones (a multiple of RENORM_CHECK_EVERY). The FTLE is ~0.35 per
#: step here, so a tangent first passes RENORM_THRESHOLD = e^230 after ~660 steps: by step 1024, 98%
#: of the points have been renormalised, and a measurement exercises that branch as a long run does.
WARMUP_STEPS = 1024
#: Relative tolerance of the log-stretch of rows on a GPU (a sum of a few logs, each within 1 ulp).
GPU_LOG_RTOL = 1e-14
#: A probe shorter than this says too little about the rate; it is repeated with 4x the steps.
PROBE_SECONDS = 0.25


@dataclass
class Measurement:
    contender: Contender
    steps: int = 0
    seconds: float = math.nan
    cpu_seconds: float = math.nan  # of the whole process during the best (shortest) run
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


# -- measuring --------------------------------------------------------------------------------------
def _two_digits(x: float) -> int:
    return int(float(f"{x:.2g}"))


def calibrate(advance: Advance, init: State, step0: int, seconds: float) -> int:
    """Steps that take about ``seconds``, from probes of 8, 32, 128, ... steps."""
    steps = 8
    while True:
        took = advance(init, step0, steps)[1].seconds
        if took >= PROBE_SECONDS or steps >= 1 << 24:
            break
        steps *= 4
    return max(8, _two_digits(seconds * steps / took))


def verify(measurements: list[Measurement], init: State, step0: int, params: MapParams, threads: int) -> None:
    """Compare every end state, bit for bit, with a Warp ensemble advanced to the same step on the CPU.

    Rows on a GPU (``--device``): the orbit and tangent bit for bit, the log-stretch to
    :data:`GPU_LOG_RTOL` (CUDA's ``log`` differs from the C library's in the last bits).

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
            mine = np.ascontiguousarray(m.state[name])
            theirs = ref.array(name)
            if m.contender.device != "cpu" and name == "log_stretch":
                # The GPU's log is not the C library's: the log-stretch agrees to a few ulp only.
                count = int(np.count_nonzero(np.abs(mine - theirs) > GPU_LOG_RTOL * np.abs(theirs)))
            else:  # bits, so -0.0 and NaN payloads count too
                count = int(np.count_nonzero(mine.view(np.int64) != theirs.view(np.int64)))
            if count:
                mismatched[name] = count
        m.mismatched = mismatched
        m.renormalised_points = int(np.count_nonzero(ref.array("log_stretch") != init["log_stretch"]))
        m.state = None  # free the memory


# -- report -----------------------------------------------------------------------------------------
def _code_path(key: str) -> str | None:
    """The kernels' code path of a warpratchet row (None for the other rows)."""
    for isa in OTHER_PATHS:
        if key in (path_key("warpratchet", isa), path_key("warpratchet_indicators", isa)):
            return isa
    return CPU_ISA if key in ("warpratchet", "warpratchet_indicators") else None


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _ratios(by_key: dict, key: str, to: str, points: int, per_cpu: bool = False) -> dict[str, float | None]:
    """``rate(key) / rate(to)`` per thread count (None where either row did not run); with
    ``per_cpu``, of the rates per CPU second (rate / CPU use: what a row did with the CPU time it
    got, the steadier ratio when other processes take the cores)."""
    out = {}
    for (k, threads), m in by_key.items():
        other = by_key.get((to, threads))
        if k == key:
            ok = m.measured and other is not None and other.measured
            ratio = m.rate(points) / other.rate(points) if ok else None
            if ok and per_cpu:
                ratio = (
                    ratio * other.cpu_seconds / m.cpu_seconds * m.seconds / other.seconds
                    if m.cpu_seconds
                    else None
                )
            out[str(threads)] = ratio
    return out


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
        simd = {}
        for isa in ("avx2", "avx512"):
            ceiling = by_key.get((f"c_{isa}", c.threads))
            simd[isa] = ceiling.rate(points) if ceiling is not None and ceiling.measured else None
        path = _code_path(c.key) or CPU_ISA
        rows.append(
            {
                "implementation": c.key,
                "label": c.label,
                "threads": c.threads,
                "status": "ok" if measured else c.unavailable,
                "steps": m.steps if measured else None,
                "seconds": m.seconds if measured else None,
                # CPU seconds / (seconds x threads): near 1 when the row had its cores to itself.
                "cpu_seconds": m.cpu_seconds if measured else None,
                "cpu_use": m.cpu_seconds / (m.seconds * c.threads) if measured else None,
                "point_steps_per_second": rate if measured else None,
                "vs_numpy": rate / numpy_rate if measured else None,
                "vs_warpratchet": rate / warp_rate if measured else None,
                "vs_c_avx2": rate / simd["avx2"] if measured and simd["avx2"] else None,
                "vs_c_avx512": rate / simd["avx512"] if measured and simd["avx512"] else None,
                "code_path": _code_path(c.key),
                "vs_ceiling": rate / simd[path] if measured and simd[path] else None,
                "bitwise_equal_to_warpratchet": (not m.mismatched) if measured else None,
                "mismatched_points": m.mismatched if measured else None,
                "renormalised_points": m.renormalised_points if measured else None,
            }
        )
    map_vs_c = _ratios(by_key, "warpratchet", CEILING, points)
    indicators_vs_c = _ratios(by_key, "warpratchet_indicators", CEILING, points)
    indicators_vs_map = _ratios(by_key, "warpratchet_indicators", "warpratchet", points)
    per_cpu = {
        "warpratchet_vs_ceiling": _ratios(by_key, "warpratchet", CEILING, points, per_cpu=True),
        "indicators_vs_ceiling": _ratios(by_key, "warpratchet_indicators", CEILING, points, per_cpu=True),
        "indicators_vs_warpratchet": _ratios(
            by_key, "warpratchet_indicators", "warpratchet", points, per_cpu=True
        ),
    }
    other_paths = {
        isa: {
            "ceiling": f"c_{isa}",
            "warpratchet_vs_ceiling": _ratios(by_key, path_key("warpratchet", isa), f"c_{isa}", points),
            "indicators_vs_ceiling": _ratios(
                by_key, path_key("warpratchet_indicators", isa), f"c_{isa}", points
            ),
            "per_cpu_second": {
                "warpratchet_vs_ceiling": _ratios(
                    by_key, path_key("warpratchet", isa), f"c_{isa}", points, per_cpu=True
                ),
                "indicators_vs_ceiling": _ratios(
                    by_key, path_key("warpratchet_indicators", isa), f"c_{isa}", points, per_cpu=True
                ),
            },
        }
        for isa in OTHER_PATHS
    }
    met = []
    for maps, indicators in [(map_vs_c, indicators_vs_c)] + [
        (o["warpratchet_vs_ceiling"], o["indicators_vs_ceiling"]) for o in other_paths.values()
    ]:
        met += [r >= TARGET_RATIO for r in maps.values() if r is not None]
        met += [r >= INDICATORS_TARGET_RATIO for r in indicators.values() if r is not None]
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
        # Both kernels against the hand-vectorised C of their code path, per thread count.
        "cpu_isa": CPU_ISA,
        "ceiling": CEILING,
        "warpratchet_vs_ceiling": map_vs_c,
        "indicators_vs_ceiling": indicators_vs_c,
        "indicators_vs_warpratchet": indicators_vs_map,
        # The same ratios per CPU second of each row.
        "per_cpu_second": per_cpu,
        # The kernels built for the other code path (a child process), against that path's C.
        "other_paths": other_paths,
        "target": (
            f"advance_map >= {TARGET_RATIO}, indicators >= {INDICATORS_TARGET_RATIO} x hand-vectorised C "
            "of the code path"
        ),
        "target_ratio": TARGET_RATIO,
        "indicators_target_ratio_vs_ceiling": INDICATORS_TARGET_RATIO,
        # None where the C row could not run (no gcc): nothing to compare with.
        "target_met": all(met) if met else None,
        "indicators_target_ratio": indicators_overhead.TARGET,
        "state_bytes_per_point": bytes_per_point,
        "state_bytes_limit": STATE_BYTES_LIMIT,
        "state_gib_at_1e8_points": gib_1e8,
        "fits_1e8_points_in_gib": MEMORY_GIB,
        "fits_1e8_points": bool(bytes_per_point <= STATE_BYTES_LIMIT and gib_1e8 <= MEMORY_GIB),
    }


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def _print_ratios(names: dict[str, str], ratios: dict[str, Any]) -> None:
    """One line per ratio of ``ratios`` (per thread count, wall and per CPU second)."""
    for key, name in names.items():
        per_threads = ", ".join(
            f"{_fmt(ratio, '.2f')} on {threads} thread{'s' if threads != '1' else ''}"
            for threads, ratio in ratios[key].items()
        )
        per_cpu = ", ".join(
            f"{_fmt(ratio, '.2f')} on {threads}" for threads, ratio in ratios["per_cpu_second"][key].items()
        )
        print(f"  {name}: {per_threads or '-'} (per CPU second: {per_cpu or '-'})")


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
        f"{'implementation':<38}{'threads':>7}{'steps':>8}{'seconds':>9}{'CPU use':>8}{'M pt-steps/s':>14}"
        f"{'x NumPy':>9}{'x warpratchet':>15}{'x AVX2 C':>10}{'x AVX-512 C':>13}  bitwise = warpratchet"
    )
    print(head)
    print("-" * len(head))
    for row in report["results"]:
        if row["status"] != "ok":
            print(f"{row['label']:<38}{row['threads']:>7}  {row['status']}")
            continue
        rate = row["point_steps_per_second"] / 1e6
        same = "yes" if row["bitwise_equal_to_warpratchet"] else f"NO {row['mismatched_points']}"
        print(
            f"{row['label']:<38}{row['threads']:>7}{row['steps']:>8}{row['seconds']:>9.2f}"
            f"{row['cpu_use']:>8.2f}{rate:>14.1f}"
            f"{_fmt(row['vs_numpy'], '.2f'):>9}{_fmt(row['vs_warpratchet'], '.3f'):>15}"
            f"{_fmt(row['vs_c_avx2'], '.3f'):>10}{_fmt(row['vs_c_avx512'], '.3f'):>13}  {same}"
        )
    print()
    print("Builds:")
    for key, build in report["builds"].items():
        print(f"  {key:<12} {build}")
    print()
    print(
        f"Ratios between rows of this run, against the hand-vectorised C of the {report['cpu_isa']} "
        f"code path (aims: >= {report['target_ratio']} for\nadvance_map, >= "
        f"{report['indicators_target_ratio_vs_ceiling']} for the indicators; the indicators at >= "
        f"{report['indicators_target_ratio']} of warpratchet):"
    )
    names = {
        "warpratchet_vs_ceiling": "warpratchet / hand-vectorised C",
        "indicators_vs_ceiling": "warpratchet + indicators / hand-vectorised C",
        "indicators_vs_warpratchet": "warpratchet + indicators / warpratchet",
    }
    _print_ratios(names, report)
    for isa, other in report["other_paths"].items():
        print(f"The {PATH_LABELS[isa]} code path (kernels built for it in a child process), against its C:")
        _print_ratios({key: names[key] for key in ("warpratchet_vs_ceiling", "indicators_vs_ceiling")}, other)
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


# -- every target ---------------------------------------------------------------------------------
#: The other kernel's target (``kernel_ceilings.py``), and the run's against its kernel alone.
TRANSPORT_TARGET_RATIO = 0.7
RUN_TARGET_RATIO = 0.9
#: The runs ``end_to_end.py`` times: 10^6 points x 6,000 steps (its default) and the README's main job.
RUN_JOBS = {
    "warpratchet run, 10^6 x 6,000": [],
    "warpratchet run, main job (10^4 x 120,000)": ["--points", "10000", "--steps", "120000", "--rounds", "5"],
}


def _rounds(count: int) -> str:
    return f"{count} round" + ("" if count == 1 else "s")


def _unavailable(path: str, measured: str, why: str) -> dict:
    return {"code_path": path, "measured": measured, "unavailable": why}


def _target_row(path: str, measured: str, threads: Any, ratio: float, target: float, by: str) -> dict:
    row = {"code_path": path, "measured": measured, "threads": int(threads), "ratio": ratio}
    return row | {"target": target, "met": bool(ratio >= target), "by": by}


def measure_targets(report: dict[str, Any], quick: bool) -> list[dict[str, Any]]:
    """Every throughput target with its ratio: the two kernels of ``report`` (this run) and, from
    child processes, transport (``kernel_ceilings.py`` on each code path of the report) and the run
    a user types (``end_to_end.py``, each job of :data:`RUN_JOBS`; one ``--quick`` job with
    ``quick``). A script that cannot run gives a row with its reason instead of a ratio."""
    rows = []
    paths = {report["cpu_isa"]: report, **report["other_paths"]}
    for isa, part in paths.items():
        for measured, key, target in (
            ("advance_map", "warpratchet_vs_ceiling", TARGET_RATIO),
            ("indicators", "indicators_vs_ceiling", INDICATORS_TARGET_RATIO),
        ):
            for threads, ratio in part[key].items():
                if ratio is None:  # the row or its C did not run
                    why = f"no ratio on {threads} thread(s) (the table says why)"
                    rows.append(_unavailable(isa, measured, why))
                    continue
                rows.append(_target_row(isa, measured, threads, ratio, target, "throughput.py"))
        ceilings = child_json(
            "kernel_ceilings.py", ["--json", *(["--quick"] if quick else [])], None if isa == CPU_ISA else isa
        )
        if isinstance(ceilings, str):
            rows.append(_unavailable(isa, "transport", ceilings))
            continue
        for row in ceilings["rows"]:
            ratio = statistics.median(row["transport_vs_c_wall"])
            by = f"kernel_ceilings.py ({_rounds(ceilings['rounds'])})"
            rows.append(_target_row(isa, "transport", row["threads"], ratio, TRANSPORT_TARGET_RATIO, by))
    jobs = {"warpratchet run (--quick)": ["--quick"]} if quick else RUN_JOBS
    for job, args in jobs.items():
        runs = child_json("end_to_end.py", ["--json", *args])
        if isinstance(runs, str):
            rows.append(_unavailable(CPU_ISA, job, runs))
            continue
        by = f"end_to_end.py ({_rounds(runs['rounds'])})"
        for row in runs["results"]:
            ratio = row["run_over_kernel_wall"]["median"]
            rows.append(_target_row(CPU_ISA, job, row["threads"], ratio, RUN_TARGET_RATIO, by))
    return rows


def print_targets(rows: list[dict[str, Any]]) -> None:
    print()
    print("Targets: each kernel against the hand-vectorised C of its code path; the run a user types")
    print("against its kernel alone (medians of each script's rounds):")
    print(f"  {'path':<8}{'measured':<46}{'threads':>7}{'ratio':>8}{'target':>8}  {'met':<5}by")
    for row in rows:
        if "unavailable" in row:
            print(f"  {row['code_path']:<8}{row['measured']:<46}  unavailable: {row['unavailable']}")
            continue
        met = "yes" if row["met"] else "no"
        print(
            f"  {row['code_path']:<8}{row['measured']:<46}{row['threads']:>7}{row['ratio']:>8.2f}"
            f"{row['target']:>8}  {met:<5}{row['by']}"
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
        description=(
            "Point-steps per second of warpratchet, NumPy, Numba, plain and hand-vectorised C "
            "on the same map."
        ),
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
        "--repeat",
        type=positive_int,
        default=1,
        help="rounds of timings (every row once per round); each row keeps its best",
    )
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_POINTS} points x {QUICK_STEPS} steps")
    parser.add_argument(
        "--device", default="cpu", help="Warp device of the warpratchet rows, e.g. cuda:0 (default cpu)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument(
        "--targets",
        action="store_true",
        help="then measure transport and the run a user types in child processes, and print every target",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    points = args.points or (QUICK_POINTS if args.quick else 1_000_000)
    steps = args.steps or (QUICK_STEPS if args.quick else None)
    every = default_threads()
    threads = sorted({1, every})
    load_average = os.getloadavg()
    try:
        Ensemble.sample(PARAMS, 1, init=INIT, seed=SEED, threads=1, device=args.device)
    except ValueError as error:  # e.g. device = 'cuda:0' is not available (Warp sees: cpu)
        build_parser().error(str(error))

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
            "c_avx2": c_simd_contenders("avx2", PARAMS, threads, Path(workdir)),
            "c_avx512": c_simd_contenders("avx512", PARAMS, threads, Path(workdir)),
            "warpratchet": warp_contenders(PARAMS, threads, args.device),
            "warpratchet_indicators": warp_indicator_contenders(PARAMS, threads, points, args.device),
            **{
                path_key("warpratchet", isa): other_path_contenders(isa, PARAMS, threads, points)
                for isa in OTHER_PATHS
                if args.device == "cpu"
            },
        }.items():
            builds[key] = build
            contenders.extend(rows)

        measurements = [Measurement(c) for c in contenders]
        for m in measurements:
            c = m.contender
            if c.advance is None:
                _log(f"{c.label}, {c.threads} thread(s): {c.unavailable}")
                continue
            m.steps = steps or calibrate(c.advance, init, step0, args.seconds)
        # Rounds: every row once per round, so that all rows see the same spells of load.
        for round_ in range(args.repeat):
            for m in (m for m in measurements if m.measured):
                c = m.contender
                _log(f"round {round_ + 1}: {c.label}, {c.threads} thread(s): {points:,} x {m.steps:,} steps")
                m.state, timing = c.advance(init, step0, m.steps)
                if round_ == 0 or timing.seconds < m.seconds:  # keep the least disturbed run
                    m.seconds, m.cpu_seconds = timing.seconds, timing.cpu_seconds

    _log("checking every end state against warpratchet, bit for bit ...")
    verify(measurements, init, step0, PARAMS, every)
    report = build_report(
        measurements, points, builds, bytes_per_point, args.quick, args.repeat, load_average
    )
    if args.targets and args.device == "cpu":
        _log("measuring transport and the run a user types (kernel_ceilings.py, end_to_end.py) ...")
        report["targets"] = measure_targets(report, args.quick)
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        print_table(report)
        if "targets" in report:
            print_targets(report["targets"])
    return 0 if report["all_bitwise_equal"] else 1


if __name__ == "__main__":
    sys.exit(main())
