"""Stops without a meeting: on several threads the run's shards go through the stops of a chunk on
their own, and the observers that take copies (a History) get the ensemble at their steps from
copies of its state (``warpratchet.runloop``, "Stops without a meeting").

Every number must be the one a stop gives: the rows, the block records and the state are compared
bit for bit with the same run whose threads meet at every stop (``runloop._copies`` returning
0), on 2 and 3 threads, with every copy held and with room for three copies only. And what a
stop guarantees still holds: a copy is the state at its step, it cannot be run, an error leaves the
ensemble whole (an observer's) or marked undefined (a shard's), and Ctrl-C stops the run at the end
of the chunk in flight.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from support import same_history, same_state

import warpratchet.ensemble as ensemble_module
import warpratchet.history as history_module
import warpratchet.runloop as runloop
from warpratchet import Ensemble, MapParams, Observer
from warpratchet.ensemble import _KERNEL_FIELDS
from warpratchet.history import History, block_steps, history_steps

PARAMS = MapParams(3.0, 0.1, 0.01)
POINTS, STEPS = 300, 2000


@pytest.fixture
def batches(monkeypatch):
    """The stops of each chunk that went through without a meeting (the copies' steps), per call."""
    seen = []
    real = Ensemble._advance_copying

    def advance_copying(self, stops, end, pool, at_copy):
        seen.append(list(stops))
        return real(self, stops, end, pool, at_copy)

    monkeypatch.setattr(Ensemble, "_advance_copying", advance_copying)
    return seen


def _history_run(threads: int, history: History, chunk_steps: int | None = None) -> Ensemble:
    ens = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=threads)
    return ens.run(STEPS, [history], chunk_steps=chunk_steps)


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("copies", [None, 3])
@pytest.mark.parametrize("settings", [{}, {"threshold_rule": "positive"}, {"threshold": 0.05}])
def test_copies_give_the_rows_blocks_and_state_of_stops_bit_for_bit(
    monkeypatch, batches, threads, copies, settings
):
    """A small ensemble run long stops at its 64 block steps and its rows; with copies the threads
    meet only at chunk ends (or, with room for three copies, at every fourth stop), and every row,
    block record, verdict and the end state are those of the run that stops at each."""
    monkeypatch.setattr(history_module, "STOP_STEPS", 0)  # the run stops at the block steps too
    if copies is not None:
        monkeypatch.setattr(ensemble_module, "COPY_BYTES", copies * 8 * len(_KERNEL_FIELDS) * POINTS)
    stops = sorted(set(history_steps(0, STEPS)) | set(block_steps(0, STEPS)))
    inside = [s for s in stops if s not in (1500, STEPS)]  # the chunks' ends: where the threads meet
    with_copies = History(block_points=64, **settings)
    ens = _history_run(threads, with_copies, chunk_steps=1500)
    assert "_copies" not in ens.__dict__  # the copies' buffers let go of after the run
    if copies is None:
        assert batches == [[s for s in inside if s < 1500], [s for s in inside if s > 1500]]
    else:  # each batch ends at the stop after three copies, where the threads meet
        copied = [step for batch in batches for step in batch]
        assert max(len(b) for b in batches) == copies and set(copied) < set(inside)
        assert len(copied) >= copies * (len(inside) // (copies + 1))
    monkeypatch.setattr(runloop, "_copies", lambda *args: 0)
    batches.clear()
    with_stops = History(block_points=64, **settings)
    reference = _history_run(threads, with_stops, chunk_steps=1500)
    assert not batches
    assert with_copies.block_rows["block_step"] == block_steps(0, STEPS)
    assert with_copies.rows["step"] == history_steps(0, STEPS)
    assert same_history(with_copies, with_stops)
    assert with_copies.convergence() == with_stops.convergence()
    assert same_state(ens.state(), reference.state()) and ens.step == STEPS


class Asks(Observer):
    """Asks for fixed steps; at each keeps what it was given."""

    takes_state_copies = True

    def __init__(self, steps, check=None):
        self.steps, self.check = list(steps), check
        self.seen, self.seconds, self.ended = [], [], False

    def next_stop(self, step):
        return next((s for s in self.steps if s > step), None)

    def after_chunk(self, ensemble, seconds):
        self.seen.append((ensemble.step, type(ensemble), ensemble.state()))
        self.seconds.append(seconds)
        if self.check is not None:
            self.check(ensemble)

    def end(self, ensemble):
        self.ended = True


def _fresh_at(step: int) -> dict:
    return Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=1).run(step).state()


def test_a_copy_is_the_state_at_its_step_read_only_and_cannot_be_run(batches):
    def check(copy):
        if copy.step in (13, 70):  # inside the chunks: copies
            with pytest.raises(ValueError, match=f"copy of the state at step {copy.step} .*cannot be run"):
                copy.run(1)
            assert not copy.array("x").flags.writeable and copy.threads == 1 and copy.run_pool is None

    asks = Asks([13, 70, 100], check)
    ens = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=2).run(120, [asks], chunk_steps=100)
    assert batches == [[13, 70]]
    assert [step for step, _, _ in asks.seen] == [13, 70, 100, 120]
    assert [kind.__name__ for _, kind, _ in asks.seen] == ["_StateCopy", "_StateCopy", "Ensemble", "Ensemble"]
    for step, _, state in asks.seen:
        assert same_state(state, _fresh_at(step))
    assert same_state(ens.state(), _fresh_at(120)) and all(s >= 0 for s in asks.seconds)


