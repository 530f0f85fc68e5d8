"""Rerun recordings (warpratchet.recording, viz.record, viz.scenes, ``run --rerun``).

Every recording is written to a file, read back with ``rerun.chunk.RrdReader`` and checked
against numbers computed independently from the ensemble or the archive; ``rerun rrd verify``
must accept every file. No test starts a viewer.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
from rrd import cloud_frames, packed, read_rrd, series, verify
from support import quick_benchmark, run_argv

from warpratchet import Ensemble, MapParams, theory
from warpratchet.cli import main as cli_main
from warpratchet.observables import (
    default_lyapunov_threshold,
    finite_time_acceleration,
    lyapunov,
    lyapunov_threshold,
    summarize,
)
from warpratchet.recording import (
    CLASSES,
    RERUN_MISSING,
    SERIES_KEYS,
    THEORY_PATH,
    VIRIDIS,
    PhaseSpaceRecording,
    RecordingSink,
    class_ids,
    frame_every,
    ftle_colors,
    require_rerun,
    torus_positions,
)

PARAMS = MapParams(3.0, 0.1, 0.01)  # domain LR: both islands, theory A of Eq. (Aa)


# -- colours, classes, positions -------------------------------------------------------------------
def test_viridis_table_is_matplotlibs_within_rounding():
    import matplotlib

    reference = matplotlib.colormaps["viridis"](np.linspace(0.0, 1.0, 256))[:, :3] * 255.0
    ours = ftle_colors(np.geomspace(1e-3, 10.0, 256))
    # Nodes: matplotlib's values rounded to integers (exact up to 0.5).
    nodes = matplotlib.colormaps["viridis"](np.linspace(0.0, 1.0, len(VIRIDIS)))[:, :3] * 255.0
    assert np.abs(VIRIDIS - nodes).max() <= 0.5
    # Between nodes: linear-interpolation error of viridis at 33 nodes (2.46/255, measured once)
    # plus 0.5 for the rounded nodes and 0.5 for the rounded output.
    assert np.abs(ours - reference).max() <= 3.5


def test_ftle_colors_are_a_log_scale_clipped_to_the_range():
    lo, hi = 1e-3, 10.0
    colors = ftle_colors(np.array([lo, hi, math.sqrt(lo * hi), 1e-9, -0.1, 1e3, np.nan]), (lo, hi))
    np.testing.assert_array_equal(colors[0], VIRIDIS[0])
    np.testing.assert_array_equal(colors[1], VIRIDIS[-1])
    np.testing.assert_array_equal(colors[2], ftle_colors(np.array([math.sqrt(lo * hi)]))[0])
    mid = (VIRIDIS[15] + VIRIDIS[16] + VIRIDIS[17]) / 3  # log-midpoint = table middle
    assert np.abs(colors[2] - mid).max() < 10
    np.testing.assert_array_equal(colors[3:5], [VIRIDIS[0], VIRIDIS[0]])  # regular orbits: dark end
    np.testing.assert_array_equal(colors[5], VIRIDIS[-1])
    np.testing.assert_array_equal(colors[6], VIRIDIS[0])


def test_class_ids_follow_sec_3c():
    ftle = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.01, 0.5])
    acc = np.array([1.0, 0.98, -1.01, 0.02, 2.1, 0.0, -1.0])
    ids = class_ids(ftle, acc, threshold=0.1)
    assert ids.tolist() == [1, 2, 3, 4, 5, 4, 1]
    assert CLASSES[2][0].startswith("L") and CLASSES[3][0].startswith("R")  # w = +1 is L, -1 is R


def test_torus_positions_stay_in_the_unit_square():
    x = np.array([0.0, 0.5, 1.0 - 1e-12, np.nextafter(1.0, 0.0)])
    p = np.array([3.25, -0.25, 1.0 - 1e-12, 7.0 - 1e-13])
    pos = torus_positions(x, p)
    assert pos.dtype == np.float32 and pos.shape == (4, 2)
    assert np.all((pos >= 0.0) & (pos < 1.0))
    np.testing.assert_array_equal(pos[:2], [[0.0, 0.25], [0.5, 0.75]])
    np.testing.assert_array_equal(pos[2:], 0.0)  # rounds to 1.0f, which is 0 on the torus


def test_frame_every_caps_the_frame_count():
    for points, steps in [(10_000, 120_000), (10**6, 1_000), (10, 10**7)]:
        every = frame_every(points, steps)
        assert every >= 1 and steps / every <= 100


# -- live recording ---------------------------------------------------------------------------------
def test_live_recording_reads_back_frames_points_and_summaries(tmp_path):
    path = tmp_path / "live.rrd"
    ens = Ensemble.sample(PARAMS, 3000, "strip", seed=3)
    sink = RecordingSink(path, max_points=1000, every=100, seed=5)
    ens.run(500, [sink], chunk_steps=50)
    assert sink.recording.closed

    # Recording does not change the run.
    plain = Ensemble.sample(PARAMS, 3000, "strip", seed=3).run(500)
    for name in ("x", "q", "winding", "dx", "dp", "log_stretch"):
        np.testing.assert_array_equal(plain.array(name), ens.array(name))

    rrd = read_rrd(path)
    frames = cloud_frames(rrd)
    assert sorted(frames) == [0, 100, 200, 300, 400, 500] == sink.frames
    idx = sink.indices
    assert idx.shape == (1000,) and np.unique(idx).size == 1000
    for frame in frames.values():
        pos = frame["positions"]
        assert pos.shape == (1000, 2)
        assert np.all((pos >= 0.0) & (pos < 1.0))
    # The last frame is the subsample of the final state, coloured by its FTLE.
    state = ens.state()
    sub = {k: v[idx] for k, v in state.items()}
    np.testing.assert_array_equal(frames[500]["positions"], torus_positions(sub["x"], sub["q"]))
    np.testing.assert_array_equal(frames[500]["colors"], packed(ftle_colors(lyapunov(sub, 500))))
    # Step 0: the strip B of Eq. (B), -b2 <= x <= b1 (mod 1).
    x0 = frames[0]["positions"][:, 0]
    assert np.all((x0 <= PARAMS.b1 + 1e-7) | (x0 >= 1.0 - PARAMS.b2 - 1e-7))

    # Scalars: the sink's summaries, bit for bit; the last one is the ensemble's.
    assert [s.step for s in sink.summaries] == [100, 200, 300, 400, 500]
    for key, entity in SERIES_KEYS.items():
        steps, values = series(rrd, entity)
        assert steps.tolist() == [100, 200, 300, 400, 500]
        np.testing.assert_array_equal(values, [getattr(s, key) for s in sink.summaries])
    final = summarize(state, 500)
    assert sink.summaries[-1] == final
    steps, values = series(rrd, THEORY_PATH)
    np.testing.assert_array_equal(values, theory.acceleration(PARAMS))  # Eq. (Aa)
    assert steps.tolist() == [100, 200, 300, 400, 500]

    [text] = rrd["/parameters"][None]["TextDocument:text"]
    assert "| K (kick strength, Eq. cpem) | 3.0 |" in text and "0.145022" in text
    from rerun.chunk import RrdReader

    assert RrdReader(path).blueprints(), "the default blueprint travels with the recording"
    verify(path)


def test_class_colouring_matches_an_independent_classification(tmp_path):
    path = tmp_path / "classes.rrd"
    ens = Ensemble.sample(PARAMS, 2000, "torus", seed=1)
    sink = RecordingSink(path, every=200, color_by="class")
    ens.run(400, [sink], chunk_steps=200)
    rrd = read_rrd(path)
    frames = cloud_frames(rrd)
    assert sorted(frames) == [0, 200, 400]
    assert np.all(frames[0]["class_ids"] == 0)  # nothing is known before the first step
    state = ens.state()
    ftle, acc = lyapunov(state, 400), finite_time_acceleration(state, 400)
    expected = np.where(ftle > default_lyapunov_threshold(400), 1, 0)
    expected[expected == 0] = np.select(
        [np.rint(acc) == 1, np.rint(acc) == -1, np.rint(acc) == 0], [2, 3, 4], 5
    )[expected == 0]
    np.testing.assert_array_equal(frames[400]["class_ids"], expected)
    # Domain LR (Fig. 3): torus points land in the chaotic sea and in both islands.
    assert {1, 2, 3} <= set(frames[400]["class_ids"].tolist())
    [context] = rrd["/phase_space"][None]["AnnotationContext:context"]
    info = {e["class_id"]: e["class_description"]["info"] for e in context}
    described = {cid: (i["label"], i["color"]) for cid, i in info.items()}
    assert described == {
        cid: (label, int(packed(np.array([rgb]))[0])) for cid, (label, rgb) in CLASSES.items()
    }
    verify(path)


def test_subsample_is_fixed_and_capped(tmp_path):
    ens = Ensemble.sample(PARAMS, 5000, "strip", seed=2)
    sink = RecordingSink(tmp_path / "sub.rrd", max_points=700, every=40)
    ens.run(80, [sink], chunk_steps=40)
    frames = cloud_frames(read_rrd(tmp_path / "sub.rrd"))
    assert sorted(frames) == [0, 40, 80]
    assert all(f["positions"].shape == (700, 2) for f in frames.values())
    np.testing.assert_array_equal(
        frames[80]["positions"], torus_positions(ens.array("x")[sink.indices], ens.array("q")[sink.indices])
    )
    with pytest.raises(ValueError, match="closed"):  # one sink records one run
        ens.run(10, [sink])


@pytest.mark.parametrize("rule", ["strict", "positive"])
def test_cli_run_writes_a_recording(tmp_path, capsys, rule):
    """The recording's series end at the report's numbers, exactly, under either threshold rule
    (the recording classifies by the run's rule, not always the strict one)."""
    path = tmp_path / "run.rrd"
    argv = run_argv("--points", "2000", "--steps", "600", "--rerun", str(path), "--rerun-every", "150",
                    "--rerun-points", "400", "--quiet", "--json", "--threshold-rule", rule)  # fmt: skip
    assert cli_main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["recording"] == str(path)
    rrd = read_rrd(path)
    frames = cloud_frames(rrd)
    assert sorted(frames) == [0, 150, 300, 450, 600]
    assert all(f["positions"].shape == (400, 2) for f in frames.values())
    for key in ("A", "A_stderr", "lyapunov", "lyapunov_min", "chaotic_fraction"):
        steps, values = series(rrd, SERIES_KEYS[key])
        assert steps[-1] == 600 and values[-1] == report[key]  # the report's numbers, exactly
    verify(path)


# -- replay of an archive ---------------------------------------------------------------------------
@pytest.mark.parametrize("rule", ["strict", "positive"])
def test_replay_of_an_archive_equals_its_snapshots_and_series(tmp_path, capsys, rule):
    """The replay shows the archive's snapshots and series, its classes by the run's threshold rule."""
    from viz.record import main as record_main
    from warpratchet.archive import open_archive

    h5, rrd_path = tmp_path / "run.h5", tmp_path / "run.rrd"
    argv = run_argv("--points", "1500", "--steps", "400", "--out", str(h5), "--snapshot-every", "100",
                    "--snapshot-points", "300", "--quiet", "--threshold-rule", rule)  # fmt: skip
    assert cli_main(argv) == 0
    assert record_main([str(h5), "-o", str(rrd_path)]) == 0
    assert "4 frames" in capsys.readouterr().out

    with open_archive(h5) as arc:
        snaps, rows = arc.snapshots, arc.series
    rrd = read_rrd(rrd_path)
    frames = cloud_frames(rrd)
    assert sorted(frames) == snaps.steps.tolist() == [100, 200, 300, 400]
    for s, step in enumerate(snaps.steps.tolist()):
        pos = frames[step]["positions"]
        assert pos.shape == (300, 2)
        assert np.all((pos >= 0.0) & (pos < 1.0))
        np.testing.assert_array_equal(pos, torus_positions(snaps.x[s], snaps.p[s]))
        np.testing.assert_array_equal(frames[step]["colors"], packed(ftle_colors(snaps.ftle[s])))
    for key, entity in SERIES_KEYS.items():
        steps, values = series(rrd, entity)
        np.testing.assert_array_equal(steps, rows["step"])
        np.testing.assert_array_equal(values, rows[key])
    _, values = series(rrd, THEORY_PATH)
    np.testing.assert_array_equal(values, theory.acceleration(PARAMS))
    verify(rrd_path)

    # By class, with the archive's A_n per point.
    rrd_class = tmp_path / "class.rrd"
    assert record_main([str(h5), "-o", str(rrd_class), "--color", "class", "--trail"]) == 0
    frames = cloud_frames(read_rrd(rrd_class))
    acc = snaps.finite_time_acceleration[-1]
    expected = class_ids(snaps.ftle[-1], acc, lyapunov_threshold(400, rule))
    np.testing.assert_array_equal(frames[400]["class_ids"], expected)
    other = "positive" if rule == "strict" else "strict"
    assert np.any(expected != class_ids(snaps.ftle[-1], acc, lyapunov_threshold(400, other)))
    verify(rrd_class)


def test_replay_of_a_format_2_1_archive_classes_by_its_stored_a_n(tmp_path, capsys):
    """An archive written before format 2.2 (each point's A_n stored as /snapshots/A) replays by
    class with those values, read in place."""
    from pathlib import Path

    from viz.record import main as record_main
    from warpratchet.archive import open_archive

    fixture = Path(__file__).resolve().parents[1] / "data" / "archive_v2_1.h5"
    rrd_path = tmp_path / "old.rrd"
    assert record_main([str(fixture), "-o", str(rrd_path), "--color", "class"]) == 0
    assert "4 frames" in capsys.readouterr().out
    with open_archive(fixture) as arc:
        stored = arc.h5["snapshots"]["A"][-1]
        snaps = arc.snapshots
    frames = cloud_frames(read_rrd(rrd_path))
    expected = class_ids(snaps.ftle[-1], stored, lyapunov_threshold(512, "strict"))
    np.testing.assert_array_equal(frames[512]["class_ids"], expected)
    verify(rrd_path)


# -- the paper's scenes --------------------------------------------------------------------------------
def test_scenes_have_the_papers_parameters():
    from viz.scenes import SCENES

    assert SCENES["fig1a"].params == MapParams(3.0, 0.05, 0.02)
    assert SCENES["fig1b"].params.K == pytest.approx(3.618, abs=5e-4)  # Fig. 1 caption: K ~ 3.618
    assert SCENES["fig1c"].params.K == pytest.approx(2.7247, abs=5e-5)  # and K ~ 2.7247
    for key in "abc":
        fig1, fig2 = SCENES[f"fig1{key}"].params, SCENES[f"fig2{key}"].params
        assert fig2.K == fig1.K and fig2.b1 == fig2.b2 == 1e-7
    assert SCENES["fig4"].params == MapParams(3.0, 0.226, 0.02)
    assert theory.domain(SCENES["fig4"].params) == "R"  # Fig. 4 caption: only the right island
    assert theory.domain(SCENES["fig1a"].params) == "LR"  # Fig. 1(a): both islands


def test_frame_steps_ramp_then_grow_geometrically():
    from viz.scenes import frame_steps

    steps = frame_steps(2000)
    assert steps[0] == 0 and steps[-1] == 2000 and np.all(np.diff(steps) > 0)
    np.testing.assert_array_equal(steps[:17], np.arange(17))
    ratios = steps[18:] / steps[17:-1]
    assert np.all(ratios[:-1] <= 1.15 + 1 / 16 + 1e-12)  # rounding to whole steps
    assert frame_steps(5).tolist() == [0, 1, 2, 3, 4, 5]


def test_scenes_command_records_fig4_and_a_trail_scene(tmp_path, capsys):
    from viz.scenes import frame_steps
    from viz.scenes import main as scenes_main

    argv = ["-o", str(tmp_path), "--only", "fig4", "fig2a", "--points", "400", "--steps", "30"]
    assert scenes_main(argv) == 0
    fig4 = cloud_frames(read_rrd(tmp_path / "fig4.rrd"))
    assert sorted(fig4) == frame_steps(30).tolist()
    fig2 = cloud_frames(read_rrd(tmp_path / "fig2a.rrd"))
    assert sorted(fig2) == list(range(31))  # Fig. 2 scenes keep every step
    for frames in (fig4, fig2):
        for frame in frames.values():
            assert frame["positions"].shape == (400, 2)
            assert np.all((frame["positions"] >= 0.0) & (frame["positions"] < 1.0))
    verify(tmp_path / "fig4.rrd")
    verify(tmp_path / "fig2a.rrd")
    # Running again must not overwrite anything.
    before = (tmp_path / "fig4.rrd").read_bytes()
    assert scenes_main(argv) == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "fig4.rrd").read_bytes() == before


