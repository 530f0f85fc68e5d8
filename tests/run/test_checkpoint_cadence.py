"""The archive's wall-clock checkpoint cadence (``checkpoint_seconds``, ``--checkpoint-seconds``).

Whatever the chunk length, a checkpoint comes once waiting for the next chunk end would leave
more than ``checkpoint_seconds`` of work unsaved, so a kill -9 loses at most about that much.
The clock is the writer's ``time.monotonic``; these tests drive it by hand, so nothing depends
on how fast the machine is.
"""

from __future__ import annotations

import json

import h5py
import pytest
from support import MAP_FLAGS, in_process, refused, same_state

from warpratchet import Ensemble, MapParams, Observer
from warpratchet.archive import ArchiveSink, _writer, open_archive
from warpratchet.spec import CHECKPOINT_SECONDS

PARAMS = MapParams(3.0, 0.1, 0.01)


class _Clock:
    """A monotonic clock that moves ``tick`` seconds at every chunk end (a chunk of ``tick`` s)."""

    def __init__(self, tick: float) -> None:
        self.now, self.tick = 1000.0, tick

    def __call__(self) -> float:
        return self.now


class _Ticks(Observer):
    def __init__(self, clock: _Clock) -> None:
        self.clock = clock

    def after_chunk(self, ensemble, seconds):
        self.clock.now += self.clock.tick


class _Checkpoints(Observer):
    """The sink's checkpoint step after each of its chunk ends."""

    def __init__(self, sink: ArchiveSink) -> None:
        self.sink, self.seen = sink, []

    def after_chunk(self, ensemble, seconds):
        self.seen.append(self.sink.checkpoint_step)


def test_checkpoints_come_before_the_unsaved_work_passes_the_cadence(tmp_path, monkeypatch):
    """Chunks of 10 s, a cadence of 25 s and a step interval that never comes: a checkpoint at
    every second chunk end (after 20 s, since the next end would leave 30 s unsaved)."""
    clock = _Clock(10.0)
    monkeypatch.setattr(_writer.time, "monotonic", clock)
    ens = Ensemble.sample(PARAMS, 500, seed=3)
    path = tmp_path / "a.h5"
    with ArchiveSink(path, ens, chunk_steps=100, checkpoint_every=10**6, checkpoint_seconds=25) as sink:
        seen = _Checkpoints(sink)
        ens.run(1000, [_Ticks(clock), sink, seen], chunk_steps=100)
    assert seen.seen == [0, 200, 200, 400, 400, 600, 600, 800, 800, 1000]
    with open_archive(path) as arc:
        assert arc.settings["checkpoint_seconds"] == 25.0
        state, step = arc.checkpoint()
    assert step == 1000 and same_state(state, ens.state())


def test_a_chunk_longer_than_the_cadence_checkpoints_at_every_chunk_end(tmp_path, monkeypatch):
    clock = _Clock(90.0)
    monkeypatch.setattr(_writer.time, "monotonic", clock)
    ens = Ensemble.sample(PARAMS, 500, seed=3)
    with ArchiveSink(tmp_path / "a.h5", ens, chunk_steps=100, checkpoint_every=10**6) as sink:
        seen = _Checkpoints(sink)
        ens.run(300, [_Ticks(clock), sink, seen], chunk_steps=100)
    assert seen.seen == [100, 200, 300]


def test_the_default_cadence_is_stored_and_kept_by_a_resume(tmp_path):
    path = tmp_path / "a.h5"
    ens = Ensemble.sample(PARAMS, 300, seed=3)
    with ArchiveSink(path, ens, chunk_steps=100) as sink:
        ens.run(200, [sink], chunk_steps=100)
    with h5py.File(path, "r") as f:
        assert f["settings"].attrs["checkpoint_seconds"] == CHECKPOINT_SECONDS == 60.0
    sink, _ = ArchiveSink.resume(path)
    with sink:
        assert sink.checkpoint_seconds == 60.0


