"""Smoke tests of ``benchmarks/throughput.py`` (issue 2, item 7; issue 12, item 4) and of
``benchmarks/indicators_overhead.py`` (issue 12: the indicators kernel against ``advance_map``).

Runs ``throughput.py --quick --json`` once in a subprocess (20 000 points x 1000 steps; about
5-10 s with the Numba JIT and the gcc build) and checks the JSON structure, the ratios, the
state-size bound and that every implementation's end state equals warpratchet's bit for bit.
No timing assertions: rates are only checked to be positive and consistent with steps/seconds.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from support import quick_benchmark

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "throughput.py"
QUICK_POINTS, QUICK_STEPS = 20_000, 1000


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=600, check=False
    )


@pytest.fixture(scope="module")
def quick_run() -> subprocess.CompletedProcess:
    return _run("--quick", "--json")


@pytest.fixture(scope="module")
def report(quick_run: subprocess.CompletedProcess) -> dict[str, Any]:
    assert quick_run.stdout.strip(), f"no JSON on stdout; stderr:\n{quick_run.stderr[-3000:]}"
    return json.loads(quick_run.stdout)


def _measured(report: dict[str, Any]) -> list[dict[str, Any]]:
    return [row for row in report["results"] if row["status"] == "ok"]


def test_exits_0_with_one_json_object(quick_run: subprocess.CompletedProcess) -> None:
    assert quick_run.returncode == 0, quick_run.stderr[-3000:]
    assert len(quick_run.stdout.strip().splitlines()) == 1


IMPLEMENTATIONS = ("numba", "c", "c_avx512", "warpratchet", "warpratchet_indicators")


def _has_avx512() -> bool:
    with open("/proc/cpuinfo") as cpuinfo:
        return any(line.startswith("flags") and " avx512f" in line for line in cpuinfo)


def test_rows_cover_every_implementation_at_1_and_all_threads(report: dict[str, Any]) -> None:
    threads = sorted({1, report["machine"]["cores"]})
    expected = [("numpy", 1)] + [(key, t) for key in IMPLEMENTATIONS for t in threads]
    assert [(row["implementation"], row["threads"]) for row in report["results"]] == expected
    assert set(report["builds"]) == {"numpy", *IMPLEMENTATIONS}
    assert report["problem"]["points"] == QUICK_POINTS and report["problem"]["quick"] is True


def test_every_implementation_ran(report: dict[str, Any]) -> None:
    for row in report["results"]:
        if row["implementation"] in ("c", "c_avx512") and shutil.which("gcc") is None:
            assert row["status"].startswith("unavailable"), row
            continue
        if row["implementation"] == "c_avx512" and not _has_avx512():
            assert row["status"] == "unavailable: this CPU has no AVX-512", row
            continue
        # numba is a test dependency, so it must run here too.
        assert row["status"] == "ok", row
        assert row["steps"] == QUICK_STEPS
        rate = row["point_steps_per_second"]
        assert math.isfinite(rate) and rate > 0
        assert rate == pytest.approx(QUICK_POINTS * row["steps"] / row["seconds"], rel=1e-12)
        assert row["cpu_seconds"] >= 0  # CPU time of the process while the row ran
        core_seconds = row["seconds"] * row["threads"]
        assert row["cpu_use"] == pytest.approx(row["cpu_seconds"] / core_seconds, rel=1e-12)


def test_every_end_state_equals_warpratchet_bit_for_bit(report: dict[str, Any]) -> None:
    rows = _measured(report)
    assert len(rows) >= 7  # NumPy, Numba x2, warpratchet x2 and with indicators x2 at least (C needs gcc)
    for row in rows:
        assert row["bitwise_equal_to_warpratchet"] is True, (row["label"], row["mismatched_points"])
        assert row["mismatched_points"] == {}
        # The renormalisation branch was taken during the compared steps, so it was checked too.
        assert row["renormalised_points"] > 0, row
    assert report["all_bitwise_equal"] is True


def test_ratios_are_to_numpy_and_warpratchet_of_the_same_run(report: dict[str, Any]) -> None:
    rows = _measured(report)
    numpy_rate = next(r for r in rows if r["implementation"] == "numpy")["point_steps_per_second"]
    warp = next(
        r
        for r in rows
        if r["implementation"] == "warpratchet" and r["threads"] == report["warpratchet_threads"]
    )
    assert report["warpratchet_point_steps_per_second"] == warp["point_steps_per_second"]
    rate = {(r["implementation"], r["threads"]): r["point_steps_per_second"] for r in rows}
    for row in rows:
        row_rate = row["point_steps_per_second"]
        assert row["vs_numpy"] == pytest.approx(row_rate / numpy_rate, rel=1e-12)
        assert row["vs_warpratchet"] == pytest.approx(row_rate / warp["point_steps_per_second"], rel=1e-12)
        c_rate = rate.get(("c_avx512", row["threads"]))
        assert row["vs_c_avx512"] == (None if c_rate is None else pytest.approx(row_rate / c_rate, rel=1e-12))


def test_both_kernels_are_compared_with_the_hand_vectorised_c(report: dict[str, Any]) -> None:
    """Issue 12: warpratchet's ratio to the AVX-512 C per thread count, and the target line."""
    rate = {(r["implementation"], r["threads"]): r["point_steps_per_second"] for r in _measured(report)}
    threads = sorted({1, report["machine"]["cores"]})
    assert report["target"] == "warpratchet >= 0.5 x hand-vectorised C" and report["target_ratio"] == 0.5
    for key, implementation, to in (
        ("warpratchet_vs_c_avx512", "warpratchet", "c_avx512"),
        ("indicators_vs_c_avx512", "warpratchet_indicators", "c_avx512"),
        ("indicators_vs_warpratchet", "warpratchet_indicators", "warpratchet"),
    ):
        assert set(report[key]) == {str(t) for t in threads}
        for t in threads:
            expected = rate[(implementation, t)] / rate[(to, t)] if (to, t) in rate else None
            assert report[key][str(t)] == (None if expected is None else pytest.approx(expected, rel=1e-12))
    kernels = ("warpratchet_vs_c_avx512", "indicators_vs_c_avx512")
    ratios = [r for key in kernels for r in report[key].values() if r is not None]
    assert report["target_met"] == (min(ratios) >= 0.5 if ratios else None)