# -- bad input ------------------------------------------------------------------------------------------
def test_existing_files_are_never_overwritten(tmp_path, capsys):
    path = tmp_path / "taken.rrd"
    path.write_bytes(b"user data")
    with pytest.raises(FileExistsError, match="taken.rrd exists"):
        RecordingSink(path)
    with pytest.raises(FileExistsError):
        PhaseSpaceRecording(PARAMS, path)
    argv = run_argv("--steps", "10", "--rerun", str(path), "--quiet")
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refusing to overwrite" in err
    assert path.read_bytes() == b"user data"
    with pytest.raises(FileNotFoundError, match="does not exist"):
        RecordingSink(tmp_path / "no" / "such.rrd")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"color_by": "rainbow"}, "color_by = 'rainbow'"),
        ({"max_points": 0}, "max_points = 0 is outside the allowed range"),
        ({"every": 0}, "every = 0 is outside the allowed range"),
    ],
)
def test_bad_sink_options_name_the_value(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        RecordingSink(tmp_path / "x.rrd", **kwargs)
    assert not (tmp_path / "x.rrd").exists()


def test_bad_recording_options_name_the_value(tmp_path, capsys):
    with pytest.raises(ValueError, match="ftle_range"):
        PhaseSpaceRecording(PARAMS, tmp_path / "x.rrd", ftle_range=(1.0, 0.1))
    with pytest.raises(ValueError, match="needs a path"):
        PhaseSpaceRecording(PARAMS)
    argv = run_argv("--rerun-every", "5")
    assert cli_main(argv) == 2
    assert "--rerun-every needs --rerun PATH" in capsys.readouterr().err


def test_missing_rerun_is_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` raise ImportError
    with pytest.raises(ImportError, match=r"pip install 'warpratchet\[rerun\]'"):
        require_rerun()
    with pytest.raises(ImportError, match="rerun-sdk is not installed"):
        RecordingSink(tmp_path / "x.rrd")
    argv = run_argv("--steps", "10", "--rerun", str(tmp_path / "y.rrd"))
    assert cli_main(argv) == 2
    assert capsys.readouterr().err == f"warpratchet: error: {RERUN_MISSING}\n"
    assert not (tmp_path / "y.rrd").exists()


def test_overhead_benchmark_quick_smoke():
    """``benchmarks/recording_overhead.py --quick --json`` runs and recording leaves results bitwise equal."""
    report = quick_benchmark("recording_overhead.py")  # exit 0, or it fails with the stderr
    assert [(c["points"], c["steps"]) for c in report["cases"]] == [(10_000, 20_000), (200_000, 1_000)]
    for case in report["cases"]:
        assert case["bitwise_identical"] is True
        assert case["frames"] == case["planned_frames"] >= 2  # the first and the final frame at least
        assert case["file_mb"] <= 10.0  # the default size budget
        assert case["seconds_plain"] > 0 and case["seconds_recorded"] > 0  # no timing assertions
