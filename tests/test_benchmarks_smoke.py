"""Smoke tests of ``benchmarks/throughput.py`` (issue 2, item 7; issue 12, item 4) and of
``benchmarks/indicators_overhead.py`` (issue 12: the indicators kernel against ``advance_map``),
``kernel_ceilings.py`` and the other benchmarks' ``--quick`` runs.

Runs ``throughput.py --quick --json`` once (:func:`support.benchmark`, in this process; 20 000
points x 1000 steps; about 5-10 s with the Numba JIT and the gcc build) and checks the JSON
structure, the ratios, the state-size bound and that every implementation's end state equals
warpratchet's bit for bit.
No timing assertions: rates are only checked to be positive and consistent with steps/seconds.
"""

from __future__ import annotations

import importlib.util
import json
import math
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest
from support import benchmark, quick_benchmark

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "throughput.py"
QUICK_POINTS, QUICK_STEPS = 20_000, 1000


def _run(*args: str) -> subprocess.CompletedProcess:
    return benchmark(SCRIPT.name, *args)


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


IMPLEMENTATIONS = ("numba", "c", "c_avx2", "c_avx512", "warpratchet", "warpratchet_indicators")
#: The kernels' code paths; the one a process does not run is measured in a child process.
PATHS = ("avx2", "avx512")


def _other_path(report: dict[str, Any]) -> str:
    return next(isa for isa in PATHS if isa != report["cpu_isa"])


def _other_rows(report: dict[str, Any]) -> tuple[str, str]:
    isa = _other_path(report)
    return f"warpratchet_{isa}", f"warpratchet_indicators_{isa}"


def _has(flag: str) -> bool:
    with open("/proc/cpuinfo") as cpuinfo:
        return any(line.startswith("flags") and f" {flag}" in line for line in cpuinfo)


def test_rows_cover_every_implementation_at_1_and_all_threads(report: dict[str, Any]) -> None:
    threads = sorted({1, report["machine"]["cores"]})
    implementations = (*IMPLEMENTATIONS, *_other_rows(report))
    expected = [("numpy", 1)] + [(key, t) for key in implementations for t in threads]
    assert [(row["implementation"], row["threads"]) for row in report["results"]] == expected
    assert set(report["builds"]) == {"numpy", *IMPLEMENTATIONS, _other_rows(report)[0]}
    assert report["problem"]["points"] == QUICK_POINTS and report["problem"]["quick"] is True


def test_every_implementation_ran(report: dict[str, Any]) -> None:
    for row in report["results"]:
        if row["implementation"] in ("c", "c_avx2", "c_avx512") and shutil.which("gcc") is None:
            assert row["status"].startswith("unavailable"), row
            continue
        if row["implementation"] == "c_avx512" and not _has("avx512f"):
            assert row["status"] == "unavailable: this CPU has no AVX-512", row
            continue
        if row["implementation"] == "c_avx2" and not _has("avx2"):
            assert row["status"] == "unavailable: this CPU has no AVX2", row
            continue
        if row["implementation"] in _other_rows(report) and not _has("avx512f"):
            # an AVX2 CPU builds the AVX-512 path but cannot run it
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
        for isa in ("avx2", "avx512"):
            c_rate = rate.get((f"c_{isa}", row["threads"]))
            expected = None if c_rate is None else pytest.approx(row_rate / c_rate, rel=1e-12)
            assert row[f"vs_c_{isa}"] == expected
        path = row["code_path"] or report["cpu_isa"]
        assert row["vs_ceiling"] == row[f"vs_c_{path}"]
        if row["implementation"] in _other_rows(report):
            assert row["code_path"] == _other_path(report)
        elif row["implementation"] in ("warpratchet", "warpratchet_indicators"):
            assert row["code_path"] == report["cpu_isa"]
        else:
            assert row["code_path"] is None


