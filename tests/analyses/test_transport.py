"""Return times to B and flights (issue 16): the kernel variant against its NumPy twin, exactly.

Both step bodies (the CPU hooks decode per-step codes in blocks; the portable hooks count lane by
lane, as CUDA does) must give the NumPy twin's histograms count for count and its carry state
value for value, for any chunking, thread count, start step and resume; and the orbit must stay
the plain kernel's bit for bit.
"""

import threading

import numpy as np
import pytest
import warp as wp

from warpratchet import kernels, reference
from warpratchet.ensemble import Ensemble
from warpratchet.force import Force
from warpratchet.kernels._transport import BINS, CARRY_FIELDS, HISTOGRAMS, advance_map_transport
from warpratchet.params import MapParams
from warpratchet.transport import Histograms, TransportEnsemble, bin_of, edges, open_runs
from warpratchet.transport import _histograms as pure
from warpratchet.transport import _twin as twin

kernels.init_warp()
FIELDS = ("x", "q", "winding", "dx", "dp", "log_stretch")
# a plateau where K f = 1: flights of gain 1 of every length from 1 to over 128 steps, so runs of
# every length inside the decoder's blocks of 8 rows and across them
PLATEAU = MapParams(2.0, table=Force.from_knots([0, 0.125, 0.375, 0.5], [0, 0.5, 0.5, -0.6]))
# a strip inside (0, 1), one run of pieces (the paper's wraps around x = 0): the AVX-512 recording
# keeps its masks as they are, not their complement (record_avx512)
INNER_STRIP = MapParams(3.0, table=Force.from_knots([0, 0.25, 0.75], [0, -0.4, 0.4]))
CASES = [
    MapParams(3.0, 0.1, 0.01),  # the README's example: returns within 3 steps (Eq. Cs)
    MapParams(3.618033988749895, 0.05, 0.02),  # Fig. 1(b)
    MapParams(2.99, 0.25, 0.07),  # Fig. 9's path: returns of 256 steps and more
    MapParams(3.242, 0.088, 0.013),  # returns of 8-15 steps
    MapParams(0.5, 0.4, 0.3),  # weak kicks: long gaps, few flights
    MapParams(3.0, 1e-9, 1e-9),  # elliptic-sawtooth limit (slopes ~5e8)
    PLATEAU,
    INNER_STRIP,
]