def test_an_observer_that_does_not_take_copies_sees_the_live_ensemble_at_every_stop(batches):
    class Live(Asks):
        takes_state_copies = False

    live, history = Live([13, 70]), History(block_points=64)
    Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=2).run(300, [live, history], chunk_steps=100)
    assert not batches  # one observer that needs the live ensemble: the threads meet at every stop
    assert [kind for _, kind, _ in live.seen] == [Ensemble] * 5  # 13, 70, 100, 200, 300


def test_an_observers_error_at_a_copy_leaves_the_ensemble_whole_at_the_chunks_end(batches):
    def check(copy):
        if copy.step == 70:
            raise RuntimeError("observer failed")

    asks, other = Asks([13, 70], check), Asks([])
    ens = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=2)
    with pytest.raises(RuntimeError, match="observer failed"):
        ens.run(300, [asks, other], chunk_steps=100)
    assert batches == [[13, 70]] and asks.ended and other.ended
    assert ens.undefined is None and ens.step == 100  # the shards went on to the chunk's end
    assert same_state(ens.state(), _fresh_at(100))
    assert same_state(ens.run(20).state(), _fresh_at(120))


def test_a_shards_error_during_copies_marks_the_ensemble_undefined(monkeypatch, batches):
    real = Ensemble._launch

    def launch(self, lo, hi, step0, steps):
        if lo > 0 and step0 >= 13:  # the second shard fails past the first copy
            raise RuntimeError("launch failed")
        real(self, lo, hi, step0, steps)

    monkeypatch.setattr(Ensemble, "_launch", launch)
    asks = Asks([13, 70])
    ens = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=2)
    with pytest.raises(RuntimeError, match="launch failed"):
        ens.run(300, [asks], chunk_steps=100)
    # the copy at 13 is seen unless the failure is noticed first
    assert batches == [[13, 70]] and [step for step, _, _ in asks.seen] in ([], [13]) and asks.ended
    assert ens.undefined is not None and "partway" in ens.undefined and ens.step == 0
    with pytest.raises(ValueError, match="cannot be run"):
        ens.run(1)


def test_ctrl_c_at_a_copy_stops_the_run_at_the_end_of_the_chunk_in_flight(batches):
    """The signal is deferred as at a stop: the shards finish their chunk, the copies still to come
    are seen, every observer sees the step where the run stops, then KeyboardInterrupt."""

    def check(copy):
        if copy.step == 13:
            os.kill(os.getpid(), signal.SIGINT)

    asks, plain = Asks([13, 70, 150], check), Asks([])
    ens = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=2)
    with pytest.raises(KeyboardInterrupt):
        ens.run(300, [asks, plain], chunk_steps=100)
    assert batches == [[13, 70]]
    assert [step for step, _, _ in asks.seen] == [13, 70, 100] and [s for s, _, _ in plain.seen] == [100]
    assert ens.step == 100 and ens.undefined is None and asks.ended and plain.ended
    assert same_state(ens.state(), _fresh_at(100))
    assert np.array_equal(asks.seen[1][2]["q"], _fresh_at(70)["q"])


@pytest.mark.parametrize("threads", [2, 3])
def test_several_pieces_per_thread_give_the_rows_and_state_of_stops_bit_for_bit(
    monkeypatch, batches, threads
):
    """With pieces of 64 points (several per thread, taken in order, each piece's stretches one after
    another), every row, block record and the end state are those of the run that stops at each."""
    monkeypatch.setattr(history_module, "STOP_STEPS", 0)
    monkeypatch.setattr(ensemble_module, "PIECE_POINTS", 64)
    pieces = Ensemble.sample(PARAMS, POINTS, "strip", seed=5, threads=threads)._copying_pieces()
    assert len(pieces) > threads
    with_copies = History(block_points=64)
    ens = _history_run(threads, with_copies, chunk_steps=1500)
    assert batches
    monkeypatch.setattr(runloop, "_copies", lambda *args: 0)
    with_stops = History(block_points=64)
    reference = _history_run(threads, with_stops, chunk_steps=1500)
    assert same_history(with_copies, with_stops)
    assert same_state(ens.state(), reference.state()) and ens.step == STEPS


@pytest.mark.parametrize("points", [1, 63, 64, 300, 5000, 100_000])
@pytest.mark.parametrize("threads", [2, 3, 8])
def test_the_pieces_cover_the_points_in_whole_blocks(points, threads):
    ens = Ensemble.sample(PARAMS, points, "strip", seed=5, threads=threads)
    pieces = ens._copying_pieces()
    assert pieces[0][0] == 0 and pieces[-1][1] == points
    assert all(a[1] == b[0] for a, b in zip(pieces[:-1], pieces[1:], strict=True))
    assert all(hi > lo and lo % 64 == 0 for lo, hi in pieces)
    assert len(pieces) <= max(threads, ensemble_module.PIECES_PER_THREAD * threads)
    if points >= ensemble_module.PIECE_POINTS * ensemble_module.PIECES_PER_THREAD * threads:
        assert len(pieces) == ensemble_module.PIECES_PER_THREAD * threads
