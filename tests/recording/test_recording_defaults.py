"""Recording defaults (issue 14, items 5 and 6): the viewer opens at the start, the series show the
whole run, frames are log-spaced within a size and a time budget, the torus has axes, and
``--rerun-spawn`` without a display is a warning. Blueprints are read back from the files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from rrd import cloud_frames, read_rrd, verify
from support import MAP_FLAGS, run_argv

from warpratchet import Ensemble, MapParams
from warpratchet.cli import main
from warpratchet.recording import (
    RecordingSink,
    ViewerUnavailable,
    log_spaced,
    plan_frames,
)
from warpratchet.recording._plan import BYTES_FIXED, BYTES_PER_FRAME, BYTES_PER_POINT

PARAMS = MapParams(3.0, 0.1, 0.01)


def blueprint_rows(path: Path) -> dict[str, dict[str, object]]:
    """``entity -> {component: pyarrow column}`` of the recording's default blueprint."""
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    [store] = reader.blueprints()
    rows: dict[str, dict[str, object]] = {}
    for chunk in reader.stream(store=store):
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            rows.setdefault(chunk.entity_path, {})[name] = batch.column(name)
    return rows


def boundary_kinds(column) -> list[tuple[str, str]]:
    """``(start kind, end kind)`` of each time range in a VisibleTimeRanges or TimeAxis column."""
    import pyarrow as pa

    values = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    while pa.types.is_list(values.type):
        values = values.flatten()
    if "range" in [values.type.field(i).name for i in range(values.type.num_fields)]:
        values = values.field("range")
    out = []
    for i in range(len(values)):
        kinds = []
        for side in ("start", "end"):
            union = values.field(side)
            code = union.type_codes[i].as_py()
            kinds.append(union.type.field(list(union.type.type_codes).index(code)).name)
        out.append((kinds[0], kinds[1]))
    return out


@pytest.fixture(scope="module")
def default_recording(tmp_path_factory) -> tuple[Path, RecordingSink, Ensemble]:
    path = tmp_path_factory.mktemp("rec") / "default.rrd"
    ens = Ensemble.sample(PARAMS, 3000, "strip", seed=3)
    sink = RecordingSink(path)
    ens.run(20_000, [sink])
    return path, sink, ens


def test_the_viewer_opens_paused_at_the_start_and_the_series_show_everything(default_recording):
    path, _, _ = default_recording
    rows = blueprint_rows(path)
    panel = {k: v for entity, cols in rows.items() if entity == "/time_panel" for k, v in cols.items()}
    assert panel["TimePanelBlueprint:timeline"].to_pylist() == [["step"]]
    assert panel["TimePanelBlueprint:play_state"].to_pylist() == [[1]]  # Paused
    assert panel["TimePanelBlueprint:loop_mode"].to_pylist() == [[3]]  # All: not "following"
    series_views = [e for e, c in rows.items() if "ViewBlueprint:class_identifier" in c
                    and c["ViewBlueprint:class_identifier"].to_pylist() == [["TimeSeries"]]]  # fmt: skip
    assert len(series_views) == 4
    for view in series_views:
        assert boundary_kinds(rows[f"{view}/VisibleTimeRanges"]["VisibleTimeRanges:ranges"]) == [
            ("Infinite", "Infinite")
        ]
        assert boundary_kinds(rows[f"{view}/TimeAxis"]["TimeAxis:view_range"]) == [("Infinite", "Infinite")]
    [bounds] = [
        c["VisualBounds2D:range"].to_pylist()[0][0] for c in rows.values() if "VisualBounds2D:range" in c
    ]
    assert bounds["x_range"][0] < 0 < 1 < bounds["x_range"][1]  # room for the axes' labels
    assert bounds["y_range"][0] < 0 < 1 < bounds["y_range"][1]
    verify(path)


def test_the_phase_space_panel_has_axes(default_recording):
    rrd = read_rrd(default_recording[0])
    [square] = rrd["/phase_space/axes/square"][None]["LineStrips2D:strips"]
    assert np.array(square).reshape(-1, 2).tolist() == [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]]
    labels = rrd["/phase_space/axes/labels"][None]["Points2D:labels"]
    assert {"x", "p mod 1", "0", "0.5", "1"} <= set(labels)


