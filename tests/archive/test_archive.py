"""HDF5 run archives: layout, exact restart, refusal of bad input, truncation and corruption.

The SIGKILL acceptance test is in test_archive_kill.py.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
from support import (
    ARCHIVE_DOC,
    Capture,
    assert_one_line_error,
    documented_names,
    documented_optional,
    in_process,
    quick_benchmark,
    refused,
    run_argv,
    same_state,
    written_names,
)

from warpratchet import Ensemble, MapParams, Observer, finite_time_acceleration, open_archive, summarize
from warpratchet.archive import (
    SERIES_FIELDS,
    ArchiveError,
    ArchiveSink,
    ArchiveWarning,
    run_to,
    schedule,
)
from warpratchet.cli import main
from warpratchet.history import History

PARAMS = MapParams(3.0, 0.1, 0.01)
POINTS = 300
SEED = 5
#: Snapshots and several checkpoints in a 1000-step run.
SCHEDULE = {"snapshot_every": 200, "snapshot_points": 40, "checkpoint_every": 400, "chunk_steps": 100}
#: Series columns that depend on the machine, not on the dynamics.
CLOCKS = ("wall_time", "unix_time")


def fresh() -> Ensemble:
    return Ensemble.sample(PARAMS, POINTS, "strip", SEED)


def record(path, steps, *, run_steps=None, history=False, **kw):
    """An archived run of ``steps`` steps (with a /history if ``history``); returns the ensemble and
    the captured states."""
    ens = fresh()
    cap = Capture()
    kept = History(kw.get("threshold")) if history else None
    with ArchiveSink(path, ens, history=kept, **kw) as sink:
        ens.run(steps, [cap, sink] + ([kept] if kept else []), chunk_steps=sink.chunk_steps)
    return ens, cap.states


def same_series(a: dict, b: dict) -> bool:
    return all(np.array_equal(a[k], b[k], equal_nan=True) for k in SERIES_FIELDS if k not in CLOCKS)


@pytest.fixture(scope="module")
def archived(tmp_path_factory):
    """A finished archive with snapshots, several checkpoints and a history (as ``warpratchet run``
    writes), plus the states of its run."""
    path = tmp_path_factory.mktemp("arc") / "run.h5"
    ens, states = record(path, 1000, history=True, **SCHEDULE)
    return path, ens, states


@pytest.fixture(scope="module")
def killed(tmp_path_factory, archived):
    """The same run as a killed writer leaves it: still marked open for SWMR writing."""
    folder = tmp_path_factory.mktemp("killed")
    ens = fresh()
    with ArchiveSink(folder / "live.h5", ens, **SCHEDULE) as sink:
        ens.run(1000, [sink], chunk_steps=sink.chunk_steps)
        shutil.copy(folder / "live.h5", folder / "run.h5")  # the bytes on disk of a live archive
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(folder / "run.h5", "r")
    return folder / "run.h5", ens, archived[2]


# -- contents and exact restart -------------------------------------------------------------------
def test_archive_holds_the_run(archived):
    path, ens, states = archived
    with open_archive(path) as arc:
        assert arc.params == PARAMS
        s = arc.settings
        assert (s["points"], s["init"], s["seed"], s["chunk_steps"]) == (POINTS, "strip", SEED, 100)
        assert (s["checkpoint_every"], s["snapshot_every"], s["snapshot_points"]) == (400, 200, 40)
        assert s["threshold"] is None and s["dtype"] == "float64" and s["renorm_check_every"] == 8
        assert {"warpratchet", "warp", "numpy", "h5py"} <= set(arc.versions)
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", arc.created)
        series = arc.series
        assert list(series["step"]) == list(range(100, 1001, 100))
        for row, step in enumerate(series["step"]):  # each row is the summary of its chunk
            expect = summarize(states[int(step)], int(step))
            assert series["A"][row] == expect.A and series["A_stderr"][row] == expect.A_stderr
            assert series["lyapunov"][row] == expect.lyapunov
            assert series["chaotic_fraction"][row] == expect.chaotic_fraction
        assert np.all(series["wall_time"] > 0)
        snaps = arc.snapshots
        assert list(snaps.steps) == [200, 400, 600, 800, 1000]
        acc = snaps.finite_time_acceleration
        assert snaps.x.shape == snaps.p.shape == snaps.ftle.shape == acc.shape == (5, 40)
        assert np.all(np.diff(snaps.indices) > 0) and snaps.indices[-1] < POINTS
        for row, step in enumerate(snaps.steps):
            st = states[int(step)]
            assert np.array_equal(snaps.x[row], st["x"][snaps.indices])
            assert np.array_equal(snaps.p[row], st["q"][snaps.indices])
        assert np.all((snaps.p >= 0) & (snaps.p < 1))
        assert arc.checkpoint_step == 1000
        restored = arc.ensemble(threads=1)
        assert restored.step == 1000 and same_state(restored.state(), ens.state())
        assert same_state(arc.initial, states[0])


def test_snapshots_name_each_points_acceleration_apart_from_the_mean(archived):
    """Each point's A_n of Eq. (An) is ``finite_time_acceleration`` (the API's name) in the file and
    in the reader; ``A`` is only the ensemble's mean, in /series; format 2.2."""
    path, _, states = archived
    with h5py.File(path, "r") as f:
        assert f.attrs["format_minor"] == 2
        assert "finite_time_acceleration" in f["snapshots"] and "A" not in f["snapshots"]
        assert "A" in f["series"] and "finite_time_acceleration" not in f["series"]
        assert "Eq. (An) of each point" in f["snapshots/finite_time_acceleration"].attrs["long_name"]
    with open_archive(path) as arc:
        snaps = arc.snapshots
        for row, step in enumerate(snaps.steps):
            want = finite_time_acceleration(states[int(step)], int(step))[snaps.indices]
            assert np.array_equal(snaps.finite_time_acceleration[row], want), step
        with pytest.warns(DeprecationWarning, match="Snapshots.A is spelled Snapshots.finite_time_accel"):
            assert snaps.A is snaps.finite_time_acceleration


