"""The Warp kernels against their NumPy twin, bit for bit, and the tangent bookkeeping.

Kernel tests run on every device: ``cpu`` and ``cuda:0`` (skipped where there is no GPU). On
CUDA, with ``fuse_fp=False`` (no FMA contraction) and IEEE division and square root, the orbit and
the tangent are the CPU's bit for bit; ``log`` is CUDA's own, so the log-stretch is compared to a
few ulp (compiled here with NVRTC, not run: this machine has no GPU).
"""

import concurrent.futures
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import warp as wp

from warpratchet import kernels, reference, theory
from warpratchet.ensemble import Ensemble
from warpratchet.observables import lyapunov, summarize
from warpratchet.params import MapParams
from warpratchet.sumrule import IndicatorEnsemble

kernels.init_warp()
DEVICES = [
    "cpu",
    pytest.param(
        "cuda:0",
        marks=pytest.mark.skipif(not wp.is_cuda_available(), reason="no CUDA device on this machine"),
    ),
]
FIELDS = ("x", "q", "winding", "dx", "dp", "log_stretch")

CASES = [
    MapParams(3.0, 0.1, 0.01),  # domain LR, Fig. 7 range
    MapParams(3.0, 0.3, 0.03),  # domain R, Fig. 12
    MapParams(3.618033988749895, 0.05, 0.02),  # Fig. 1(b)
    MapParams(2.99, 0.25, 0.07),  # Fig. 9's path
    MapParams(3.0, 1e-9, 1e-9),  # elliptic-sawtooth limit, Fig. 2 (slopes ~5e8)
    MapParams(0.5, 0.4, 0.3),  # weak kicks, no islands of acceleration
]


