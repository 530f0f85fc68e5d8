"""Ctrl-C and errors during a run (issue 14, item 1): a real SIGINT to a real process, API and CLI.

Before the fix, SIGINT during ``Ensemble.run`` raised while the CPU shards were still running:
``ens.step`` stayed behind the arrays and every later ``A_n`` divided by the wrong ``n``. Now
the run stops between chunks: the state equals a fresh ensemble run to the reported step,
bit for bit, and every observer's ``end`` ran.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest
from support import MAP_FLAGS, launch, same_state

from warpratchet import Ensemble, MapParams, Observer

PARAMS = MapParams(3.0, 0.1, 0.01)


#: Seconds a child process may take before the test gives up (a busy machine is slow, not broken).
PATIENCE = 900


def _wait_for(proc: subprocess.Popen, ready, what: str) -> None:
    """Poll ``ready()`` until it holds (a readiness signal, never a fixed sleep); fail naming the
    command if the process ends first or nothing happens for :data:`PATIENCE` seconds."""
    deadline = time.monotonic() + PATIENCE
    while not ready():
        if proc.poll() is not None:
            out, err = proc.communicate()
            raise AssertionError(f"{proc.args} ended before {what}: {err}")
        assert time.monotonic() < deadline, f"{proc.args}: no {what} within {PATIENCE} s"
        time.sleep(0.02)


def _rows(path) -> int:
    """Series rows an archive holds while it is written (0 while it is being created)."""
    from warpratchet import open_archive

    try:
        with open_archive(path) as arc:
            return int(arc.series["step"].size)
    except (OSError, ValueError):
        return 0


def _stderr_line(proc: subprocess.Popen) -> str:
    """The next line the process writes on stderr (waiting for it, at most :data:`PATIENCE` s)."""
    line: list[str] = []
    reader = threading.Thread(target=lambda: line.append(proc.stderr.readline()), daemon=True)
    reader.start()
    reader.join(PATIENCE)
    assert line, f"{proc.args}: no line on stderr within {PATIENCE} s"
    return line[0]


def _finish(proc: subprocess.Popen) -> tuple[str, str]:
    try:
        return proc.communicate(timeout=PATIENCE)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError(f"{proc.args} did not stop within {PATIENCE} s of the signal") from None


needs_posix = pytest.mark.skipif(os.name != "posix", reason="sends SIGINT to a child process")

SCRIPT = textwrap.dedent(
    """
    import json, sys
    from warpratchet import Ensemble, MapParams, Observer

    class Log(Observer):
        calls = []
        def begin(self, ensemble, target_step): self.calls.append("begin")
        def after_chunk(self, ensemble, seconds):
            if not self.calls.count("chunk"):
                print("started", flush=True)
            self.calls.append("chunk")
        def end(self, ensemble): self.calls.append("end")

    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 40_000, "strip", seed=5, threads=2)
    log = Log()
    try:
        ens.run(10**8, [log], chunk_steps=500)
    except KeyboardInterrupt:
        print(json.dumps({"step": ens.step, "calls": log.calls}))
        ens.state()  # the arrays are there to compare: dump them
        import numpy as np
        np.savez(sys.argv[1], **ens.state())
        sys.exit(0)
    sys.exit(3)
    """
)


@needs_posix
def test_sigint_during_ensemble_run_leaves_a_consistent_ensemble(tmp_path):
    out = tmp_path / "state.npz"
    proc = subprocess.Popen(
        [sys.executable, "-c", SCRIPT, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline() == "started\n"  # after the first chunk: the readiness signal
    proc.send_signal(signal.SIGINT)
    stdout, stderr = _finish(proc)
    assert proc.returncode == 0, stderr
    report = json.loads(stdout)
    step = report["step"]
    assert 0 < step < 10**8 and step % 500 == 0  # stopped at a chunk end
    calls = report["calls"]
    assert calls[0] == "begin" and calls[-1] == "end" and calls.count("chunk") == step // 500
    # The arrays are exactly those of an uninterrupted run to `step`.
    state = dict(np.load(out))
    fresh = Ensemble.sample(PARAMS, 40_000, "strip", seed=5, threads=2).run(step)
    assert same_state(state, fresh.state())


def _stopped_line(stderr: str, verb: str, target: int) -> int:
    """The one line of a stopped run (no traceback); returns the step it names."""
    assert "Traceback" not in stderr
    [line] = stderr.strip().splitlines()
    assert line.startswith(f"warpratchet: {verb} at step ") and f"of {target}" in line, line
    return int(line.split("at step ")[1].split()[0])


def _checkpointed_at(path, step: int, line_source: str) -> None:
    """The archive is closed cleanly and checkpointed at ``step`` with its newest row there, and
    its state is that of an uninterrupted run to ``step``, bit for bit."""
    from warpratchet.archive import open_archive, verify_archive

    assert f"{path} keeps the checkpoint at step {step}: run the same command again" in line_source
    verify_archive(path)  # every checksum and counter
    with open_archive(path) as arc:
        state, checkpoint = arc.checkpoint()
        rows = arc.series["step"]
    assert checkpoint == step and rows[-1] == step  # nothing lost: the row and checkpoint where it stopped
    fresh = Ensemble.sample(PARAMS, 40_000, "strip", seed=0).run(checkpoint)
    assert same_state(state, fresh.state())


@needs_posix
@pytest.mark.parametrize(
    ("signum", "verb", "status"), [(signal.SIGINT, "interrupted", 130), (signal.SIGTERM, "terminated", 143)]
)
def test_a_signal_to_the_cli_checkpoints_where_it_stops_and_the_same_command_continues(
    tmp_path, signum, verb, status
):
    """Ctrl-C or a scheduler's SIGTERM: one line, 130 / 143, the row and checkpoint at the step it
    names; the same command again continues from there (a second signal shows it moved on)."""
    path = tmp_path / "run.h5"
    argv = ["run", *MAP_FLAGS, "--points", "40000", "--steps", "100000000", "--chunk-steps", "1000"]
    argv += ["--out", str(path)]
    steps = []
    for _ in range(2):
        proc = launch(*argv)
        if steps:  # the archive is the command's alone until it says where it continues from
            said = _stderr_line(proc)
            assert said.startswith(f"warpratchet: continuing {path} from its checkpoint at step {steps[-1]} ")
        before = _rows(path)
        _wait_for(proc, lambda before=before: _rows(path) > before, "a new series row")
        proc.send_signal(signum)
        stdout, stderr = _finish(proc)
        assert proc.returncode == status, stderr
        assert stdout == ""
        steps.append(_stopped_line(stderr, verb, 100_000_000))
        _checkpointed_at(path, steps[-1], stderr)
    assert 0 < steps[0] < steps[1]


@needs_posix
def test_a_recording_beside_the_archive_ends_at_the_step_reached(tmp_path):
    pytest.importorskip("rerun", reason="rerun-sdk 0.41 (the rerun extra) needs Python >= 3.11")
    from rrd import cloud_frames, read_rrd, verify

    path, rrd = tmp_path / "run.h5", tmp_path / "run.rrd"
    proc = launch(
        "run", *MAP_FLAGS, "--points", "40000", "--steps", "100000000", "--chunk-steps", "1000",
        "--out", str(path), "--rerun", str(rrd),
    )  # fmt: skip
    _wait_for(proc, lambda: _rows(path) > 0, "a series row")
    proc.send_signal(signal.SIGINT)
    stdout, stderr = _finish(proc)
    assert proc.returncode == 130, stderr
    step = _stopped_line(stderr, "interrupted", 100_000_000)
    _checkpointed_at(path, step, stderr)
    verify(rrd)  # the recording was closed cleanly, its last frame at the step reached
    assert max(cloud_frames(read_rrd(rrd))) == step


@needs_posix
def test_a_second_ctrl_c_right_after_the_first_corrupts_nothing(tmp_path):
    """Two SIGINTs back to back: the second arrives while the first is being acted on (the chunk
    in flight, the row, the checkpoint, the close) and is only noted; the archive verifies."""
    path = tmp_path / "run.h5"
    proc = launch(
        "run",
        *MAP_FLAGS,
        "--points",
        "40000",
        "--steps",
        "100000000",
        "--chunk-steps",
        "1000",
        "--out",
        str(path),
    )
    _wait_for(proc, lambda: _rows(path) > 0, "a series row")
    proc.send_signal(signal.SIGINT)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = _finish(proc)
    assert proc.returncode == 130, stderr
    _checkpointed_at(path, _stopped_line(stderr, "interrupted", 100_000_000), stderr)


def test_a_second_ctrl_c_during_the_checkpoint_write_corrupts_nothing(tmp_path, monkeypatch):
    """A Ctrl-C delivered inside the checkpoint's write (after the slot's data, before its step)
    is noted, not acted on: the new checkpoint is complete and the archive verifies."""
    from warpratchet.archive import _rows, open_archive, verify_archive

    real_sync = _rows.sync_h5
    calls = []

    def interrupted_sync(f):
        calls.append(int(f["checkpoint"]["current"][0]))
        if len(calls) == 1:  # the slot's data written, its step not yet: the second Ctrl-C
            os.kill(os.getpid(), signal.SIGINT)
        real_sync(f)

    class FirstCtrlC(Observer):
        def after_chunk(self, ensemble, seconds):
            if ensemble.step == 3000:
                monkeypatch.setattr(_rows, "sync_h5", interrupted_sync)
                os.kill(os.getpid(), signal.SIGINT)

    path = tmp_path / "nb.h5"
    ens = Ensemble.sample(PARAMS, 2000, "strip", seed=4)
    with pytest.raises(KeyboardInterrupt):
        ens.run(10_000, [FirstCtrlC()], chunk_steps=1000, archive=path)
    assert ens.step == 3000 and len(calls) == 2  # one checkpoint, both of its syncs
    verify_archive(path)
    with open_archive(path) as arc:
        state, checkpoint = arc.checkpoint()
    assert checkpoint == 3000 and same_state(state, ens.state())


API_SCRIPT = textwrap.dedent(
    """
    import json, os, sys
    from warpratchet import Ensemble, MapParams

    path, signame = sys.argv[1], sys.argv[2]
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 40_000, "strip", seed=5, threads=2)
    try:
        ens.run(10**8, chunk_steps=1000, archive=path)
    except KeyboardInterrupt:
        print(json.dumps({"step": ens.step}), flush=True)
        # The notebook's way on: the same ensemble, the same archive.
        ens.run(3000, archive=path)
        print(json.dumps({"step": ens.step}), flush=True)
        sys.exit(0)
    finally:
        print(json.dumps({"finally": ens.step}), flush=True)  # SIGTERM unwinds too
    """
)


@needs_posix
@pytest.mark.parametrize(("signum", "status"), [(signal.SIGINT, 0), (signal.SIGTERM, 143)])
def test_a_signal_during_ensemble_run_with_an_archive_checkpoints_there(tmp_path, signum, status):
    """Ctrl-C: ``ens.run(rest, archive=same)`` continues, bit for bit. SIGTERM (default action):
    the run stops at the chunk end, checkpoints, unwinds and the process exits with 143."""
    from warpratchet import open_archive

    path = tmp_path / "nb.h5"
    proc = subprocess.Popen(
        [sys.executable, "-c", API_SCRIPT, str(path), signal.Signals(signum).name],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_for(proc, lambda: _rows(path) > 0, "a series row")
    proc.send_signal(signum)
    stdout, stderr = _finish(proc)
    assert proc.returncode == status, stderr
    reports = [json.loads(line) for line in stdout.splitlines()]
    stopped = reports[0]["step"] if signum == signal.SIGINT else reports[0]["finally"]
    assert stopped > 0
    final = reports[1]["step"] if signum == signal.SIGINT else stopped
    if signum == signal.SIGINT:
        assert final == stopped + 3000
    with open_archive(path) as arc:
        state, checkpoint = arc.checkpoint()
        rows = arc.series["step"]
    assert checkpoint == final and rows[-1] == final
    fresh = Ensemble.sample(PARAMS, 40_000, "strip", seed=5).run(final)
    assert same_state(state, fresh.state())


class _Ends(Observer):
    def __init__(self, name, log, fail_end=False):
        self.name, self.log, self.fail_end = name, log, fail_end

    def end(self, ensemble):
        self.log.append(self.name)
        if self.fail_end:
            raise RuntimeError(f"{self.name} failed to close")


def test_every_observer_ends_even_when_one_fails():
    log: list[str] = []
    ens = Ensemble.sample(PARAMS, 100, seed=1)
    with pytest.raises(RuntimeError, match="first failed"):
        ens.run(10, [_Ends("first", log, fail_end=True), _Ends("second", log)])
    assert log == ["first", "second"]
    assert ens.step == 10  # the run itself completed


def test_an_error_inside_a_chunk_marks_the_ensemble_undefined(monkeypatch):
    ens = Ensemble.sample(PARAMS, 1000, seed=1, threads=2)
    ens.run(20)
    calls = []
    original = ens._launch

    def flaky(lo, hi, step0, steps):
        calls.append(lo)
        if lo > 0:  # the second shard fails, the first advances: points at two different steps
            raise RuntimeError("launch failed")
        original(lo, hi, step0, steps)

    monkeypatch.setattr(ens, "_launch", flaky)
    with pytest.raises(RuntimeError, match="launch failed"):
        ens.run(10)
    assert ens.step == 20 and ens.undefined is not None and "from step 20 to 30" in ens.undefined
    with pytest.raises(ValueError, match="cannot be run"):
        ens.run(1)
    with pytest.raises(ValueError, match="no summary"):
        ens.summary()


def test_stops_requested_by_an_observer_end_chunks_there_for_it_only():
    class Stops(Observer):
        def __init__(self, steps):
            self.steps, self.seen = list(steps), []

        def next_stop(self, step):
            return next((s for s in self.steps if s > step), None)

        def after_chunk(self, ensemble, seconds):
            self.seen.append(ensemble.step)

    class Plain(Observer):
        def __init__(self):
            self.seen = []

        def after_chunk(self, ensemble, seconds):
            self.seen.append(ensemble.step)

    stops, plain = Stops([1, 2, 5, 13, 40]), Plain()
    ens = Ensemble.sample(PARAMS, 500, seed=2)
    ens.run(50, [stops, plain], chunk_steps=20)
    assert stops.seen == [1, 2, 5, 13, 20, 40, 50]
    assert plain.seen == [20, 40, 50]
    fresh = Ensemble.sample(PARAMS, 500, seed=2).run(50)
    assert same_state(ens.state(), fresh.state())  # stops never change the result


def test_deferral_only_in_the_main_thread_and_restores_the_handler():
    import threading

    from warpratchet.runloop import deferred_interrupts

    before = signal.getsignal(signal.SIGINT)
    with deferred_interrupts() as d:
        assert signal.getsignal(signal.SIGINT) == d.handler
    assert signal.getsignal(signal.SIGINT) is before
    seen = []

    def worker():
        with deferred_interrupts():
            seen.append(signal.getsignal(signal.SIGINT))

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert seen == [before]
    with pytest.raises(KeyboardInterrupt), deferred_interrupts():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # the handler runs here, notes the signal, and the block goes on
        seen.append("after")
    assert seen[-1] == "after"