def _start(p: MapParams, n: int = 1003, seed: int = 3) -> tuple[dict, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.random(n)
    kinks = list(p.table.knots) if p.b1 is None else [0.0, p.b1, 1.0 - p.b2]
    x[: len(kinks) + 1] = [*kinks, 0.5]  # on the kinks and the strip's edges
    q = rng.random(n) - 3.0
    return Ensemble(p, x, q, threads=1).state(), x


def _launches(p, state, carry, step0, pieces, body, block_rows=8):
    """Advance fresh arrays with ``advance_map_transport`` in launches of ``pieces`` steps
    (``block_rows``: the CPU hooks' decoding, 8-row blocks or the row loop alone)."""
    arrays = [wp.array(state[k], dtype=wp.int64 if k == "winding" else wp.float64) for k in FIELDS]
    extra = [wp.array(carry[k], dtype=wp.int64) for k in CARRY_FIELDS]
    counts = np.zeros(3 * BINS, dtype=np.int64)
    step = step0
    for steps in pieces:
        launch = wp.zeros(3 * BINS, dtype=wp.int64)
        advance_map_transport.launch(
            "cpu", arrays, [*extra, launch], step, steps, p, body=body, block_rows=block_rows
        )
        counts += launch.numpy()
        step += steps
    out = {k: a.numpy() for k, a in zip(FIELDS, arrays, strict=True)}
    return out, {k: e.numpy() for k, e in zip(CARRY_FIELDS, extra, strict=True)}, counts.reshape(3, BINS)


def test_the_pure_module_names_the_kernels_bins_and_fields():
    assert (pure.BINS, pure.HISTOGRAMS, pure.CARRY_FIELDS) == (BINS, HISTOGRAMS, CARRY_FIELDS)


def _case_id(p: MapParams) -> str:
    if p.b1 is None:  # a force given as a table
        return f"K{p.K:.4g}-" + ("plateau" if p is PLATEAU else "inner-strip")
    return f"K{p.K:.4g}-b{p.b1:g}-{p.b2:g}"


@pytest.mark.parametrize("p", CASES, ids=_case_id)
def test_both_step_bodies_count_exactly_what_the_numpy_twin_counts(p):
    """1003 points (lanes past the end) x 1500 steps from global step 5, in odd launches."""
    state, _ = _start(p)
    carry = twin.initial_carry(p, state["x"], 5)
    expected_state, expected_carry, expected = twin.advance(p, state, carry, 1500, step0=5)
    assert expected.sum() > 1000  # events happened
    if p is PLATEAU:  # its flights of 8 steps and more (bins 3 and up) happened
        assert expected[1, 3:].sum() > 100
    # block_rows=1: every row through the row loop, the path of an AVX-512 CPU without GFNI
    runs = [("cpu", [1500], 8), ("cpu", [3, 97, 1, 8, 600, 791], 8), ("cpu", [1500], 1)]
    runs += [("cpu", [3, 97, 1, 8, 600, 791], 1), ("portable", [700, 800], 8)]
    for body, pieces, block_rows in runs:
        got_state, got_carry, got = _launches(p, state, carry, 5, pieces, body, block_rows)
        np.testing.assert_array_equal(got, expected, err_msg=f"{body} {pieces} block_rows={block_rows}")
        for name in CARRY_FIELDS:
            np.testing.assert_array_equal(got_carry[name], expected_carry[name], err_msg=f"{name} {body}")
        for name in FIELDS:  # the orbit is the plain kernel's (the twin steps warpratchet.reference)
            np.testing.assert_array_equal(got_state[name], expected_state[name], err_msg=f"{name} {body}")


@pytest.mark.parametrize("body", ["cpu", "portable"])
def test_runs_open_for_a_million_steps_close_exactly(body):
    """A carry from far back (gaps and flights longer than any byte tracker) ends exactly.

    Points start at global step 10^6 with their last visit to B at step 17 and a flight of
    gain +1 or -1 in progress since step 3: the first visit closes a gap of ~10^6 steps (bin 19),
    the first step of another gain ends a flight of ~10^6 steps.
    """
    p = MapParams(3.0, 0.1, 0.01)
    state, _ = _start(p, n=77)
    step0 = 1_000_000
    carry = {
        "last_visit": np.full(77, 17, dtype=np.int64),
        "flight_gain": np.where(np.arange(77) % 2 == 0, 1, -1).astype(np.int64),
        "flight_start": np.full(77, 3, dtype=np.int64),
    }
    _, expected_carry, expected = twin.advance(p, state, carry, 300, step0=step0)
    for block_rows in (8, 1):
        _, got_carry, got = _launches(p, state, carry, step0, [5, 295], body, block_rows)
        np.testing.assert_array_equal(got, expected, err_msg=f"block_rows={block_rows}")
        for name in CARRY_FIELDS:
            np.testing.assert_array_equal(got_carry[name], expected_carry[name], err_msg=name)
    assert expected[0, 19] > 0 and expected[1, 19] > 0 and expected[2, 19] > 0


@pytest.mark.parametrize("init", ["strip", "torus"])
def test_counts_do_not_depend_on_threads_chunking_or_interruption(init):
    """1, 2 and 3 threads, chunks of 1 to 10^4 steps, a run split in three: the same counts.

    The chunks of one step cover the first 1000 steps (a launch per step costs milliseconds): every
    sampled spread step up to 1000 and returns of 64 steps and more span many launches there."""
    p = MapParams(2.99, 0.25, 0.07)

    def final(threads, pieces, chunks):
        ens = TransportEnsemble.sample(p, 1001, init, seed=5, threads=threads)
        for steps, chunk in zip(pieces, chunks, strict=True):
            ens.run(steps, chunk_steps=chunk)
        return ens.transport_state(), ens.state()

    transport, state = final(1, [4000], [10_000])
    assert transport.counts[0, 6:].sum() > 0  # returns of 64 steps and more: the trackers' int64 parts
    assert transport.spread_steps.tolist()[-3:] == [1778, 2371, 3162]  # round(10^(k/8)), any target
    for threads, pieces, chunks in (
        (2, [4000], [64]),
        (3, [1000, 3000], [1, 997]),
        (2, [1, 999, 3000], [333] * 3),
    ):
        other, other_state = final(threads, pieces, chunks)
        _assert_same_transport(other, transport, f"threads={threads} chunks={chunks} pieces={pieces}")
        for name in state:
            np.testing.assert_array_equal(other_state[name], state[name], err_msg=name)


def _assert_same_transport(got, expected, what: str = "") -> None:
    np.testing.assert_array_equal(got.counts, expected.counts, err_msg=f"counts {what}")
    for name in CARRY_FIELDS:
        np.testing.assert_array_equal(got.carry[name], expected.carry[name], err_msg=f"{name} {what}")
    np.testing.assert_array_equal(got.spread_steps, expected.spread_steps, err_msg=f"spread steps {what}")
    np.testing.assert_array_equal(got.spread, expected.spread, err_msg=f"spread {what}")


def test_an_ensemble_rebuilt_from_its_transport_state_continues_exactly():
    p = MapParams(3.0, 0.1, 0.01)
    whole = TransportEnsemble.sample(p, 500, "torus", seed=2)
    whole.run(2000)
    half = TransportEnsemble.sample(p, 500, "torus", seed=2)
    half.run(777)
    again = TransportEnsemble.from_state(p, half.state(), half.step, transport=half.transport_state())
    again.run(2000 - 777)
    _assert_same_transport(again.transport_state(), whole.transport_state())


def test_the_orbit_is_the_plain_kernels():
    p = MapParams(3.0, 0.1, 0.01)
    plain = Ensemble.sample(p, 700, "strip", seed=4).run(900, chunk_steps=100).state()
    counted = TransportEnsemble.sample(p, 700, "strip", seed=4).run(900, chunk_steps=100).state()
    for name, values in plain.items():
        np.testing.assert_array_equal(counted[name], values, err_msg=name)


def test_returns_at_K3_take_at_most_three_steps_and_flights_are_counted_by_sign():
    """At K = 3 the chaotic region is C = B u MB u M^2 B (Eq. Cs): a strip orbit is back in B
    within three steps, so every return gap is 1, 2 or 3 (bins 0 and 1)."""
    p = MapParams(3.0, 0.1, 0.01)
    ens = TransportEnsemble.sample(p, 2000, "strip", seed=1)
    ens.run(3000)
    h = ens.histograms()
    assert h.return_times[:2].sum() > 0 and h.return_times[2:].sum() == 0
    assert h.flights_plus.sum() > 0 and h.flights_minus.sum() > 0


def test_first_gap_counts_from_step_zero_only_for_points_that_start_in_B():
    p = MapParams(3.0, 0.1, 0.01)
    x = np.array([0.05, 0.5, 0.995, p.b1, 1.0 - p.b2, np.nextafter(p.b1, 1.0)])
    carry = twin.initial_carry(p, x, 0)
    np.testing.assert_array_equal(carry["last_visit"], [0, -1, 0, 0, 0, -1])
    ens = TransportEnsemble(p, x, np.zeros_like(x))
    np.testing.assert_array_equal(ens.transport_state().carry["last_visit"], carry["last_visit"])


def test_bins_edges_and_open_runs():
    np.testing.assert_array_equal(
        bin_of([1, 2, 3, 4, 7, 8, 2**40 - 1, 2**40, 2**62]), [0, 1, 1, 2, 2, 3, 39, 40, 62]
    )
    with pytest.raises(ValueError, match=">= 1"):
        bin_of([0])
    assert edges(3) == [1, 2, 4, 8]
    carry = {
        "last_visit": np.array([-1, 10, 99]),
        "flight_gain": np.array([0, 2, -1]),
        "flight_start": np.array([5, 97, 100]),
    }
    h = open_runs(carry, 100)
    assert h.return_times.tolist()[:7] == [0, 1, 0, 0, 0, 0, 1]  # gaps of >= 2 and >= 91 steps
    assert h.flights_plus.tolist()[:3] == [0, 0, 1] and h.flights_minus.tolist()[:1] == [1]
    d = Histograms.from_counts(np.arange(3 * BINS).reshape(3, BINS) * 0 + 1, 10).as_dict(bins=2)
    assert d == {
        "return_times": {"edges": [1, 2, 4], "counts": [1, 1]},
        "flights": {"edges": [1, 2, 4], "counts_plus": [1, 1], "counts_minus": [1, 1]},
    }


def test_twin_steps_like_the_reference():
    """The twin's orbit is warpratchet.reference's (one call per step equals one call for all)."""
    p = MapParams(3.0, 0.1, 0.01)
    state, _ = _start(p, n=50)
    got, _, _ = twin.advance(p, state, twin.initial_carry(p, state["x"], 3), 40, step0=3)
    expected = reference.advance(p, state, 40, step0=3)
    for name in FIELDS:
        np.testing.assert_array_equal(got[name], expected[name], err_msg=name)


def test_a_block_size_outside_the_decoders_is_refused():
    p = MapParams(3.0, 0.1, 0.01)
    state, _ = _start(p, n=40)
    with pytest.raises(ValueError, match="block_rows = 16 is not one of the allowed values 1, 8"):
        _launches(p, state, twin.initial_carry(p, state["x"], 0), 0, [8], "cpu", 16)


def test_two_threads_on_one_scratch_are_refused_not_miscounted():
    """The CPU hooks share a launch's scratch on the assumption that Warp runs its threads one
    after the other; two launches given one scratch and run at once (Warp releases the GIL) break
    it, and the guard must turn that into an error rather than counts that are silently wrong."""
    from warpratchet.kernels._transport_cpu import SCRATCH_BYTES

    p = MapParams(3.0, 0.1, 0.01)
    state, x = _start(p, n=20000)
    carry = twin.initial_carry(p, x, 0)
    scratch = wp.zeros(SCRATCH_BYTES, dtype=wp.uint8)
    start = threading.Barrier(2, timeout=900)  # a thread that never comes fails the test
    errors: list[str] = []

    def launch() -> None:
        arrays = [wp.array(state[k], dtype=wp.int64 if k == "winding" else wp.float64) for k in FIELDS]
        extra = [wp.array(carry[k], dtype=wp.int64) for k in CARRY_FIELDS]
        start.wait()
        try:
            # 8 x 10^8 point-steps each: long enough that the two overlap on two cores and, through
            # the scheduler's time slices, on one busy core too
            advance_map_transport.launch(
                "cpu", arrays, [*extra, wp.zeros(3 * BINS, dtype=wp.int64)], 0, 40_000, p, scratch=scratch
            )
        except RuntimeError as error:
            errors.append(str(error))

    threads = [threading.Thread(target=launch) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors, "two launches shared one scratch at once and neither noticed"
    assert "used its scratch at once" in errors[0]
    # and a launch of its own, the same arrays, is not flagged (every other test relies on it)
    _launches(p, state, carry, 0, [40], "cpu")


def test_the_cli_refuses_a_flagged_launch_in_one_line_with_status_1(monkeypatch, capsys):
    """A launch the guard flags is not the user's input: one error line, status 1, no counts."""
    from warpratchet.cli import main
    from warpratchet.kernels._transport_cpu import CONFLICT_WORD, SCRATCH_BYTES

    launch = advance_map_transport.launch

    def flagged(*args, **kwargs):
        scratch = np.zeros(SCRATCH_BYTES, dtype=np.uint8)
        scratch.view(np.int64)[CONFLICT_WORD] = 1  # as if another thread had been there
        return launch(*args, scratch=wp.array(scratch, dtype=wp.uint8), **kwargs)

    monkeypatch.setattr(advance_map_transport, "launch", flagged)
    argv = ["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "64", "--steps", "16"]
    code = main([*argv, "--transport", "--json", "--quiet"])
    captured = capsys.readouterr()
    assert code == 1 and captured.out == "", captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warpratchet: error: two CPU threads"), captured.err


def test_the_spread_classifies_as_the_run_is_told_and_refuses_bad_settings():
    ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 16, "strip", seed=0)
    assert (ens.threshold, ens.threshold_rule) == (None, "strict")
    assert ens.classify_with(0.5) is ens and (ens.threshold, ens.threshold_rule) == (0.5, "strict")
    assert ens.classify_with(threshold_rule="positive").threshold_rule == "positive"
    with pytest.raises(ValueError, match="threshold_rule = 'loose' is not one of"):
        ens.classify_with(threshold_rule="loose")
    with pytest.raises(ValueError, match="threshold = -1"):
        ens.classify_with(-1.0)