def test_snapshots_empty_without_schedule(tmp_path):
    record(tmp_path / "a.h5", 50, chunk_steps=25)
    with open_archive(tmp_path / "a.h5") as arc:
        snaps = arc.snapshots
        assert len(snaps) == 0 and snaps.x.shape == (0, 0) and snaps.indices.size == 0
        assert arc.rows == 2 and arc.checkpoint_step == 50


def test_resume_matches_an_uninterrupted_run(tmp_path):
    """A run stopped at a step off the chunk grid, resumed twice: same state, rows and snapshots."""
    ref_path = tmp_path / "ref.h5"
    ref, _ = record(
        ref_path, 2500, snapshot_every=200, snapshot_points=30, checkpoint_every=400, chunk_steps=100
    )
    path = tmp_path / "run.h5"
    record(path, 1050, snapshot_every=200, snapshot_points=30, checkpoint_every=400, chunk_steps=100)
    for total in (1800, 2500):
        sink, ens = ArchiveSink.resume(path, threads=1)
        with sink:
            run_to(ens, total, [sink], sink.chunk_steps)
    assert ens.step == ref.step and same_state(ens.state(), ref.state())
    with open_archive(path) as arc, open_archive(ref_path) as want:
        steps = list(arc.series["step"])
        assert steps == sorted(set(list(range(100, 1001, 100)) + [1050] + list(range(1100, 2501, 100))))
        ref_rows = {int(s): i for i, s in enumerate(want.series["step"])}
        for name in SERIES_FIELDS:
            if name not in CLOCKS:
                got = [arc.series[name][i] for i, s in enumerate(steps) if s != 1050]
                assert np.array_equal(got, want.series[name][[ref_rows[s] for s in steps if s != 1050]])
        assert np.array_equal(arc.snapshots.steps, want.snapshots.steps)
        assert np.array_equal(arc.snapshots.x, want.snapshots.x)
        assert arc.checkpoint_step == 2500 and arc.created != ""


def test_interrupted_run_is_checkpointed_where_it_stopped(tmp_path):
    """Ctrl-C between chunks (Ensemble.run never stops inside one): the state is exact, so the
    sink checkpoints it at the step reached; rows up to it stay, and the resume is bitwise."""

    class Boom(Observer):
        def after_chunk(self, ensemble, seconds):
            if ensemble.step == 700:
                raise KeyboardInterrupt

    path = tmp_path / "run.h5"
    ens = fresh()
    with ArchiveSink(path, ens, checkpoint_every=300, chunk_steps=100) as sink:
        with pytest.raises(KeyboardInterrupt):
            ens.run(1000, [sink, Boom()], chunk_steps=100)
    with open_archive(path) as arc:
        assert arc.checkpoint_step == 700 and list(arc.series["step"]) == list(range(100, 701, 100))
    sink, ens = ArchiveSink.resume(path)
    with sink:
        assert ens.step == 700 and sink.checkpoint_step == 700
        run_to(ens, 1000, [sink], sink.chunk_steps)
    ref = fresh().run(1000)
    assert same_state(ens.state(), ref.state())
    with open_archive(path) as arc:
        assert list(arc.series["step"]) == list(range(100, 1001, 100))