def test_both_kernels_are_compared_with_the_hand_vectorised_c(report: dict[str, Any]) -> None:
    """Both kernels' ratios to the hand-vectorised C of their code path per thread count (never
    blank where gcc is found: every x86-64 CPU this runs on has the AVX2 C at least), and the
    target line."""
    rate = {(r["implementation"], r["threads"]): r["point_steps_per_second"] for r in _measured(report)}
    threads = sorted({1, report["machine"]["cores"]})
    ceiling = report["ceiling"]
    assert ceiling == f"c_{report['cpu_isa']}" and report["cpu_isa"] in ("avx2", "avx512")
    assert report["target_ratio"] == 0.8 and report["indicators_target_ratio_vs_ceiling"] == 0.7
    for key, implementation, to in (
        ("warpratchet_vs_ceiling", "warpratchet", ceiling),
        ("indicators_vs_ceiling", "warpratchet_indicators", ceiling),
        ("indicators_vs_warpratchet", "warpratchet_indicators", "warpratchet"),
    ):
        assert set(report[key]) == {str(t) for t in threads}
        for t in threads:
            if shutil.which("gcc") is not None:
                assert (to, t) in rate, (to, t)
            expected = rate[(implementation, t)] / rate[(to, t)] if (to, t) in rate else None
            assert report[key][str(t)] == (None if expected is None else pytest.approx(expected, rel=1e-12))
        # the same ratio per CPU second: the wall ratio scaled by the rows' CPU use
        rows = {(r["implementation"], r["threads"]): r for r in _measured(report)}
        for t in threads:
            if (to, t) in rows and rows[(implementation, t)]["cpu_use"] > 0:
                use = rows[(to, t)]["cpu_use"] / rows[(implementation, t)]["cpu_use"]
                expected = pytest.approx(report[key][str(t)] * use, rel=1e-9)
                assert report["per_cpu_second"][key][str(t)] == expected
    met = [r >= 0.8 for r in report["warpratchet_vs_ceiling"].values() if r is not None]
    met += [r >= 0.7 for r in report["indicators_vs_ceiling"].values() if r is not None]
    # the other code path against its own C (blank only where this CPU cannot run that path)
    isa = _other_path(report)
    other = report["other_paths"][isa]
    assert set(report["other_paths"]) == {isa} and other["ceiling"] == f"c_{isa}"
    targets = ("warpratchet_vs_ceiling", "indicators_vs_ceiling")
    for key, implementation in zip(targets, _other_rows(report), strict=True):
        for t in threads:
            runs = (implementation, t) in rate and (f"c_{isa}", t) in rate
            expected = rate[(implementation, t)] / rate[(f"c_{isa}", t)] if runs else None
            assert other[key][str(t)] == (None if expected is None else pytest.approx(expected, rel=1e-12))
            if _has("avx512f") and shutil.which("gcc") is not None:
                assert runs, (implementation, t)
        met += [
            r >= (0.8 if key == "warpratchet_vs_ceiling" else 0.7)
            for r in other[key].values()
            if r is not None
        ]
    assert report["target_met"] == (all(met) if met else None)


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


def test_targets_cover_every_kernel_path_and_run():
    """``throughput.py --quick --json --targets`` (structure; no timing assertions): every target,
    each kernel on each code path and thread count (transport from ``kernel_ceilings.py``, in a
    child process) and the run a user types (``end_to_end.py``), with its ratio and whether it is
    met, or the reason it could not be measured."""
    report = json.loads(_run("--quick", "--json", "--targets").stdout)
    threads = sorted({1, report["machine"]["cores"]})
    rows = report["targets"]
    expected = [
        (isa, kernel, t)
        for isa in (report["cpu_isa"], _other_path(report))
        for kernel in ("advance_map", "indicators", "transport")
        for t in threads
    ] + [(report["cpu_isa"], "warpratchet run (--quick)", t) for t in threads]
    measured = [(r["code_path"], r["measured"], r["threads"]) for r in rows if "unavailable" not in r]
    unavailable = [(r["code_path"], r["measured"]) for r in rows if "unavailable" in r]
    assert [key for key in expected if (key[0], key[1]) not in unavailable] == measured
    assert all(isa == _other_path(report) for isa, _ in unavailable)  # only where the CPU lacks it
    targets = {"advance_map": 0.8, "indicators": 0.7, "transport": 0.7, "warpratchet run (--quick)": 0.9}
    for row in (r for r in rows if "unavailable" not in r):
        assert row["target"] == targets[row["measured"]]
        assert row["ratio"] > 0 and row["met"] is (row["ratio"] >= row["target"])


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