def test_default_frames_are_log_spaced_from_the_start_and_in_budget(default_recording):
    path, sink, ens = default_recording
    frames = sorted(cloud_frames(read_rrd(path)))
    assert frames == sink.frames == list(sink.plan.steps)
    # Dense early, sparse late. How many frames the time budget pays for depends on the machine
    # (frames are thinned when they cost more than the model says, e.g. under load).
    assert frames[0] == 0 and frames[-1] == 20_000 and len(frames) >= 3
    assert frames[1] <= 20
    gaps = np.diff(frames)
    assert gaps[len(gaps) // 2 :].sum() > 4 * gaps[: len(gaps) // 2].sum()
    assert path.stat().st_size <= 10_000_000
    # The series have rows between frames too, at the ensemble's summary.
    assert len(sink.summaries) >= len(frames) - 1 and sink.summaries[-1] == ens.summary()


def test_the_size_budget_is_enforced_with_fewer_points_or_frames(tmp_path):
    ens = Ensemble.sample(PARAMS, 30_000, "strip", seed=1)
    path = tmp_path / "fewer_points.rrd"
    sink = RecordingSink(path, max_bytes=300_000)
    ens.run(2000, [sink])
    assert path.stat().st_size <= 300_000
    assert 1000 < len(sink.indices) < 20_000  # two frames only fit with fewer points
    assert cloud_frames(read_rrd(path))[2000]["positions"].shape == (len(sink.indices), 2)
    # With a fixed cadence the interval is widened instead (frames stay on its multiples).
    path = tmp_path / "fewer_frames.rrd"
    sink = RecordingSink(path, max_bytes=1_000_000, every=100)
    ens.run(2000, [sink])
    assert path.stat().st_size <= 1_000_000 and len(sink.indices) == 20_000
    assert 2 < len(sink.frames) < 21 and all(s % 100 == 0 for s in sink.frames)


def test_plans():
    assert log_spaced(10, 20) == list(range(1, 11))
    steps = log_spaced(120_000, 40)
    assert steps[0] == 1 and steps[-1] == 120_000 and np.all(np.diff(steps) > 0)
    assert np.allclose(np.diff(np.log(steps))[-10:], math.log(120_000) / 40, rtol=0.02)
    # Size: frames x points fit the budget.
    plan = plan_frames(0, 120_000, 10**6, max_points=20_000, max_bytes=10_000_000)
    size = BYTES_FIXED + len(plan.steps) * (plan.points * BYTES_PER_POINT + BYTES_PER_FRAME)
    assert plan.points == 20_000 and size <= 10_000_000 * 0.95
    # Time: a 3x faster kernel gets about a third of the frames (never a slower run).
    slow = plan_frames(0, 120_000, 10_000, throughput=1e9)
    fast = plan_frames(0, 120_000, 10_000, throughput=3e9)
    assert len(fast.steps) < len(slow.steps) and "time budget" in fast.reason
    assert abs((len(fast.steps) - 1) / (len(slow.steps) - 1) - 1 / 3) < 0.1
    # A fixed cadence too large for the budget is widened, still on multiples.
    wide = plan_frames(0, 10_000, 10**5, max_points=10**5, every=10, max_bytes=5_000_000)
    inner = wide.steps[1:-1]
    assert len(wide.steps) <= 4 and all(s % 10 == 0 for s in inner)
    with pytest.raises(ValueError, match="max_bytes = 100 is outside the allowed range"):
        plan_frames(0, 100, 10, max_bytes=100)


def test_run_help_states_the_budget(capsys):
    assert main(["run", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "--rerun-max-mb MB size budget of the recording" in out and "(default 10)" in out
    assert "log-spaced" in out
    assert "--rerun-every STEPS frames every STEPS steps" in out  # the README's name for its value


def test_rerun_spawn_without_a_display_warns_and_the_run_goes_on(tmp_path, monkeypatch, capsys):
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(ViewerUnavailable, match="needs a display"):
        RecordingSink(spawn=True).open(Ensemble.sample(PARAMS, 10))
    argv = run_argv("--points", "500", "--steps", "500", "--rerun-spawn", "--quiet", "--json")
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "--rerun-spawn needs a display" in captured.err
    assert "not recording, the run goes on" in captured.err
    assert json.loads(captured.out)["steps"] == 500  # the results are printed
    path = tmp_path / "also.rrd"
    assert main([*argv, "--rerun", str(path)]) == 0
    captured = capsys.readouterr()
    assert f"recording to {path} only" in captured.err and path.exists()
    verify(path)


def test_scenes_stay_within_the_budget(tmp_path, capsys):
    from viz.scenes import main as scenes_main

    argv = ["-o", str(tmp_path), "--only", "fig1a", "fig2a", "--points", "6000", "--steps", "60",
            "--max-mb", "0.5"]  # fmt: skip
    assert scenes_main(argv) == 0
    for name in ("fig1a", "fig2a"):
        assert (tmp_path / f"{name}.rrd").stat().st_size <= 500_000
    out = capsys.readouterr().out
    assert out.count("wrote ") == 2


def test_recording_on_the_command_line_has_frames_at_the_start(tmp_path, capsys):
    path = tmp_path / "cli.rrd"
    assert (
        main(["run", *MAP_FLAGS, "--points", "2000", "--steps", "5000", "--quiet", "--rerun", str(path)]) == 0
    )
    frames = sorted(cloud_frames(read_rrd(path)))
    assert frames[0] == 0 and frames[-1] == 5000 and len(frames) >= 3
    assert frames[1] <= 50  # the spreading is seen