def test_no_checkpoint_yet_restarts_from_initial_state(tmp_path):
    path = tmp_path / "run.h5"
    ens = fresh()
    ArchiveSink(path, ens, chunk_steps=100).close()
    with open_archive(path) as arc:
        assert arc.checkpoint_step == 0 and arc.rows == 0 and arc.latest() is None
        assert same_state(arc.ensemble().state(), fresh().state())


# -- schedule and refusals -------------------------------------------------------------------------
def test_schedule_lands_chunk_ends_on_snapshots_and_checkpoints():
    assert schedule(10_000) == (25_000, 200_000)
    assert schedule(10_000, snapshot_every=1000) == (1000, 8000)
    assert schedule(10**6, snapshot_every=6000, checkpoint_every=9000) == (1000, 9000)
    assert schedule(100, chunk_steps=50, snapshot_every=200, checkpoint_every=500) == (50, 500)
    with pytest.raises(ValueError, match="chunk_steps = 300 must divide checkpoint_every = 1000"):
        schedule(100, chunk_steps=300, checkpoint_every=1000)
    with pytest.raises(ValueError, match="only allow chunks of 1 steps"):
        schedule(10**6, snapshot_every=10_007)
    with pytest.raises(ValueError, match="snapshot_every = -1"):
        schedule(100, snapshot_every=-1)


def test_refuses_to_overwrite_and_force_replaces(tmp_path, capfd):
    path = tmp_path / "precious.h5"
    path.write_bytes(b"user data")
    with pytest.raises(ArchiveError, match="exists; refusing to overwrite"):
        ArchiveSink(path, fresh())
    assert path.read_bytes() == b"user data"
    proc = in_process(capfd, *run_argv("--points", "10", "--steps", "10", "--out", str(path), "--quiet"))
    assert_one_line_error(proc)
    assert "--force" in proc.stderr and path.read_bytes() == b"user data"
    ArchiveSink(path, fresh(), force=True).close()
    with open_archive(path) as arc:
        assert arc.points == POINTS
    assert [p.name for p in tmp_path.iterdir()] == ["precious.h5"]  # no temporary left behind


def test_file_in_use_is_refused(tmp_path):
    path = tmp_path / "run.h5"
    with ArchiveSink(path, fresh(), chunk_steps=100):
        with pytest.raises(ArchiveError, match="in use by another process"):
            ArchiveSink.resume(path)
        with pytest.raises(ArchiveError, match="in use by another process"):
            ArchiveSink(path, fresh(), force=True)
    ArchiveSink.resume(path)[0].close()  # free again once the writer closed it


def test_incompatible_format_version_is_refused(tmp_path, archived, capfd):
    path = tmp_path / "future.h5"
    shutil.copy(archived[0], path)
    with h5py.File(path, "r+") as f:
        f.attrs["format_version"] = 3
    with pytest.raises(ArchiveError, match="format version 3 is not supported"):
        open_archive(path)
    assert_one_line_error(in_process(capfd, "resume", str(path), "--steps", "5000"))
    with pytest.raises(ArchiveError, match="not a warpratchet archive"):
        with h5py.File(tmp_path / "other.h5", "w") as f:
            f["x"] = 1
        open_archive(tmp_path / "other.h5")
    with pytest.raises(ArchiveError, match="no such archive"):
        open_archive(tmp_path / "missing.h5")


# -- the documented layout is the written one -----------------------------------------------------
def test_docs_match_the_file(archived, tmp_path):
    # the /transport group's names (feature "transport"): tests/cli/test_transport_cli.py
    documented = {name for name in documented_names() if not name.startswith("/transport")}
    assert len(documented) > 60  # the table was found and parsed
    optional = documented_optional()
    assert optional == {"/settings@seed", "/settings@threshold"}
    written = written_names(archived[0])
    assert documented - written <= optional, "documented but not written"
    assert written - documented == set(), "written but not documented"
    ens = Ensemble(PARAMS, np.full(4, 0.2), np.full(4, 0.3))  # no seed, an explicit threshold
    ArchiveSink(tmp_path / "user.h5", ens, threshold=0.5, chunk_steps=10, history=History(0.5)).close()
    other = written_names(tmp_path / "user.h5")
    assert documented - other == {"/settings@seed"} and written - other == {"/settings@seed"}
    text = ARCHIVE_DOC.read_text()
    assert "warpratchet-archive" in text and "version 2" in text