def _start(p: MapParams, n: int = 1000, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    # Include exact kink positions and p values that push t = q + K f across integers.
    x = rng.random(n)
    x[:4] = [0.0, p.b1, 1.0 - p.b2, 0.5]
    q = rng.random(n) - 3.0  # negative momenta exercise the winding bookkeeping
    return x, q


def _ensemble(p: MapParams, n: int = 1000, seed: int = 3, threads: int = 2, device: str = "cpu") -> Ensemble:
    return Ensemble(p, *_start(p, n, seed), threads=threads, device=device)


def _assert_reference(got: dict, expected: dict, device: str) -> None:
    """Bitwise on the CPU; on CUDA bitwise but for the log-stretch (CUDA's log, see the docstring)."""
    for name in FIELDS:
        if device != "cpu" and name == "log_stretch":
            np.testing.assert_allclose(got[name], expected[name], rtol=1e-14, atol=0, err_msg=name)
        else:
            np.testing.assert_array_equal(got[name], expected[name], err_msg=f"{name} on {device}")


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("p", CASES, ids=lambda p: f"K{p.K:.4g}-b{p.b1:g}-{p.b2:g}")
def test_kernel_equals_numpy_reference_bit_for_bit(p, device):
    """1000 points x 500 steps, started at global step 3 so renormalisation checks are off-phase."""
    ens = _ensemble(p, device=device)
    ens.step = 3  # a run resumed from step 3: the checks fall on global steps 8, 16, ...
    start = ens.state()
    ens.run(500, chunk_steps=97)
    expected = reference.advance(p, start, 500, step0=3)
    got = ens.state()
    _assert_reference(got, expected, device)
    assert np.all((got["x"] >= 0) & (got["x"] < 1)) and np.all((got["q"] >= 0) & (got["q"] < 1))


def _folding(p: MapParams, n: int, folds: int = 16, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points of which the first ``folds`` fold ``q`` in their first step: ``x`` just above
    the zero ``c`` of the middle piece of Eq. (fx), where ``K f`` is a tiny negative, and ``q`` the
    next double below ``-K f``, so that ``t = q + K f`` is a negative of ~1e-32 and
    ``t - floor(t)`` rounds to 1 (folded to 0, one more whole unit: ``kernels._step``)."""
    rng = np.random.default_rng(seed)
    x, q = rng.random(n), rng.random(n)
    x[:folds] = np.nextafter(p.table.fields()["c"], 1.0) + np.arange(folds) * 2.0**-53
    q[:folds] = np.nextafter(-p.K * p.table.evaluate(x[:folds])[0], 0.0)
    return x, q


@pytest.mark.parametrize("steps", [1, 40])
def test_the_fold_of_q_is_the_references_on_every_cpu_kernel(steps):
    """Where ``q + K f`` lies just below an integer: the paired map and indicator kernels and
    transport's steps (whose short-chain step takes the position from a choice between ``x + frac``
    and ``x + 0``, made by the fold's test) give the reference's bits."""
    from warpratchet.transport import TransportEnsemble

    p = CASES[0]
    x, q = _folding(p, 200)
    start = Ensemble(p, x, q, threads=1).state()
    assert np.all(reference.advance(p, start, 1)["q"][:16] == 0.0)  # every fold happened
    expected = reference.advance(p, start, steps)
    for cls in (Ensemble, IndicatorEnsemble, TransportEnsemble):
        ens = cls(p, x, q, threads=2)
        ens.run(steps)
        _assert_reference(ens.state(), expected, "cpu")


@pytest.mark.parametrize("n", [4, 31, 32, 33, 63, 64, 65, 97, 129, 200])
def test_every_size_of_ensemble_and_shard_is_the_reference_bit_for_bit(n):
    """Sizes around a Warp thread's lanes and two blocks of them (the CPU body's threads take two;
    a last block partly or wholly past the end, shards on 1, 2 and 3 threads), with the
    indicators, whose steps are the map's."""
    p = MapParams(3.0, 0.1, 0.01)
    x, q = _start(p, n)
    zeros = {name: np.zeros(n) for name in reference.INDICATOR_FIELDS}
    state, accumulators = reference.advance_indicators(p, Ensemble(p, x, q, threads=1).state(), zeros, 300)
    for threads in (1, 2, 3):
        ens = Ensemble(p, x, q, threads=threads)
        ens.run(300, chunk_steps=101)
        _assert_reference(ens.state(), state, "cpu")
        indicators = IndicatorEnsemble(p, x, q, threads=threads).run(300, chunk_steps=101)
        _assert_reference(indicators.state(), state, "cpu")
        for name, array in zip(reference.INDICATOR_FIELDS, indicators._extra_arrays(), strict=True):
            np.testing.assert_array_equal(array.numpy(), accumulators[name], err_msg=name)


@pytest.mark.parametrize("device", DEVICES)
def test_global_steps_past_2_to_the_31_renormalise_in_phase(device):
    """Global step numbers are 64-bit: a run resumed at step 2^33 + 3 checks at multiples of 8."""
    p = MapParams(3.0, 0.05, 0.02)
    ens = _ensemble(p, n=300, device=device)
    ens.step = 2**33 + 3
    start = ens.state()
    ens.run(1500, chunk_steps=250)
    expected = reference.advance(p, start, 1500, step0=2**33 + 3)
    assert np.count_nonzero(expected["log_stretch"]) > 30  # the checks did renormalise
    _assert_reference(ens.state(), expected, device)


def test_a_chunk_of_2_to_the_32_steps_is_split_into_launches_not_dropped(monkeypatch):
    """Issue 13.1: 2^32 steps in one chunk once ran as 0 (the kernel's step count is 32-bit).

    The launches are recorded instead of run (2^32 real steps would take minutes): they must
    cover every step, from consecutive global steps, each within the kernel's 32-bit counter.
    """
    launches = []
    monkeypatch.setattr(
        Ensemble, "_launch", lambda self, lo, hi, step0, steps: launches.append((lo, hi, step0, steps))
    )
    ens = _ensemble(MapParams(3.0, 0.1, 0.01), n=8, threads=1)
    # Ensemble.run caps a chunk at MAX_CHUNK_STEPS (a RunSpec bound); the launcher below it must
    # still carry any count it is given.
    ens._advance(2**32 + 5, None)
    assert ens.step == 2**32 + 5
    assert sum(steps for *_, steps in launches) == 2**32 + 5
    assert all(0 < steps <= kernels.MAX_LAUNCH_STEPS < 2**31 for *_, steps in launches)
    assert [step0 for _, _, step0, _ in launches] == [0, *np.cumsum([s for *_, s in launches])[:-1]]
    assert {(lo, hi) for lo, hi, *_ in launches} == {(0, 8)}


def test_a_failing_shard_on_the_calling_thread_waits_for_the_pools_shards(monkeypatch):
    """With a pool, the calling thread launches the first shard itself. If that launch raises, the
    error must reach the caller only after the pool's shards have finished: until then they write
    the ensemble's arrays. The pool's shard here finishes only once the ensemble waits for it."""
    import warpratchet.ensemble as ensemble_module

    waiting, finished = threading.Event(), threading.Event()

    def launch(self, lo, hi, step0, steps):
        if lo == 0:
            raise RuntimeError("the first shard failed")
        assert waiting.wait(60), "the ensemble never waited for the pool's shard"
        finished.set()

    def wait(futures):
        waiting.set()
        return concurrent.futures.wait(futures)

    monkeypatch.setattr(Ensemble, "_launch", launch)
    monkeypatch.setattr(ensemble_module, "wait", wait)
    ens = _ensemble(MapParams(3.0, 0.1, 0.01), n=64, threads=2)
    with ThreadPoolExecutor(2) as pool:
        try:
            with pytest.raises(RuntimeError, match="the first shard failed"):
                ens._advance(5, pool)
            assert finished.is_set()
            assert ens.step == 0  # the failed chunk is not counted
        finally:
            waiting.set()  # never leave the pool's thread blocked, whatever failed above


def test_a_launch_refuses_a_step_count_it_cannot_carry():
    ens = _ensemble(MapParams(3.0, 0.1, 0.01), n=8, threads=1)
    arrays = [ens._arrays[name] for name in FIELDS]
    message = r"steps = 2147483648 is outside the allowed range 0 <= steps <= 2147483647"
    with pytest.raises(ValueError, match=message):
        kernels.advance_map.launch("cpu", arrays, [], 0, 2**31, ens.params)


def test_a_replayed_launch_advances_the_arrays_the_ensemble_holds_now():
    """An ensemble records each shard's launch once and replays it chunk after chunk
    (``AdvanceKernel.recorded``); an array replaced by another object must be the one advanced
    from then on, never the one the launch was recorded with."""
    p = MapParams(3.0, 0.1, 0.01)
    ens, twin = (Ensemble.sample(p, 1001, "torus", seed=5, threads=2) for _ in range(2))
    ens.run(10, chunk_steps=3)
    recorded = dict(ens._recorded)
    assert len(recorded) == 2  # one per shard
    old = ens._arrays["dx"]
    ens._arrays["dx"] = wp.clone(old)
    old.fill_(np.nan)  # a replay of the old recording would advance these, and leave the new dx behind
    ens._views.clear()
    ens.run(10, chunk_steps=3)
    assert all(ens._recorded[shard][1] is not launch for shard, (_, launch) in recorded.items())
    twin.run(20)
    for name, values in twin.state().items():
        np.testing.assert_array_equal(ens.state()[name], values, err_msg=name)


def _advance_arrays(kernel, body, p, x, q, step0, steps, extra_fields=0):
    """Advance fresh state arrays (tangent (1, 0)) with ``kernel`` on one step body on the CPU."""
    state = Ensemble(p, x, q, threads=1).state()
    arrays = [wp.array(state[name], dtype=wp.int64 if name == "winding" else wp.float64) for name in FIELDS]
    extra = [wp.zeros(x.size, dtype=wp.float64) for _ in range(extra_fields)]
    kernel.launch("cpu", arrays, extra, step0, steps, p, body=body)
    return [a.numpy() for a in arrays + extra]


@pytest.mark.parametrize(
    ("kernel", "extra_fields"),
    [(kernels.advance_map, 0), (kernels.advance_map_indicators, 3)],
    ids=["advance_map", "advance_map_indicators"],
)
@pytest.mark.parametrize("p", CASES, ids=lambda p: f"K{p.K:.4g}-b{p.b1:g}-{p.b2:g}")
def test_cpu_and_portable_step_bodies_agree_bit_for_bit(kernel, extra_fields, p):
    """The CPU body (vector C++), the portable Warp body and the one-point kernel (what CUDA
    runs) on the same CPU.

    1003 points (not a multiple of the 32 lanes, so a thread has lanes past the end) x 1200
    steps from global step 3; every state field and every indicator accumulator must agree.
    """
    x, q = _start(p, n=1003)
    step0 = 0 if extra_fields else 3  # the indicators start at global step 0
    cpu = _advance_arrays(kernel, "cpu", p, x, q, step0, 1200, extra_fields)
    portable = _advance_arrays(kernel, "portable", p, x, q, step0, 1200, extra_fields)
    for name, a, b in zip([*FIELDS, "extra0", "extra1", "extra2"], cpu, portable, strict=False):
        np.testing.assert_array_equal(a, b, err_msg=name)
    # The one-point kernel (what a GPU runs), state and accumulators.
    point = _advance_arrays(kernel, "point", p, x, q, step0, 1200, extra_fields)
    for name, a, b in zip([*FIELDS, "extra0", "extra1", "extra2"], cpu, point, strict=False):
        np.testing.assert_array_equal(a, b, err_msg=f"{name} (one point per thread)")
    if p in CASES[:4]:  # chaotic enough that the renormalisation branch ran on both bodies
        assert np.count_nonzero(cpu[FIELDS.index("log_stretch")]) > 100


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("p", CASES, ids=lambda p: f"K{p.K:.4g}-b{p.b1:g}-{p.b2:g}")
def test_indicator_kernel_equals_numpy_reference_bit_for_bit(p, device):
    """MEGNO and FLI accumulators against ``reference.advance_indicators`` (``fdlog`` in both).

    1003 points x 1203 steps in chunks of 97 on 2 threads. On CUDA the renormalisation's ``log``
    is CUDA's, so the log-stretch agrees to 1e-14 (see the module docstring) and the
    accumulators, sums of ~150 such values whose MEGNO part is a difference of two of them, to 1e-12.
    """
    x, q = _start(p, n=1003)
    ens = IndicatorEnsemble(p, x, q, threads=2, device=device).run(1203, chunk_steps=97)
    zeros = {name: np.zeros(x.size) for name in reference.INDICATOR_FIELDS}
    state, expected = reference.advance_indicators(p, _ensemble(p, n=1003).state(), zeros, 1203)
    _assert_reference(ens.state(), state, device)
    for name, array in zip(reference.INDICATOR_FIELDS, ens._extra_arrays(), strict=True):
        if device == "cpu":
            np.testing.assert_array_equal(array.numpy(), expected[name], err_msg=name)
        else:
            np.testing.assert_allclose(array.numpy(), expected[name], rtol=1e-12, atol=1e-12, err_msg=name)
    assert np.count_nonzero(expected["megno_ysum"]) > 900  # the checkpoints ran


# A variant that uses the step's facts: per point, the steps that ended in B and the whole units
# gained, summed in the kernel (the pattern of return times and flights, issue 16).
@wp.struct
class _FactArrays:
    visits: wp.array(dtype=wp.float64)
    gained: wp.array(dtype=wp.float64)


@wp.struct
class _FactSums:
    visits: kernels._step.LaneVector
    gained: kernels._step.LaneVector


@wp.func
def _load_sums(arrays: _FactArrays, first: int, spacing: int, n: int):
    acc = _FactSums()
    acc.visits = kernels._step.load_lane_vector(arrays.visits, first, spacing, n)
    acc.gained = kernels._step.load_lane_vector(arrays.gained, first, spacing, n)
    return acc


@wp.func
def _store_sums(arrays: _FactArrays, acc: _FactSums, first: int, spacing: int, n: int):
    kernels._step.store_lane_vector(arrays.visits, acc.visits, first, spacing, n)
    kernels._step.store_lane_vector(arrays.gained, acc.gained, first, spacing, n)


@wp.func
def _add_facts(acc: wp.ref[_FactSums], s: wp.ref[kernels.Lanes], global_step: wp.int64):
    for k in range(wp.static(kernels.INTERLEAVE)):
        acc.visits[k] = acc.visits[k] + s.in_strip[k]
        acc.gained[k] = acc.gained[k] + s.gain[k]


@wp.func
def _no_check(acc: wp.ref[_FactSums], s: wp.ref[kernels.Lanes], check: wp.int64):
    pass


_FACTS = kernels.advance_kernel(
    kernels.Variant("test_facts", _FactArrays, _FactSums, _load_sums, _store_sums, _add_facts, _no_check),
    module_suffix=".test_facts",
)


def test_a_variant_with_per_step_work_keeps_out_of_the_paired_kernels_module():
    """Where the map's threads take two blocks (the CPU body), its module is built with the
    scheduler off; a variant with per-step work given no module suffix gets modules of its own,
    so that building it does not change the shared module's flags."""
    from warpratchet.kernels._runtime import PAIRED_CPU_FLAGS
    from warpratchet.kernels._step import PAIRED

    variant = kernels.Variant(
        "test_facts_shared", _FactArrays, _FactSums, _load_sums, _store_sums, _add_facts, _no_check
    )
    kernel = kernels.advance_kernel(variant)
    shared = kernels.advance_map.cpu.module
    assert kernels.advance_map.cpu_paired is PAIRED and not kernel.cpu_paired
    assert (kernel.cpu.module.name != shared.name) is PAIRED
    assert (PAIRED_CPU_FLAGS in shared.options["cpu_compiler_flags"]) is PAIRED


@pytest.mark.parametrize("body", ["cpu", "portable"])
def test_a_variant_sees_each_steps_gain_and_whether_it_ended_in_the_strip(body):
    """The facts a variant gets per step, against the NumPy twin stepped one step at a time."""
    p = MapParams(3.0, 0.1, 0.01)
    x, q = _start(p, n=333)
    steps = 300
    got = _advance_arrays(_FACTS, body, p, x, q, 5, steps, extra_fields=2)
    state = Ensemble(p, x, q, threads=1).state()
    visits, gained = np.zeros(x.size), np.zeros(x.size)
    for s in range(steps):
        after = reference.advance(p, state, 1, step0=5 + s)
        visits += (after["x"] <= p.b1) | (after["x"] >= 1.0 - p.b2)
        gained += after["winding"] - state["winding"]
        state = after
    assert 0 < visits.sum() < visits.size * steps and np.count_nonzero(gained) > 0
    np.testing.assert_array_equal(got[6], visits)
    np.testing.assert_array_equal(got[7], gained)
    np.testing.assert_array_equal(got[FIELDS.index("winding")], state["winding"])


def test_portable_kernels_compile_for_cuda(tmp_path):
    """What runs on CUDA compiles for CUDA (NVRTC, no GPU needed); the CPU body is never built for it."""
    runtime = wp._src.context.runtime
    archs = sorted(getattr(runtime, "nvrtc_supported_archs", None) or [])
    if not archs:
        pytest.skip("Warp has no NVRTC on this machine (CUDA-enabled warp-lang needed)")
    arch = 86 if 86 in archs else archs[-1]
    module = kernels.advance_map.portable.module
    assert module is kernels.advance_map_indicators.portable.module
    assert module is not kernels.advance_map.cpu.module
    (artifact,) = wp.compile_aot_module(module, arch=arch, module_dir=tmp_path)
    assert artifact.stat().st_size > 0


@pytest.mark.parametrize("device", DEVICES)
def test_renormalisation_was_exercised_and_matches_every_step_normalisation(device):
    """Threshold renormalisation (every 8 steps, |dx| > 1e100) against the textbook per-step one."""
    p = MapParams(3.0, 0.05, 0.02)
    ens = _ensemble(p, n=400, device=device)
    start = ens.state()
    ens.run(2000)
    got = ens.state()
    assert np.count_nonzero(got["log_stretch"]) > 50  # the chaotic points passed 1e100, some twice
    textbook = reference.advance_renormalising_every_step(p, start, 2000)
    np.testing.assert_array_equal(got["x"], textbook["x"])
    ftle, ftle_textbook = lyapunov(got, 2000), lyapunov(textbook, 2000)
    chaotic = ftle_textbook > 0.01
    rel = np.abs(ftle[chaotic] - ftle_textbook[chaotic]) / ftle_textbook[chaotic]
    assert rel.max() < 1e-12
    assert np.abs(ftle[~chaotic] - ftle_textbook[~chaotic]).max() < 1e-12


@pytest.mark.parametrize("device", DEVICES)
def test_tangent_map_has_unit_determinant_in_the_kernel(device):
    """det DM = 1: propagate (1, 0) and (0, 1) one step with the kernel, form the 2x2 matrix."""
    p = MapParams(3.0, 0.1, 0.05)
    x = np.linspace(0, 1, 2001, endpoint=False)
    columns = []
    for tangent in ((1.0, 0.0), (0.0, 1.0)):
        ens = Ensemble(p, x, np.full_like(x, 0.3))
        st = ens.state()
        st["dx"][:], st["dp"][:] = tangent
        ens = Ensemble.from_state(p, st, 0, device=device)
        ens.run(1)
        columns.append((ens.array("dx").copy(), ens.array("dp").copy()))
    (a, c), (b, d) = columns
    det = a * d - b * c
    np.testing.assert_allclose(det, 1.0, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(np.stack([[a, b], [c, d]]).transpose(2, 0, 1), p.jacobian(x))


@pytest.mark.parametrize("device", DEVICES)
def test_results_do_not_depend_on_thread_count_or_chunking(device):
    """Bitwise identical for 1, 2 and 3 threads, any chunk length, and a run split in pieces.

    (On a GPU the CPU thread count does not apply; the chunkings still must not matter.)
    """
    p = MapParams(3.0, 0.1, 0.01)

    def final(threads, pieces, chunk):
        ens = Ensemble.sample(p, 1001, "torus", seed=5, threads=threads, device=device)
        for steps in pieces:
            ens.run(steps, chunk_steps=chunk)
        return ens.state()

    reference_state = final(1, [3000], 10_000)
    for threads, pieces, chunk in ((2, [3000], 64), (3, [200, 2800], 1), (2, [1, 999, 2000], 333)):
        other = final(threads, pieces, chunk)
        for name, values in reference_state.items():
            np.testing.assert_array_equal(values, other[name], err_msg=f"{name} threads={threads}")


@pytest.mark.parametrize("device", DEVICES)
def test_momentum_keeps_full_precision_far_from_the_origin(device):
    """An accelerator-mode point gains one unit per step; after 10^5 steps p ~ 1e5 and x is still exact."""
    p = MapParams(3.0, 0.1, 0.01)
    (x0,) = [x for w, x in theory.accelerator_modes(p) if w == 1]
    # Off the fixed point (p0 = 0.02): an orbit inside the L island, rotating around it.
    ens = Ensemble(p, np.array([x0]), np.array([0.02]), threads=1, device=device)
    ens.run(100_000)
    assert ens.momentum()[0] == pytest.approx(0.02 + 100_000, abs=0.2)
    assert 0.0 <= ens.array("x")[0] < 1.0


@pytest.mark.parametrize("device", DEVICES)
def test_state_is_56_bytes_per_point(device):
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 10, "torus", device=device)
    assert sum(ens.array(name).itemsize for name in ens.state()) == 56


def _devices():
    return [str(d) for d in wp.get_devices()]


@pytest.mark.parametrize("device", _devices())
def test_every_warp_device_gives_the_reference_result(device):
    """The same kernel on every device Warp sees (``cpu`` here; ``cuda:N`` where a GPU exists).

    Neither build contracts ``a*b + c`` into FMAs (``fuse_fp=False``), so the orbit and the
    tangent are NumPy's bit for bit on every device, over 2000 steps (the tangent renormalised
    many times). The log-stretch is bitwise on the CPU; on a GPU, CUDA's ``log`` is not the C
    library's (correctly rounded to within 1 ulp in both), so the sum of ~3 logs agrees to 1e-14.
    """
    p = MapParams(3.0, 0.1, 0.01)
    ens = Ensemble.sample(p, 777, "torus", seed=1, device=device)
    start = ens.state()
    ens.run(2000)
    expected = reference.advance(p, start, 2000)
    got = ens.state()
    assert np.count_nonzero(got["log_stretch"]) > 100
    for name in FIELDS:
        if device == "cpu" or name != "log_stretch":
            np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
        else:
            np.testing.assert_allclose(got[name], expected[name], rtol=1e-14, atol=0, err_msg=name)


@pytest.mark.parametrize("device", DEVICES)
def test_a_summary_on_every_device_is_summarize_of_its_state_on_the_hosts_threads(device, monkeypatch):
    """An ensemble's summary and its history variance are taken on the host's threads on every
    device (off a GPU, from one copy of the state): the numbers of ``summarize`` and of the
    history's own variance of that state, bit for bit, across more than one summary chunk too."""
    import warpratchet.ensemble
    import warpratchet.history
    import warpratchet.observables

    monkeypatch.setattr(warpratchet.observables, "TREE_LEAF", 1024)  # many leaves: on the threads
    monkeypatch.setattr(warpratchet.ensemble, "TREE_LEAF", 1024)
    monkeypatch.setattr(warpratchet.observables, "SUMMARY_CHUNK", 20_000)  # 3 chunks, the history's too
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 50_000, "torus", seed=2, threads=2, device=device)
    ens.run(400)
    calls = []
    real = warpratchet.ensemble.summarize_with_variance
    monkeypatch.setattr(
        warpratchet.ensemble, "summarize_with_variance", lambda *a, **k: calls.append(k) or real(*a, **k)
    )
    got = ens.summary(warn=False)
    state = ens.state()
    assert len(calls) == 1 and calls[0]["pool"] is not None  # on a pool of the host's threads
    assert got == summarize(state, ens.step)
    variance = ens.known_variance(ens.step)
    assert np.float64(variance).tobytes() == np.float64(warpratchet.history._variance(state)).tobytes()


@pytest.mark.parametrize("device", DEVICES)
def test_indicator_kernel_matches_the_plain_kernel_and_runs_on_every_device(device):
    """The indicators kernel leaves the orbit bitwise that of ``advance_map`` on each device."""
    p = MapParams(3.0, 0.1, 0.01)
    x, q = _start(p, n=500)
    plain = Ensemble(p, x, q, device=device).run(700, chunk_steps=300).state()
    ind = IndicatorEnsemble(p, x, q, device=device).run(700, chunk_steps=300)
    for name in FIELDS:
        np.testing.assert_array_equal(ind.state()[name], plain[name], err_msg=name)
    assert np.all(np.isfinite(ind.indicators()["megno"]))