@pytest.mark.skipif(
    shutil.which("gcc") is None or platform.machine() not in ("x86_64", "AMD64"),
    reason="the hand-vectorised C needs gcc and an x86-64 CPU",
)
def test_kernel_ceilings_benchmark_runs_and_every_kernel_follows_the_c():
    """Smoke test of ``benchmarks/kernel_ceilings.py --quick`` (structure; no timing assertions):
    the C's end state is the map kernel's and the three kernels' orbits are the same, bit for bit."""
    report = quick_benchmark("kernel_ceilings.py")
    assert report["targets"] == {"map": 0.8, "indicators": 0.7, "transport": 0.7}
    assert [row["threads"] for row in report["rows"]][0] == 1
    for row in report["rows"]:
        assert row["bitwise_equal"] is True
        assert all(rate > 0 for rate in row["best_rate"].values())
        for name in report["targets"]:
            for key in (f"{name}_vs_c_wall", f"{name}_vs_c_cpu", f"{name}_thread_rate"):
                assert len(row[key]) == report["rounds"] and all(r > 0 for r in row[key])
            # the slowest shard runs inside the timed launches
            assert all(0 < r <= 1 for r in row[f"{name}_slowest_shard"])


@pytest.mark.parametrize("fresh", [False, True])
def test_end_to_end_benchmark_runs_and_reports_the_kernels_numbers(fresh):
    """Smoke test of ``benchmarks/end_to_end.py --quick`` (structure; no timing assertions), in this
    process or each run and kernel in a process of its own: the run's reported A and Lyapunov
    exponent are the kernel-only ensemble's, bit for bit."""
    report = quick_benchmark("end_to_end.py", *(["--fresh"] if fresh else []))
    assert report["bitwise_equal"] is True and report["rounds"] == 1 and report["device"] == "cpu"
    assert report["fresh"] is fresh
    assert [row["threads"] for row in report["results"]][0] == 1
    for row in report["results"]:
        for key in ("run_over_kernel_wall", "run_over_kernel_cpu"):
            assert 0 < row[key]["min"] <= row[key]["median"] <= row[key]["max"]


def test_run_pieces_benchmark_times_the_runs_launches_and_rows():
    """Smoke test of ``benchmarks/run_pieces.py --quick`` (structure; no timing assertions): the
    run's launches and rows are counted, and one thread has no shards to wait for."""
    report = quick_benchmark("run_pieces.py")
    assert report["rounds"] == 1 and report["results"][0]["threads"] == 1
    for row in report["results"]:
        assert row["launches"] >= 1 and row["rows"] >= 1 and row["blocks"] >= 1
        assert 0 < row["launch_s"] <= row["run_s"] and 0 < row["kernel_launch_s"] <= row["kernel_s"]
        assert row["start_lag_s"] >= 0 and row["shard_lag_s"] >= 0 and row["row_s"] > 0
        if row["threads"] == 1:
            assert row["start_lag_s"] == row["shard_lag_s"] == 0


def test_row_cost_benchmark_splits_a_row_and_bounds_the_run():
    """Smoke test of ``benchmarks/row_cost.py --quick`` (structure; no timing assertions): a case
    per thread count, the rows of a run of 6 000 steps counted as a History counts them, the row on
    one thread split into the row kernels' launches, and the bound formed from the parts it
    prints."""
    from warpratchet.history import history_steps

    report = quick_benchmark("row_cost.py")
    assert report["steps"] == 6000 and report["rows_in_run"] == len(history_steps(0, 6000))
    assert [case["threads"] for case in report["cases"]] == [1, 2]
    for case in report["cases"]:
        low, high = case["row_range_s"]
        assert 0 < low <= case["row_s"] <= high and case["step_s"] > 0
        rows = report["rows_in_run"] * (case["row_s"] + case["stop_s"])
        assert case["best_ratio"] == pytest.approx(case["kernel_s"] / (case["kernel_s"] + rows))
    split = report["cases"][0]["row_launches_s"]
    assert {"row_pass", "leaf_sums"} <= set(split) and all(s > 0 for s in split.values())


