"""Files of released versions keep opening, inspecting and resuming (tests/data/README.md).

``tests/data/archive_v1.h5`` and ``tests/data/sweep_v1.h5`` were written by warpratchet 0.1.0,
``archive_v2.h5`` and ``sweep_v2.h5`` by format v2 before issue 15 (no ``/history``, no verdict
columns), ``archive_v2_0.h5`` by format 2.0 with its history (before the CF attributes and named
dimensions of 2.1), ``archive_v2_1.h5`` by format 2.1; they stand for files users already have.
They are opened read-only in place (and checked to be byte for byte unchanged afterwards) and
resumed only from copies.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from support import exact_rows, in_process, same_state

from warpratchet import Ensemble, MapParams, open_archive, summarize
from warpratchet.archive import SERIES_FIELDS, SNAPSHOT_FIELDS, ArchiveSink, run_to
from warpratchet.cli import main
from warpratchet.history import history_steps
from warpratchet.sweep import read_sweep
from warpratchet.sweep._records import ADDED_COLUMNS

DATA = Path(__file__).resolve().parents[1] / "data"
ARCHIVE, SWEEP = DATA / "archive_v1.h5", DATA / "sweep_v1.h5"
ARCHIVE_V2, SWEEP_V2 = DATA / "archive_v2.h5", DATA / "sweep_v2.h5"
ARCHIVE_V2_0, ARCHIVE_V2_1 = DATA / "archive_v2_0.h5", DATA / "archive_v2_1.h5"
#: The run that wrote archive_v1.h5 (tests/data/README.md; seed 0 is the CLI's default).
PARAMS, POINTS, SEED, STEPS = MapParams(3.0, 0.1, 0.01), 200, 0, 512
SCHEDULE = {"chunk_steps": 64, "snapshot_every": 128, "snapshot_points": 50, "checkpoint_every": 256}
#: Series columns that depend on the machine, not on the dynamics.
CLOCKS = ("wall_time", "unix_time")


def fresh() -> Ensemble:
    return Ensemble.sample(PARAMS, POINTS, "strip", seed=SEED)


def archived_run(path: Path, steps: int) -> Ensemble:
    """A fresh archive of the fixture's run, to ``steps`` steps, with today's code."""
    ens = fresh()
    with ArchiveSink(path, ens, **SCHEDULE) as sink:
        ens.run(steps, [sink], chunk_steps=sink.chunk_steps)
    return ens


@pytest.fixture(autouse=True)
def fixtures_untouched():
    """No test may change a fixture file, not even by opening it."""
    files = (ARCHIVE, SWEEP, ARCHIVE_V2, SWEEP_V2, ARCHIVE_V2_0, ARCHIVE_V2_1)
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}
    yield
    after = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}
    assert after == before


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, Ensemble]:
    """Today's archive of the same run, to 1024 steps (twice the fixture's)."""
    path = tmp_path_factory.mktemp("ref") / "ref.h5"
    return path, archived_run(path, 2 * STEPS)


def test_archive_v1_opens_with_its_run(reference):
    with open_archive(ARCHIVE) as arc, open_archive(reference[0]) as ref:
        assert arc.format_version == 1 and arc.params == PARAMS and arc.versions["warpratchet"] == "0.1.0"
        s = arc.settings
        assert (s["points"], s["sampler"], s["seed"], s["threshold"]) == (POINTS, "strip", SEED, None)
        assert {k: s[k] for k in SCHEDULE} == SCHEDULE
        assert arc.initial_step == 0 and arc.checkpoint_step == STEPS
        # The numbers README.md of tests/data quotes, as the 0.1.0 run printed them.
        last = arc.latest()
        assert (last["step"], last["chaotic_points"]) == (STEPS, 197)
        assert last["A"] == 0.14617400228230937 and last["A_stderr"] == 0.005873036274085623
        assert last["threshold"] == 0.14137352783280288
        # Rows, snapshots and the checkpoint are those of today's run, bit for bit.
        rows, want = arc.series, ref.series
        assert list(rows["step"]) == list(range(64, STEPS + 1, 64))
        for name in SERIES_FIELDS:
            if name not in CLOCKS:
                assert np.array_equal(rows[name], want[name][: arc.rows], equal_nan=True), name
        snaps, want_snaps = arc.snapshots, ref.snapshots
        assert list(snaps.steps) == [128, 256, 384, 512]
        assert np.array_equal(snaps.indices, want_snaps.indices)
        for name in SNAPSHOT_FIELDS:
            assert np.array_equal(getattr(snaps, name), getattr(want_snaps, name)[: len(snaps)]), name
        assert same_state(arc.initial, fresh().state())
        assert same_state(arc.ensemble(threads=1).state(), fresh().run(STEPS, chunk_steps=64).state())


def test_inspect_prints_archive_v1(capfd):
    proc = in_process(capfd, "inspect", str(ARCHIVE), "--json")
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    keys = {"path", "format", "format_version", "created", "params", "settings", "versions"}
    keys |= {"initial_step", "checkpoint_step", "rows", "snapshots", "latest", "A_theory"}
    assert keys <= set(info)
    assert (info["format"], info["format_version"], info["checkpoint_step"]) == (
        "warpratchet-archive",
        1,
        STEPS,
    )
    assert (info["rows"], info["snapshots"], info["params"]["K"]) == (8, 4, 3.0)
    assert info["latest"]["A"] == 0.14617400228230937
    assert info["format_minor"] == 0  # absent in version 1
    proc = in_process(capfd, "inspect", str(ARCHIVE))
    assert proc.returncode == 0, proc.stderr
    assert "checkpoint at step 512" in proc.stdout and "K = 3.0" in proc.stdout


def test_archive_v1_resumes_bit_for_bit(tmp_path, reference):
    """Resumed to 1024 steps: the state, rows and snapshots of an uninterrupted run of today."""
    path = tmp_path / "v1.h5"
    shutil.copy(ARCHIVE, path)
    sink, ens = ArchiveSink.resume(path, threads=1)
    with sink:
        assert ens.step == STEPS and sink.chunk_steps == 64
        run_to(ens, 2 * STEPS, [sink], sink.chunk_steps)
    uninterrupted = fresh().run(2 * STEPS, chunk_steps=64)
    assert same_state(ens.state(), uninterrupted.state())
    with open_archive(path) as arc, open_archive(reference[0]) as ref:
        assert arc.checkpoint_step == 2 * STEPS and arc.versions["warpratchet"] == "0.1.0"
        assert same_state(arc.ensemble().state(), uninterrupted.state())
        for name in SERIES_FIELDS:
            if name not in CLOCKS:
                assert np.array_equal(arc.series[name], ref.series[name], equal_nan=True), name
        for name in ("steps", "indices", *SNAPSHOT_FIELDS):
            assert np.array_equal(getattr(arc.snapshots, name), getattr(ref.snapshots, name)), name
        assert "finite_time_acceleration" in arc.h5["snapshots"] and "A" not in arc.h5["snapshots"]


def test_cli_resumes_archive_v1(tmp_path, capsys):
    path = tmp_path / "v1.h5"
    shutil.copy(ARCHIVE, path)
    assert main(["resume", str(path), "--steps", "1024", "--K", "3", "--seed", "0", "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    expect = summarize(fresh().run(2 * STEPS).state(), 2 * STEPS)
    assert report["steps"] == 2 * STEPS and report["A"] == expect.A and report["lyapunov"] == expect.lyapunov


@pytest.mark.parametrize("version", [1, 2])
def test_sweep_files_read_their_rows(version, tmp_path, capsys):
    """Every column as written, floats bit for bit (JSON keeps every digit of a float64); the columns
    added since (the verdict of issue 15, ``records.ADDED_COLUMNS``) read as not recorded; the same
    sweep computes nothing and leaves the rows as they were."""
    path = DATA / f"sweep_v{version}.h5"
    rows = read_sweep(path)
    want = json.loads((DATA / f"sweep_v{version}.json").read_text())
    assert len(rows) == len(want) == 2
    assert exact_rows(rows, skip=ADDED_COLUMNS) == exact_rows(want)
    assert exact_rows([{k: row[k] for k in ADDED_COLUMNS} for row in rows]) == exact_rows([ADDED_COLUMNS] * 2)
    for row in rows:
        added = {k: row[k] for k in ADDED_COLUMNS}
        assert added["verdict"] == "" and added["threshold_rule"] == "strict"
        assert all(
            math.isnan(added[k]) for k in ("A_stderr_robust", "drift", "drift_z", "diffusion_exponent")
        )
    copy = tmp_path / path.name
    shutil.copy(path, copy)
    args = [
        "sweep",
        "--path",
        "maximal",
        "--K",
        "3",
        "--b2",
        "0.02:0.04:2",
        "--points",
        "200",
        "--steps",
        "512",
    ]
    assert main([*args, "--out", str(copy), "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"2 points: 0 computed, 2 read from {copy}"
    assert exact_rows(read_sweep(copy), skip=ADDED_COLUMNS) == exact_rows(want)


def test_archive_v2_without_history_opens_and_resumes_with_a_verdict(tmp_path, capsys):
    """An archive written before /history: no history to read; resumed, it reports the session's
    history and the verdict (not archived: the file keeps its layout), and the state of today's run."""
    with open_archive(ARCHIVE_V2) as arc:
        assert arc.format_version == 2 and arc.features == () and arc.history is None
        assert arc.checkpoint_step == STEPS and arc.settings["threshold_rule"] == "strict"
        # The file stores the indicator under its former name, classifier.
        assert "classifier" in arc.h5["settings"].attrs and "classifier" not in arc.settings
        assert arc.settings["indicator"] == "ftle" and arc.spec.indicator == "ftle"
        with pytest.raises(ValueError, match="has no history"):
            arc.to_pandas("history")
    path = tmp_path / "v2.h5"
    shutil.copy(ARCHIVE_V2, path)
    assert main(["resume", str(path), "--steps", str(4 * STEPS), "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["history"]["step"] == history_steps(STEPS, 4 * STEPS)  # this session's rows
    assert report["verdict"] in ("converged", "drifting") and report["A_stderr_robust"] is None  # no blocks
    expect = summarize(fresh().run(4 * STEPS).state(), 4 * STEPS)
    assert report["A"] == expect.A == report["history"]["A"][-1]
    with open_archive(path) as arc:
        assert arc.features == () and arc.history is None and arc.checkpoint_step == 4 * STEPS


def test_archive_v2_0_opens_exports_and_resumes_as_today(tmp_path):
    """Format 2.0 (fixed-length strings, no CF attributes, phony dimensions in /initial) reads as
    before; a resume rebuilds it in today's format (2.2) and continues today's run bit for bit."""
    with open_archive(ARCHIVE_V2_0) as arc:
        assert arc.format_version == 2 and "format_minor" not in arc.h5.attrs
        assert arc.settings["init"] == "strip" and arc.features == ("history",)
        assert arc.checkpoint_step == STEPS and arc.history is not None
        assert arc.params == PARAMS
    want = fresh().run(4 * STEPS).state()
    path = tmp_path / "v2_0.h5"
    shutil.copy(ARCHIVE_V2_0, path)
    assert main(["resume", str(path), "--steps", str(4 * STEPS), "--quiet", "--json"]) == 0
    with open_archive(path) as arc:
        assert arc.h5.attrs["format_minor"] == 2 and arc.h5.attrs["Conventions"] == "CF-1.8"
        assert same_state(arc.checkpoint()[0], want)


@pytest.mark.parametrize("path", [ARCHIVE, ARCHIVE_V2, ARCHIVE_V2_0, ARCHIVE_V2_1], ids=lambda p: p.stem)
def test_former_snapshot_name_reads_as_today(path):
    """Files before format 2.2 store each point's A_n as /snapshots/A: the reader and the xarray
    export name it ``finite_time_acceleration``, the same values and units."""
    xr = pytest.importorskip("xarray", reason="the xarray extra is not installed")
    with open_archive(path) as arc:
        stored = arc.h5["snapshots"]
        assert "A" in stored and "finite_time_acceleration" not in stored
        snaps = arc.snapshots
        assert len(snaps) == 4
        assert np.array_equal(snaps.finite_time_acceleration, stored["A"][: len(snaps)])
        exported = arc.to_xarray("snapshots")
        assert "A" not in exported.variables and isinstance(exported, xr.Dataset)
        assert np.array_equal(exported["finite_time_acceleration"].values, snaps.finite_time_acceleration)
        assert exported["finite_time_acceleration"].attrs["units"] == "1/iteration"


def _same_run(arc, ref) -> None:
    """The rows and snapshots of ``arc`` are the first ones of today's ``ref``, bit for bit."""
    for name in SERIES_FIELDS:
        if name not in CLOCKS:
            assert np.array_equal(arc.series[name], ref.series[name][: arc.rows], equal_nan=True), name
    snaps, want = arc.snapshots, ref.snapshots
    assert np.array_equal(snaps.indices, want.indices)
    for name in ("steps", *SNAPSHOT_FIELDS):
        assert np.array_equal(getattr(snaps, name), getattr(want, name)[: len(snaps)]), name


def test_archive_v2_1_opens_verifies_and_exports(reference, capsys):
    """Format 2.1: today's run bit for bit, every checksum good, the snapshots exported whole."""
    xr = pytest.importorskip("xarray", reason="the xarray extra is not installed")
    with open_archive(ARCHIVE_V2_1) as arc, open_archive(reference[0]) as ref:
        assert arc.format_version == 2 and arc.h5.attrs["format_minor"] == 1 == arc.format_minor
        assert arc.features == ("history",) and arc.checkpoint_step == STEPS and arc.params == PARAMS
        _same_run(arc, ref)
        exported = arc.to_xarray("snapshots")
        for name in SNAPSHOT_FIELDS:
            assert np.array_equal(exported[name].values, getattr(arc.snapshots, name)), name
        assert list(arc.to_pandas().index) == list(arc.series["step"])
    with xr.open_dataset(ARCHIVE_V2_1, group="snapshots", engine="h5netcdf") as raw:
        assert np.array_equal(raw["ftle"].values, exported["ftle"].values)
        assert "A" in raw.variables and "finite_time_acceleration" not in raw.variables  # as stored
        assert np.array_equal(raw["A"].values, exported["finite_time_acceleration"].values)
    assert main(["verify", str(ARCHIVE_V2_1)]) == 0
    assert main(["inspect", str(ARCHIVE_V2_1)]) == 0
    out = capsys.readouterr().out
    assert "checkpoint at step 512" in out and "warpratchet-archive v2.1," in out


def test_archive_v2_1_resumes_bit_for_bit(tmp_path, reference):
    """Resumed to 1024 steps: the state, rows and snapshots of an uninterrupted run of today, in a
    file that verify accepts."""
    path = tmp_path / "v2_1.h5"
    shutil.copy(ARCHIVE_V2_1, path)
    sink, ens = ArchiveSink.resume(path, threads=1)
    with sink:
        assert ens.step == STEPS and sink.chunk_steps == 64
        run_to(ens, 2 * STEPS, [sink, sink.history], sink.chunk_steps)
    uninterrupted = fresh().run(2 * STEPS, chunk_steps=64)
    assert same_state(ens.state(), uninterrupted.state())
    with open_archive(path) as arc, open_archive(reference[0]) as ref:
        assert arc.checkpoint_step == 2 * STEPS and arc.rows == ref.rows
        assert same_state(arc.ensemble().state(), uninterrupted.state())
        _same_run(arc, ref)
        # Rebuilt in today's format: one name for the snapshots' A_n, never both.
        assert arc.h5.attrs["format_minor"] == 2
        assert "finite_time_acceleration" in arc.h5["snapshots"] and "A" not in arc.h5["snapshots"]
    assert main(["verify", str(path)]) == 0