@pytest.mark.parametrize("value", [0, -1.0, float("nan"), float("inf"), 7 * 86400.0 + 1, "60"])
def test_a_cadence_outside_its_range_is_refused(tmp_path, value):
    ens = Ensemble.sample(PARAMS, 100, seed=3)
    with pytest.raises(
        ValueError, match=r"checkpoint_seconds = .*allowed range 0.0 < checkpoint_seconds <= 604800.0"
    ):
        ArchiveSink(tmp_path / "a.h5", ens, checkpoint_seconds=value)
    assert not (tmp_path / "a.h5").exists()


def test_the_cli_flag_sets_the_cadence_and_needs_out(tmp_path, capfd):
    path = tmp_path / "r.h5"
    proc = in_process(
        capfd,
        "run",
        *MAP_FLAGS,
        "--points",
        "100",
        "--steps",
        "200",
        "--out",
        str(path),
        "--checkpoint-seconds",
        "5",
    )
    assert proc.returncode == 0, proc.stderr
    with open_archive(path) as arc:
        assert arc.settings["checkpoint_seconds"] == 5.0
    line = refused(
        capfd, ["run", *MAP_FLAGS, "--points", "100", "--steps", "200", "--checkpoint-seconds", "5"]
    )
    assert "--checkpoint-seconds needs --out FILE" in line
    line = refused(
        capfd,
        ["run", *MAP_FLAGS, "--points", "100", "--out", str(tmp_path / "s.h5"), "--checkpoint-seconds", "0"],
    )
    assert "checkpoint_seconds = 0.0 is outside the allowed range" in line
    assert not (tmp_path / "s.h5").exists()


def test_resume_to_the_step_an_archive_holds_reports_it_and_exits_0(tmp_path, capfd):
    """``resume --steps N`` again on an archive at N is idempotent, as ``run --out`` is."""
    from warpratchet.cli import main

    path = tmp_path / "r.h5"
    assert (
        in_process(
            capfd, "run", *MAP_FLAGS, "--points", "200", "--steps", "600", "--out", str(path)
        ).returncode
        == 0
    )
    first = in_process(capfd, "resume", str(path), "--steps", "900", "--json")
    assert first.returncode == 0, first.stderr
    before = path.read_bytes()
    code, again = main(["resume", str(path), "--steps", "900", "--json"]), capfd.readouterr()
    assert code == 0, again.err
    assert again.err.strip() == f"warpratchet: {path} holds all 900 steps already: its report, nothing run"
    assert path.read_bytes() == before  # nothing touched
    report, original = json.loads(again.out), json.loads(first.stdout)
    assert (
        report["steps"] == 900 and report["A"] == original["A"] and report["history"] == original["history"]
    )
    behind = refused(capfd, ["resume", str(path), "--steps", "300"])
    assert "--steps 300 is behind the archive's checkpoint at step 900" in behind


def test_inspect_reports_progress_at_the_checkpoint_and_at_the_newest_row(tmp_path, capfd):
    """A run killed between checkpoints: its rows reach step 300, a rerun keeps step 0."""
    path = tmp_path / "r.h5"
    ens = Ensemble.sample(PARAMS, 200, seed=3)
    sink = ArchiveSink(path, ens, chunk_steps=100, checkpoint_every=1000)
    sink.begin(ens, 1000)
    for _ in range(3):  # the rows of three chunks, and no end (as a kill leaves it)
        ens.run(100)
        sink.after_chunk(ens, 0.5)
    sink.close()
    with open_archive(path) as arc:
        info = arc.info()
    assert (info["checkpoint_step"], info["done"], info["latest_done"]) == (0, 0.0, 0.3)
    assert info["eta_seconds"] == pytest.approx(700 / (300 / 1.5))  # from the newest row
    text = in_process(capfd, "inspect", str(path)).stdout
    assert (
        "target: step 1000, 0.0% done at the checkpoint (where a rerun continues), 30.0% at the newest row"
        in text
    )
    assert "latest (step 300)" in text