def test_command_time_benchmark_splits_fresh_processes_into_their_parts():
    """Smoke test of ``benchmarks/command_time.py --quick`` (structure; no timing assertions): both
    ways, each round's start, import, command and exit, which add up to the round's total."""
    report = quick_benchmark("command_time.py")
    assert report["command"][:2] == ["warpratchet", "run"] and report["rounds"] == 1
    assert set(report["seconds"]) == {"console", "main"}
    for parts in report["seconds"].values():
        assert all(parts[part]["median"] > 0 for part in ("start", "import", "command", "exit"))
        total = sum(parts[part]["median"] for part in ("start", "import", "command", "exit"))
        assert parts["total"]["median"] == pytest.approx(total)


def test_launch_cost_benchmark_splits_a_launch_into_fixed_and_per_step_parts():
    """Smoke test of ``benchmarks/launch_cost.py --quick`` (structure; no timing assertions): one
    row per slice size and way of launching (packed each time, or a recorded launch replayed), and
    the fixed and per-step parts add up to the one-step launch."""
    report = quick_benchmark("launch_cost.py")
    assert [(row["points"], row["launch"]) for row in report["rows"]] == [
        (size, way) for size in (1_024, 16_384) for way in ("packed", "replayed")
    ]
    for row in report["rows"]:
        assert row["launch_1_step_s"] > 0 and row["launch_8_steps_s"] > 0
        parts = (row["fixed_ns_per_point"] + row["step_ns_per_point"]) * row["points"] * 1e-9
        assert parts == pytest.approx(row["launch_1_step_s"])


def test_stop_cost_benchmark_stops_where_the_run_stops():
    """Smoke test of ``benchmarks/stop_cost.py --quick`` (structure; no timing assertions): one row
    per thread count, each stopped run cut where a History stops a run of 2 000 points x 3 000
    steps (its rows and, for so small an ensemble, its block steps; no regular chunk end before the
    target), the same run with copies at the stops timed too, and no lag or spread between shards
    on one thread."""
    from warpratchet.ensemble import default_threads
    from warpratchet.history import BLOCK_POINTS, BLOCKS, block_steps, copies_blocks, history_steps

    report = quick_benchmark("stop_cost.py")
    points, steps = report["points"], report["steps"]
    assert (points, steps) == (2_000, 3_000)
    assert not copies_blocks(points, min(points, BLOCK_POINTS), steps, BLOCKS)  # the run stops at blocks
    stops = set(history_steps(0, steps)) | set(block_steps(0, steps))
    assert [row["threads"] for row in report["rows"]] == sorted({1, default_threads()})
    for row in report["rows"]:
        assert row["chunks"] == len(stops)
        assert row["one_chunk_s"] > 0 and row["stopped_s"] > 0 and row["copies_s"] > 0
        assert row["shards_vs_one"] > 0
        for ratio in (row["ratio"], row["copies_ratio"]):
            assert ratio["min"] <= ratio["median"] <= ratio["max"]
        assert row["lag_first_us"] >= 0 and row["tail_us"] >= 0
        if row["threads"] == 1:
            assert row["lag_rest_us"] == row["spread_us"] == 0
        else:
            assert row["lag_rest_us"] > 0 and row["spread_us"] >= 0


def test_fig7_tenfold_benchmark_projects_the_figure_from_its_rate():
    """Smoke test of ``benchmarks/fig7_tenfold.py --quick``: 33 x 10^5 x 1.2e6 point-steps over the
    measured rate."""
    report = quick_benchmark("fig7_tenfold.py")
    assert report["figure_point_steps"] == 33 * 100_000 * 1_200_000
    assert report["orbits"] == 10_000 and report["steps"] >= 2000 and report["point_steps_per_second"] > 0
    rate = report["point_steps_per_second"]
    assert report["figure_seconds"] == pytest.approx(report["figure_point_steps"] / rate)
    with_all_cores = report["figure_seconds"] * report["cpu_use"]
    assert report["figure_seconds_with_all_cores"] == pytest.approx(with_all_cores)
    assert math.isfinite(report["A"]) and report["b2"] == pytest.approx(0.085)


def _contenders(monkeypatch: pytest.MonkeyPatch) -> Any:
    """``benchmarks/throughput_contenders.py``, imported for this test."""
    path = SCRIPT.parent / "throughput_contenders.py"
    spec = importlib.util.spec_from_file_location("throughput_contenders", path)
    contenders = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, contenders)  # its dataclasses look their module up
    spec.loader.exec_module(contenders)
    return contenders