def test_every_dataset_describes_itself(archived):
    """units and long_name everywhere; every axis of every dataset is a named dimension (a dimension
    scale attached to it), so netCDF readers invent no phony_dim; the time axes are the steps."""
    with h5py.File(archived[0], "r") as f:
        datasets = []
        f.visititems(lambda name, obj: datasets.append(obj) if isinstance(obj, h5py.Dataset) else None)
        assert len(datasets) > 30
        # netCDF dimensions without values (docs/archive.md): no data, so no units or checksum
        mark = b"This is a netCDF dimension but not a netCDF variable."
        pure = {ds.name for ds in datasets if bytes(ds.attrs.get("NAME", b"")).startswith(mark)}
        assert pure == {
            "/initial/point", "/checkpoint/point", "/checkpoint/counter", "/progress/counter"
        }  # fmt: skip
        for ds in datasets:
            if ds.name in pure:
                continue
            assert ds.attrs["units"] and ds.attrs["long_name"], ds.name
            assert ds.fletcher32, ds.name
            for axis in range(ds.ndim):
                assert ds.is_scale or len(ds.dims[axis]) == 1, f"{ds.name} axis {axis} has no dimension"
        for name in SERIES_FIELDS[1:]:
            assert f["series"][name].dims[0][0] == f["series/step"], name
        for name in ("x", "p", "ftle", "finite_time_acceleration"):
            dims = f["snapshots"][name].dims
            assert dims[0][0] == f["snapshots/step"] and dims[1][0] == f["snapshots/indices"], name
        # Closed: exactly the valid rows, no allocated zeros past them.
        assert f["series/step"].shape == (int(f["progress/series_rows"][0]),) == (10,)
        assert f["snapshots/x"].shape == (int(f["progress/snapshot_rows"][0]), 40) == (5, 40)


