"""Parameter sweeps: paths, per-point seeds, the HDF5 sweep file, resume, Dask, and the CLI."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
from support import benchmark, bits, exact_rows

from warpratchet import Ensemble, summarize, theory
from warpratchet import sweep as sweep_module
from warpratchet.cli import main
from warpratchet.sweep import (
    ROW_FIELDS,
    TIMING_FIELDS,
    SweepSpec,
    fixed_b1_path,
    grid_points,
    k_path,
    line_path,
    maximal_path,
    point_seed,
    read_definition,
    read_sweep,
    run_point,
    run_sweep,
)

# Small enough that a point takes a few milliseconds: these tests check bookkeeping, not physics.
SPEC = SweepSpec(points=400, steps=3000, init="strip", seed=5)
# Domain LR, domain R at K = 3, and a K = 2.99 point (Fig. 9) where the theory has no A.
POINTS = maximal_path([0.01, 0.1]) + line_path(1 / 3, [0.08]) + fixed_b1_path(0.25, [0.05], K=2.99)


def _physics(rows):
    """Rows without the timing fields (which differ between runs), compared bit for bit."""
    return exact_rows(rows, skip=TIMING_FIELDS)


@pytest.fixture(scope="module")
def reference_rows():
    return run_sweep(POINTS, SPEC, progress=False)


# -- paths ----------------------------------------------------------------------------------------
def test_paths_follow_the_papers_definitions():
    b2 = [0.005, 0.05, 1 / 6]
    for p, b in zip(maximal_path(b2), b2, strict=True):
        assert (p.K, p.b1, p.b2) == (3.0, theory.b1_on_maximal_path(b), b)  # Eq. (b2max)
    for p, b in zip(line_path(1 / 3, b2, K=2.5), b2, strict=True):
        assert (p.K, p.b1, p.b2) == (2.5, b / (1 / 3), b)  # Eq. (Ama)
    assert [(p.K, p.b1, p.b2) for p in fixed_b1_path(0.25, [0.005, 0.14], K=2.99)] == [
        (2.99, 0.25, 0.005),
        (2.99, 0.25, 0.14),
    ]
    assert [p.K for p in k_path([2.5, 3.0, 3.5], 0.1, 0.01)] == [2.5, 3.0, 3.5]
    with pytest.raises(ValueError, match="b2 = 0.2 is outside"):
        maximal_path([0.1, 0.2])
    with pytest.raises(ValueError, match="a = -1.0"):
        line_path(-1.0, [0.1])


def test_grid_skips_impossible_pairs_and_masks_domains():
    b1, b2 = [0.01, 0.1, 0.5, 0.9], [0.01, 0.5]
    full = grid_points(b1, b2)
    # (0.5, 0.5) and (0.9, 0.5) have b1 + b2 >= 1: no map (Eq. fx).
    assert [(p.b1, p.b2) for p in full] == [
        (0.01, 0.01),
        (0.01, 0.5),
        (0.1, 0.01),
        (0.1, 0.5),
        (0.5, 0.01),
        (0.9, 0.01),
    ]
    lr = grid_points(b1, b2, domain="LR")
    assert lr == [p for p in full if theory.domain(p) == "LR"] == grid_points(b1, b2, domain={"LR"})
    assert 0 < len(lr) < len(full)
    assert grid_points(b1, b2, domain={"LR", "L", "R", "none"}) == full
    with pytest.raises(ValueError, match="'XY'"):
        grid_points(b1, b2, domain="XY")


def test_spec_rejects_bad_values_by_name():
    with pytest.raises(ValueError, match="points = 0 is outside"):
        SweepSpec(points=0)
    with pytest.raises(ValueError, match="steps = 1.5"):
        SweepSpec(steps=1.5)
    with pytest.raises(ValueError, match="init = 'disc'"):
        SweepSpec(init="disc")
    with pytest.raises(ValueError, match="threshold = nan"):
        SweepSpec(threshold=math.nan)
    with pytest.raises(ValueError, match="at least 1 point"):
        run_sweep([], SPEC, progress=False)
    with pytest.raises(ValueError, match="threads = 0 is outside"):
        run_sweep(POINTS[:1], SPEC, progress=False, threads=0)
    with pytest.raises(ValueError, match="client = 3 is neither"):
        run_sweep(POINTS[:1], SPEC, progress=False, client=3)


# -- rows -----------------------------------------------------------------------------------------
def test_point_seeds_are_the_spawned_children_of_the_root_seed():
    children = np.random.SeedSequence(7).spawn(3)
    seeds = [point_seed(7, i) for i in range(3)]
    assert seeds == [int(c.generate_state(1, np.uint64)[0] >> np.uint64(11)) for c in children]
    assert len(set(seeds)) == 3 and all(0 <= s < 2**53 for s in seeds)


def test_rows_summarise_the_ensemble_their_seed_rebuilds(reference_rows):
    assert [row["index"] for row in reference_rows] == list(range(len(POINTS)))
    for row, p in zip(reference_rows, POINTS, strict=True):
        assert list(row) == list(ROW_FIELDS)
        assert (row["K"], row["b1"], row["b2"], row["domain"]) == (p.K, p.b1, p.b2, theory.domain(p))
        assert row["seed"] == point_seed(SPEC.seed, row["index"])
        if p.K == 3.0:
            assert row["A_theory"] == theory.acceleration(p)
        else:
            assert math.isnan(row["A_theory"])
    assert [row["domain"] for row in reference_rows] == ["LR", "LR", "R", "R"]
    # The stored seed alone rebuilds the point's ensemble: its summary is the row, bit for bit.
    row, p = reference_rows[2], POINTS[2]
    ens = Ensemble.sample(p, SPEC.points, SPEC.init, row["seed"], threads=1).run(SPEC.steps)
    s = summarize(ens.state(), ens.step)
    assert bits(s.A) == bits(row["A"]) and bits(s.lyapunov) == bits(row["lyapunov"])
    assert bits(s.threshold) == bits(row["threshold"])  # the threshold used, the default resolved
    assert s.chaotic_points == row["chaotic_points"]
    assert _physics([run_point(p, SPEC, 2, threads=1)]) == _physics([row])


# -- executors ------------------------------------------------------------------------------------
def test_dask_local_cluster_gives_the_local_rows_bit_for_bit(tmp_path, reference_rows, monkeypatch):
    import distributed

    local_file, dask_file = tmp_path / "local.h5", tmp_path / "dask.h5"
    local = run_sweep(POINTS, SPEC, out=local_file, progress=False)
    # No ensemble may run in this process from here on: the Dask rows must come from the workers.
    monkeypatch.setattr(sweep_module._run, "Ensemble", None)
    with (
        distributed.LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        on_dask = run_sweep(POINTS, SPEC, out=dask_file, client=client, progress=False)
        # An address string connects (and disconnects) a client of its own.
        by_address = run_sweep(POINTS, SPEC, client=cluster.scheduler_address, progress=False)
        worker_pids = set(client.run(os.getpid).values())
    assert len(worker_pids) == 2 and os.getpid() not in worker_pids
    expected = _physics(reference_rows)
    assert _physics(local) == expected
    assert _physics(on_dask) == expected
    assert _physics(by_address) == expected
    assert _physics(read_sweep(local_file)) == _physics(read_sweep(dask_file)) == expected
    assert all(row["seconds"] > 0 for row in on_dask)


# -- the sweep file, interruption and resume -----------------------------------------------------
class _Stop(Exception):
    pass


def test_interrupted_sweep_resumes_computing_only_missing_points(tmp_path, reference_rows):
    out = tmp_path / "sweep.h5"

    def stop_after_two(row):
        if row["index"] == 1:
            raise _Stop

    with pytest.raises(_Stop):
        run_sweep(POINTS, SPEC, out=out, progress=False, on_row=stop_after_two)
    first = read_sweep(out)
    assert [row["index"] for row in first] == [0, 1]
    # A crash between writing a record and counting it leaves a stray record past rows_valid.
    with h5py.File(out, "r+") as f:
        f["rows"].resize((3,))
        f["rows"][2] = np.zeros((), dtype=f["rows"].dtype)
    assert exact_rows(read_sweep(out)) == exact_rows(first)

    computed = []
    rows = run_sweep(POINTS, SPEC, out=out, progress=False, on_row=computed.append)
    assert [row["index"] for row in computed] == [2, 3]
    assert exact_rows(rows[:2]) == exact_rows(first)  # identical seconds too: read back, not recomputed
    assert _physics(rows) == _physics(read_sweep(out)) == _physics(reference_rows)
    # A finished sweep is all resume: nothing left to compute.
    computed.clear()
    again = run_sweep(POINTS, SPEC, out=out, progress=False, on_row=computed.append)
    assert exact_rows(again) == exact_rows(rows)
    assert computed == []


def test_sweep_killed_with_sigkill_resumes(tmp_path, reference_rows):
    out = tmp_path / "killed.h5"
    script = textwrap.dedent(
        f"""
        import os, signal
        from warpratchet.sweep import SweepSpec, maximal_path, line_path, fixed_b1_path, run_sweep
        points = maximal_path([0.01, 0.1]) + line_path(1 / 3, [0.08]) + fixed_b1_path(0.25, [0.05], K=2.99)
        def die(row):
            if row["index"] == 2:
                os.kill(os.getpid(), signal.SIGKILL)
        run_sweep(points, SweepSpec(**{SPEC.as_dict()!r}), out={str(out)!r}, progress=False, on_row=die)
        """
    )
    killed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=900)
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    assert [row["index"] for row in read_sweep(out)] == [0, 1, 2]
    assert read_definition(out) == (POINTS, SPEC)

    computed = []
    rows = run_sweep(POINTS, SPEC, out=out, progress=False, on_row=computed.append)
    assert [row["index"] for row in computed] == [3]
    assert _physics(rows) == _physics(reference_rows)


def test_a_file_holding_anything_else_is_never_overwritten(tmp_path):
    out = tmp_path / "sweep.h5"
    run_sweep(POINTS[:2], SPEC, out=out, progress=False)
    before = out.read_bytes()
    with pytest.raises(ValueError, match="steps is 3000 in the file, 4000 requested"):
        run_sweep(POINTS[:2], SweepSpec(points=400, steps=4000, seed=5), out=out, progress=False)
    with pytest.raises(ValueError, match="point 1 is"):
        run_sweep([POINTS[0], POINTS[2]], SPEC, out=out, progress=False)
    with pytest.raises(ValueError, match="the file has 2 points, 3 requested"):
        run_sweep(POINTS[:3], SPEC, out=out, progress=False)
    assert out.read_bytes() == before

    other = tmp_path / "data.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.arange(3)
    text = tmp_path / "notes.h5"
    text.write_text("my notes\n")
    for path in (other, text):
        content = path.read_bytes()
        with pytest.raises(ValueError, match="not .*sweep file.*force"):
            run_sweep(POINTS[:1], SPEC, out=path, progress=False)
        assert path.read_bytes() == content

    with pytest.raises(ValueError, match="data.h5 is not a warpratchet sweep file"):
        read_sweep(other)
    with pytest.raises(ValueError, match="cannot read sweep file .*notes.h5"):
        read_sweep(text)
    replaced = run_sweep(POINTS[:1], SPEC, out=other, progress=False, force=True)
    assert _physics(read_sweep(other)) == _physics(replaced)


# -- command line ---------------------------------------------------------------------------------
def test_cli_json_rows_and_resume(tmp_path, capsys):
    out = tmp_path / "cli.h5"
    args = ["sweep", "--path", "fixed-b1", "--K", "2.99", "--b1", "0.25", "--b2", "0.05:0.1:2"]
    args += ["--points", "300", "--steps", "2000", "--out", str(out), "--quiet"]
    assert main(args + ["--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert list(printed) == ["rows"]
    assert [list(row) for row in printed["rows"]] == [list(ROW_FIELDS)] * 2
    assert [row["b2"] for row in printed["rows"]] == [0.05, 0.1]  # both ends included
    assert all(row["A_theory"] is None for row in printed["rows"])  # K != 3: no closed form, null
    assert printed["rows"] == json.loads(json.dumps(read_sweep(out)).replace("NaN", "null"))

    assert main(args) == 0  # same sweep, same file: resumed, nothing to compute
    assert capsys.readouterr().out.splitlines()[-1] == f"2 points: 0 computed, 2 read from {out}"

    changed = [a if a != "2000" else "3000" for a in args]
    assert main(changed) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "steps is 2000 in the file, 3000 requested" in err and "--force" in err
    assert main(changed + ["--force"]) == 0
    assert read_definition(out)[1].steps == 3000


# -- benchmark smoke test -------------------------------------------------------------------------
def test_sweep_scaling_benchmark_runs_every_executor_with_identical_rows():
    sizes = ["--sweep-points", "2", "--points", "200", "--steps", "200"]
    done = benchmark("sweep_scaling.py", "--quick", "--json", *sizes)
    assert done.returncode == 0, done.stderr[-3000:]
    assert len(done.stdout.strip().splitlines()) == 1
    report = json.loads(done.stdout)
    cores = report["machine"]["cores"]
    local = [("local", None, t) for t in sorted({cores, 1}, reverse=True)]
    expected = [(p, *e) for p in ("work", "tiny") for e in local]
    expected += [(p, "dask", w, 1) for w in (1, 2) for p in ("work", "tiny")]
    results = report["results"]
    assert [(r["problem"], r["executor"], r["workers"], r["threads_per_point"]) for r in results] == expected
    assert report["rows_identical"] is True and all(r["rows_identical"] for r in results)
    for r in results:
        assert r["points_per_minute"] == pytest.approx(60 * r["sweep_points"] / r["seconds"], rel=1e-12)
    by_workers = {r["workers"]: r for r in results if r["problem"] == "work" and r["executor"] == "dask"}
    assert report["speedup_2_vs_1_workers"] == pytest.approx(
        by_workers[2]["points_per_minute"] / by_workers[1]["points_per_minute"], rel=1e-12
    )