@pytest.mark.skipif(not _has("avx2"), reason="the AVX2 code path needs an x86-64 CPU with AVX2")
def test_the_other_code_paths_rows_say_why_when_their_worker_cannot_start(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A child process that exits before it answers (here at once, status 3) makes the other code
    path's rows unavailable, with that reason, instead of stopping the benchmark."""
    from warpratchet import MapParams

    contenders = _contenders(monkeypatch)
    popen = subprocess.Popen
    monkeypatch.setattr(
        contenders.subprocess,
        "Popen",
        lambda args, **kw: popen([sys.executable, "-c", "raise SystemExit(3)"], **kw),
    )
    rows, build = contenders.other_path_contenders("avx2", MapParams(3.0, 0.1, 0.01), [1, 2], 1000)
    reason = "unavailable: the worker for the avx2 code path exited with status 3"
    assert build == reason
    keys = [contenders.path_key(key, "avx2") for key in ("warpratchet", "warpratchet_indicators")]
    assert [(r.key, r.threads, r.advance, r.unavailable) for r in rows] == [
        (key, t, None, reason) for key in keys for t in (1, 2)
    ]


def test_the_c_and_numba_contenders_take_another_force_bit_for_bit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The C contenders (``force.h`` from the table) and the Numba one (its branches from the
    table) on a force of 4 pieces with slopes 1, -1, 0 and 1/3: 2003 points x 300 steps from
    global step 5, every evolved field equal to warpratchet's bit for bit."""
    import numpy as np

    from warpratchet import Ensemble, MapParams
    from warpratchet.force import Force

    contenders = _contenders(monkeypatch)
    params = MapParams(3.0, table=Force.from_knots([0, 0.2, 0.5, 0.7], [0, 0.2, -0.1, -0.1]))
    rng = np.random.default_rng(3)
    x = rng.random(2003)
    x[:4] = [0.0, 0.2, 0.5, 0.7]  # the knots, where the pieces meet
    ens = Ensemble(params, x, rng.random(2003) - 2.0, threads=1)
    ens.step = 5
    start = ens.state()
    ens.run(300)
    expected = ens.state()
    rows = [
        *contenders.c_contenders(params, [2], tmp_path)[0],
        *contenders.c_simd_contenders("avx2", params, [2], tmp_path)[0],
        *contenders.c_simd_contenders("avx512", params, [2], tmp_path)[0],
        *contenders.numba_contenders(params, [2])[0],
    ]
    ran = 0
    for row in rows:
        if row.advance is None:
            assert row.unavailable.startswith("unavailable: ") and "gcc failed" not in row.unavailable
            continue
        got, _ = row.advance(start, 5, 300)
        ran += 1
        for name in contenders.EVOLVED:
            np.testing.assert_array_equal(
                got[name].view(np.int64), expected[name].view(np.int64), err_msg=f"{row.key} {name}"
            )
    assert ran >= (1 if shutil.which("gcc") else 0)
    assert np.count_nonzero(expected["winding"] != start["winding"]) > 100


def _benchmark_module(name: str, monkeypatch: pytest.MonkeyPatch) -> Any:
    """``benchmarks/NAME.py`` imported (its folder on ``sys.path`` for its own imports)."""
    folder = Path(__file__).resolve().parents[1] / "benchmarks"
    monkeypatch.syspath_prepend(str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# A function as objdump lists it: a loop (0x10-0x30, with the floor) inside a loop (0x08-0x40).
_CODE = [
    (0x00, "push", "%rbp"),
    (0x04, "mov", "%rsp,%rbp"),
    (0x08, "vaddpd", "%ymm0,%ymm1,%ymm1"),
    (0x10, "vmulpd", "%ymm2,%ymm1,%ymm3"),
    (0x18, "vroundpd", "$0x9,%ymm3,%ymm4"),
    (0x20, "vsubpd", "%ymm4,%ymm3,%ymm3"),
    (0x30, "jne", "10 <f+0x10>"),
    (0x34, "vsubpd", "%ymm4,%ymm3,%ymm3"),
    (0x40, "jne", "8 <f+0x8>"),
    (0x44, "ret", ""),
]


def test_kernel_profile_finds_where_the_loader_put_the_code(monkeypatch: pytest.MonkeyPatch) -> None:
    """The load address is the page-aligned base that puts every sample inside the function on one
    of its instructions; samples of other code are ignored, and a sample between two instructions
    rules a base out."""
    profile = _benchmark_module("kernel_profile", monkeypatch)
    starts = [address for address, _, _ in _CODE]
    base = 0x7F12_3456_7000
    elsewhere = 0x7F12_3456_5123  # another module's code, more sampled than any instruction here
    samples = {base + 0x18: 50, base + 0x20: 30, base + 0x34: 5, base: 1, elsewhere: 80}
    assert profile.find_base(samples, starts, 0, 0x45) == base
    assert profile.find_base({base + 0x18: 50, base + 0x19: 3}, starts, 0, 0x45) is None
    assert profile.find_base({elsewhere: 80}, starts, 0, 0x45) is None


def test_kernel_profile_counts_an_instruction_for_its_smallest_loop(monkeypatch: pytest.MonkeyPatch):
    """Shares by loop add up to 1 with the share in no loop: the inner loop (the step loop: it has
    the floor) owns its four instructions, the outer loop only its own three."""
    profile = _benchmark_module("kernel_profile", monkeypatch)
    loops, outside = profile.loop_shares(_CODE, {0x18: 50, 0x20: 30, 0x34: 10, 0x00: 10}, top=5)
    assert [(row["first"], row["last"], row["own_instructions"]) for row in loops] == [
        (0x10, 0x30, 4),
        (0x08, 0x40, 3),
    ]
    assert [row["step_loop"] for row in loops] == [True, False]
    assert [row["share"] for row in loops] == pytest.approx([0.8, 0.1])
    assert outside == pytest.approx(0.1)
    assert len(profile.loop_shares(_CODE, {0x18: 1}, top=1)[0]) == 1


def _perf_samples() -> bool:
    """Whether ``perf record`` can sample a process here (installed, allowed by
    ``kernel.perf_event_paranoid``) and ``objdump`` is there."""
    if shutil.which("perf") is None or shutil.which("objdump") is None:
        return False
    with tempfile.TemporaryDirectory() as tmp:
        command = ["perf", "record", "-q", "-e", "cpu-clock", "-o", f"{tmp}/data", "--", "true"]
        return subprocess.run(command, capture_output=True).returncode == 0


@pytest.mark.skipif(not _perf_samples(), reason="perf cannot sample processes here (or objdump is missing)")
def test_kernel_profile_benchmark_finds_the_kernels_step_loop():
    """Smoke test of ``benchmarks/kernel_profile.py --quick`` on the transport kernel (the one with
    the most loops): its samples land on its own code, and most of them in its step loop."""
    proc = benchmark("kernel_profile.py", "--quick", "--json", "--kernel", "transport")
    assert proc.returncode == 0, proc.stderr
    (row,) = json.loads(proc.stdout)["results"]
    assert row["kernel"] == "transport"
    assert row["samples_in_function"] > 0 and row["function_share_of_launches"] > 0
    assert row["base"] % 4096 == 0 and Path(row["object"]).exists()
    loops = row["loops"]
    assert loops[0]["step_loop"] and sum(loop["step_loop"] for loop in loops) == 1
    assert sum(loop["share"] for loop in loops) + row["outside_loops"] <= 1 + 1e-12


@pytest.mark.skipif(
    shutil.which("gcc") is None or platform.machine() not in ("x86_64", "AMD64"),
    reason="the FMA-bound probe needs gcc and an x86-64 CPU",
)
def test_core_sharing_benchmark_times_each_thread_on_one_and_two_threads():
    """Smoke test of ``benchmarks/core_sharing.py --quick`` (structure; no timing assertions): one
    rate for the single thread and two for the pair in every round, and their ratios."""
    report = quick_benchmark("core_sharing.py")
    assert report["rounds"] == 2 and len(report["one_thread"]) == 2
    for single, pair, ratio in zip(
        report["one_thread"], report["two_threads"], report["two_over_one"], strict=True
    ):
        assert single > 0 and len(pair) == 2 and all(rate > 0 for rate in pair)
        assert ratio == pytest.approx([rate / single for rate in pair])