# -- truncated and corrupted files -----------------------------------------------------------------
def _read_all(path):
    """Everything a reader can get from an archive (raises ArchiveError if it cannot)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(path) as arc:
            info = arc.info()
            out = {
                "series": arc.series,
                "snapshots": arc.snapshots,
                "initial": arc.initial,
                "checkpoint": arc.checkpoint(),
                "meta": (arc.params, arc.settings, arc.versions, arc.created, info["rows"]),
            }
    return out, [str(w.message) for w in caught]


def _flip(src, dst, offset, count=8):
    shutil.copy(src, dst)
    with open(dst, "r+b") as fh:
        fh.seek(offset)
        data = bytearray(fh.read(count))
        fh.seek(offset)
        fh.write(bytes(b ^ 0xA5 for b in data))


def test_truncated_file_is_a_clear_error(tmp_path, archived, capfd):
    path = tmp_path / "cut.h5"
    data = Path(archived[0]).read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ArchiveError, match="truncated file.*the file is truncated or corrupted"):
        _read_all(path)
    assert_one_line_error(in_process(capfd, "inspect", str(path)))
    assert_one_line_error(in_process(capfd, "resume", str(path), "--steps", "5000", "--quiet"))
    assert Path(path).read_bytes() == data[: len(data) // 2]  # a failed resume touches nothing


def test_a_file_that_is_not_hdf5_is_named_so_not_called_truncated(tmp_path, capfd):
    path = tmp_path / "notes.h5"
    path.write_text("not an archive\n")
    with pytest.raises(ArchiveError, match="notes.h5 is not an HDF5 file") as exc:
        open_archive(path)
    assert "truncated" not in str(exc.value)
    proc = in_process(capfd, "inspect", str(path))
    assert_one_line_error(proc)
    assert "not an HDF5 file" in proc.stderr


def test_truncated_file_of_a_killed_writer_errors_or_recovers_truthfully(tmp_path, killed, capfd):
    """HDF5 skips its size check in SWMR mode: what is missing must still never pass unnoticed."""
    src, _, states = killed
    data = Path(src).read_bytes()
    for fraction in (0.5, 0.75, 0.9):
        path = tmp_path / f"cut{fraction}.h5"
        path.write_bytes(data[: int(len(data) * fraction)])
        try:
            got, notes = _read_all(path)
        except ArchiveError as exc:
            assert "truncated or corrupted" in str(exc)
            continue
        state, step = got["checkpoint"]
        assert notes and "recovered" in notes[0] and step < 1000
        assert same_state(state, states[step])
    proc = in_process(capfd, "inspect", str(tmp_path / "cut0.5.h5"))
    assert "Traceback" not in proc.stderr
    if proc.returncode == 0:
        assert "warpratchet: warning:" in proc.stderr and "recovered" in proc.stderr
    else:
        assert_one_line_error(proc)


@pytest.mark.parametrize("which", ["archived", "killed"])
def test_flipped_bytes_never_give_silent_wrong_data(tmp_path, request, which):
    """Byte flips anywhere: a clear error, the same data, or an older checkpoint that is right."""
    src, _, states = request.getfixturevalue(which)
    want, _ = _read_all(src)
    size = os.path.getsize(src)
    rng = np.random.default_rng(11)
    offsets = [size // 2, *rng.integers(0, size - 8, 30)]
    outcomes = []
    for i, offset in enumerate(offsets):
        path = tmp_path / f"flip{i}.h5"
        _flip(src, path, int(offset))
        try:
            got, notes = _read_all(path)
        except ArchiveError:
            outcomes.append("error")
            continue
        state, step = got["checkpoint"]
        assert same_state(state, states[step]), f"offset {offset}: checkpoint differs from the run at {step}"
        assert (step == 1000) == (not notes), f"offset {offset}: recovery {notes} must be announced"
        assert same_series(got["series"], want["series"]), f"offset {offset}: series differ"
        for name in ("steps", "indices", "x", "p", "ftle", "finite_time_acceleration"):
            assert np.array_equal(getattr(got["snapshots"], name), getattr(want["snapshots"], name))
        assert same_state(got["initial"], want["initial"]) and got["meta"] == want["meta"]
        outcomes.append("recovered" if notes else "same")
    assert "error" in outcomes  # flips do hit data


def test_flipped_bytes_in_the_middle_via_cli(tmp_path, archived, capfd):
    path = tmp_path / "mid.h5"
    size = os.path.getsize(archived[0])
    _flip(archived[0], path, size // 2, 16)
    for args in (
        ("inspect", str(path), "--json"),
        ("resume", str(path), "--steps", "1200", "--quiet", "--json"),
    ):
        proc = in_process(capfd, *args)
        assert "Traceback" not in proc.stderr
        if proc.returncode == 2:
            assert_one_line_error(proc)
        else:
            assert proc.returncode == 0, proc.stderr
    if proc.returncode == 0:  # resumed: from a checkpoint that verified, so exactly the true run
        report = json.loads(proc.stdout)
        ref = fresh().run(1200)
        with open_archive(path) as arc:
            assert report["steps"] == 1200 and same_state(arc.ensemble().state(), ref.state())


def test_damaged_checkpoint_falls_back_to_the_previous_one(tmp_path, archived, capfd):
    src, _, states = archived
    path = tmp_path / "bad.h5"
    shutil.copy(src, path)
    with h5py.File(path, "r") as f:  # locate the newest slot's data on disk
        slot = ("a", "b")[int(f["checkpoint/current"][0])]
        older = int(f[f"checkpoint/{'b' if slot == 'a' else 'a'}/step"][0])
        offset = f[f"checkpoint/{slot}/q"].id.get_chunk_info(0).byte_offset
    assert older == 800
    _flip(path, tmp_path / "tmp.h5", offset + 100)
    os.replace(tmp_path / "tmp.h5", path)
    with pytest.warns(
        ArchiveWarning, match="checkpoint at step 1000 is unreadable.*recovered the checkpoint at step 800"
    ):
        with open_archive(path) as arc:
            ens = arc.ensemble()
    assert ens.step == 800 and same_state(ens.state(), states[800])
    proc = in_process(capfd, "resume", str(path), "--steps", "1500", "--quiet", "--json")
    assert proc.returncode == 0, proc.stderr
    assert "warpratchet: warning:" in proc.stderr and "step 800" in proc.stderr
    assert json.loads(proc.stdout)["steps"] == 1500
    ref = fresh().run(1500)
    with open_archive(path) as arc:
        assert same_state(arc.ensemble().state(), ref.state())
        assert list(arc.series["step"]) == list(range(100, 1501, 100))


# -- command line ---------------------------------------------------------------------------------
def test_cli_run_resume_inspect(tmp_path, capsys):
    path = str(tmp_path / "cli.h5")
    run = run_argv("--points", "200", "--seed", "4", "--steps", "600", "--out", path)
    schedule_flags = ["--snapshot-every", "200", "--snapshot-points", "20", "--checkpoint-every", "400"]
    assert main([*run, *schedule_flags, "--quiet", "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["archive"] == path and first["steps"] == 600
    assert main(["resume", path, "--steps", "1000", "--K", "3", "--points", "200", "--quiet", "--json"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert set(second) == set(first) and second["steps"] == 1000 and second["seed"] == 4
    ref = Ensemble.sample(PARAMS, 200, "strip", 4).run(1000)
    s = summarize(ref.state(), 1000)
    assert second["A"] == s.A and second["lyapunov"] == s.lyapunov
    assert main(["inspect", path, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["checkpoint_step"] == 1000 and info["rows"] == 5 and info["snapshots"] == 5
    assert info["latest"]["A"] == s.A and info["params"]["K"] == 3.0 and info["format_version"] == 2
    assert info["format_minor"] == 2
    assert main(["inspect", path]) == 0
    text = capsys.readouterr().out
    assert "checkpoint at step 1000" in text and "K = 3.0" in text
    assert "warpratchet-archive v2.2," in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["resume", "{path}", "--steps", "400"],
            "--steps 400 is behind the archive's checkpoint at step 600",
        ),
        (
            ["resume", "{path}", "--steps", "900", "--K", "2.5"],
            "--K 2.5 disagrees with the archive's K = 3.0",
        ),
        (["resume", "{path}", "--steps", "900", "--seed", "1"], "--seed 1 disagrees"),
        (["resume", "{missing}", "--steps", "900"], "no such archive"),
        (run_argv("--snapshot-every", "5"), "--snapshot-every needs --out"),
        (
            run_argv("--out", "{new}", "--chunk-steps", "300", "--checkpoint-every", "1000"),
            "chunk_steps = 300 must divide checkpoint_every = 1000",
        ),
        (["inspect", "{missing}"], "no such archive"),
    ],
)
def test_cli_refusals(tmp_path, capsys, args, message):
    path = tmp_path / "r.h5"
    record(path, 600, chunk_steps=200)
    before = path.read_bytes()
    fill = {"path": str(path), "missing": str(tmp_path / "nope.h5"), "new": str(tmp_path / "new.h5")}
    assert message in refused(capsys, [a.format(**fill) for a in args])
    assert path.read_bytes() == before and not (tmp_path / "new.h5").exists()


def test_overhead_benchmark_runs_and_archiving_changes_nothing():
    """Smoke test of benchmarks/archive_overhead.py --quick (structure only, no timing assertions)."""
    report = quick_benchmark("archive_overhead.py")
    assert report["quick"] and report["budget"] == 1.05 and len(report["cases"]) == 2
    for case in report["cases"]:
        assert case["identical"] and case["rows"] >= 1 and case["file_bytes"] > 0
        assert case["wall_ratio"] > 0 and 0 < case["sink_share_of_kernel"]


def test_settings_are_runspec_attributes(archived):
    """/settings is RunSpec.to_attrs() (init, not sampler; the default threshold absent, not NaN)."""
    from warpratchet.spec import RunSpec

    path, ens, _ = archived
    with h5py.File(path, "r") as f:
        attrs = dict(f["settings"].attrs)
        target = int(f["progress/target_step"][0])
    assert "sampler" not in attrs and attrs["init"] == "strip" and "threshold" not in attrs
    assert target == 1000
    with open_archive(path) as arc:
        spec = arc.spec
    want = RunSpec(
        K=3.0, b1=0.1, b2=0.01, points=POINTS, seed=SEED, steps=1000, chunk_steps=100,
        threads=ens.threads, device=ens.device,
    )  # fmt: skip
    assert spec == want
    stored = RunSpec(**{k: v for k, v in want.as_dict().items()}).to_attrs()
    stored.pop("steps")
    assert {k: (v.decode() if isinstance(v, bytes) else v) for k, v in attrs.items() if k in stored} == stored
