"""Files of released versions keep opening, inspecting and resuming (tests/data/README.md).

``tests/data/archive_v1.h5`` and ``tests/data/sweep_v1.h5`` were written by warpratchet 0.1.0;
they stand for files users already have. They are opened read-only in place (and checked to be
byte for byte unchanged afterwards) and resumed only from copies.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from support import cli, same_state

from warpratchet import Ensemble, MapParams, open_archive, summarize
from warpratchet.archive import SERIES_FIELDS, SNAPSHOT_FIELDS, ArchiveSink, run_to
from warpratchet.cli import main
from warpratchet.sweep import read_sweep

DATA = Path(__file__).resolve().parent / "data"
ARCHIVE, SWEEP = DATA / "archive_v1.h5", DATA / "sweep_v1.h5"
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
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (ARCHIVE, SWEEP)}
    yield
    after = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (ARCHIVE, SWEEP)}
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


def test_inspect_prints_archive_v1():
    proc = cli("inspect", str(ARCHIVE), "--json")
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
    proc = cli("inspect", str(ARCHIVE))
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


def test_cli_resumes_archive_v1(tmp_path, capsys):
    path = tmp_path / "v1.h5"
    shutil.copy(ARCHIVE, path)
    assert main(["resume", str(path), "--steps", "1024", "--K", "3", "--seed", "0", "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    expect = summarize(fresh().run(2 * STEPS).state(), 2 * STEPS)
    assert report["steps"] == 2 * STEPS and report["A"] == expect.A and report["lyapunov"] == expect.lyapunov


def test_sweep_v1_reads_its_rows():
    rows = read_sweep(SWEEP)
    want = json.loads((DATA / "sweep_v1.json").read_text())
    assert len(rows) == len(want) == 2
    assert rows == want  # every column, floats exactly (JSON keeps every digit of a float64)
