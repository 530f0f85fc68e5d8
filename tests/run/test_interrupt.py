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
import time

import numpy as np
import pytest
from support import MAP_FLAGS, launch, same_state

from warpratchet import Ensemble, MapParams, Observer
from warpratchet.history import block_steps, history_steps

PARAMS = MapParams(3.0, 0.1, 0.01)


def _interrupt_when(proc: subprocess.Popen, ready, settle: float = 0.5, timeout: float = 180) -> None:
    """Send SIGINT ``settle`` seconds after ``ready()`` holds (the run is under way)."""
    deadline = time.monotonic() + timeout
    while not ready():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.02)
    time.sleep(settle)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)


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
    assert proc.stdout.readline() == "started\n"  # after the first chunk
    _interrupt_when(proc, lambda: True)
    stdout, stderr = proc.communicate(timeout=120)
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


@needs_posix
@pytest.mark.parametrize("archived", [False, True])
def test_sigint_during_cli_run_is_one_line_and_exit_130(tmp_path, archived):
    """With an archive (ready: the file exists), or a recording (ready: the .rrd exists)."""
    if not archived:
        pytest.importorskip("rerun", reason="rerun-sdk 0.41 (the rerun extra) needs Python >= 3.11")
    argv = ["run", *MAP_FLAGS, "--points", "40000", "--steps", "100000000", "--chunk-steps", "1000"]
    path = tmp_path / ("run.h5" if archived else "run.rrd")
    argv += ["--out" if archived else "--rerun", str(path)]
    proc = launch(*argv)
    _interrupt_when(proc, path.exists)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stdout == "" and "Traceback" not in stderr
    [line] = stderr.strip().splitlines()
    assert line.startswith("warpratchet: interrupted at step ") and "of 100000000" in line
    step = int(line.split("at step ")[1].split()[0])
    # Chunks end at multiples of --chunk-steps, at the history's rows and block ends (log-spaced
    # and target j / 64), and at a recording's (log-spaced) frames.
    history_stops = {*history_steps(0, 100_000_000), *block_steps(0, 100_000_000)}
    assert step > 0 and (step % 1000 == 0 or step in history_stops or not archived)
    if archived:
        # Stopped at a chunk end (a series row), the run is checkpointed where it stopped: nothing
        # is lost. Stopped at a history stop between two rows, the archive keeps the checkpoint
        # of its last row (a checkpoint is complete only with the rows and history records up to
        # it), and the message names that step.
        saved = step if step % 1000 == 0 else None
        kept = int(line.split("keeps the checkpoint at step ")[1].split(":")[0])
        assert kept == saved if saved is not None else (kept < step and kept % 1000 == 0)
        assert f"{path} keeps the checkpoint at step {kept}: run the same command again" in line
        from warpratchet import open_archive

        with open_archive(path) as arc:  # closed cleanly: readable, its checkpoint exact
            state, checkpoint = arc.checkpoint()
            rows = arc.series["step"]
        assert checkpoint == kept and rows[-1] == step - step % 1000
        fresh = Ensemble.sample(PARAMS, 40_000, "strip", seed=0).run(checkpoint)
        assert same_state(state, fresh.state())
    else:
        from test_recording import cloud_frames, read_rrd, verify

        verify(path)  # the recording was closed cleanly, its last frame at the step reached
        assert max(cloud_frames(read_rrd(path))) == step


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