def test_state_is_at_most_80_bytes_per_point_and_1e8_points_fit(report: dict[str, Any]) -> None:
    per_point = report["state_bytes_per_point"]
    assert per_point <= 80
    assert report["state_gib_at_1e8_points"] == pytest.approx(1e8 * per_point / 2**30, rel=1e-12)
    assert report["state_gib_at_1e8_points"] <= 24.0
    assert report["fits_1e8_points"] is True


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--points", "0"), "0 is outside the allowed range >= 1"),
        (("--steps", "-3"), "-3 is outside the allowed range >= 1"),
        (("--seconds", "0"), "0.0 is outside the allowed range 0 < seconds <= 600"),
        (("--points", "many"), "invalid integer value: 'many'"),
        (("--device", "cuda:7"), "device = 'cuda:7' is not available"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args: tuple[str, ...], needle: str) -> None:
    done = _run(*args)
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], done.stderr


def test_indicators_overhead_benchmark_runs_and_the_orbit_is_advance_maps():
    """Smoke test of ``benchmarks/indicators_overhead.py --quick`` (structure; no timing assertions)."""
    report = quick_benchmark("indicators_overhead.py")
    assert report["quick"] and report["target"] == 0.8
    assert [row["threads"] for row in report["results"]][0] == 1
    for row in report["results"]:
        assert row["bitwise_same_orbit"]
        for key in ("ratio_per_wall_second", "ratio_per_cpu_second"):
            spread = row[key]
            assert 0 < spread["min"] <= spread["median"] <= spread["max"]
        assert row["ratio_of_best"] > 0 and row["map_point_steps_per_second"] > 0
