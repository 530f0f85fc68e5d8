"""The Warp kernel against its NumPy twin, bit for bit, and the tangent bookkeeping."""

import numpy as np
import pytest

from warpratchet import reference, theory
from warpratchet.ensemble import Ensemble
from warpratchet.observables import lyapunov
from warpratchet.params import MapParams

CASES = [
    MapParams(3.0, 0.1, 0.01),  # domain LR, Fig. 7 range
    MapParams(3.0, 0.3, 0.03),  # domain R, Fig. 12
    MapParams(3.618033988749895, 0.05, 0.02),  # Fig. 1(b)
    MapParams(2.99, 0.25, 0.07),  # Fig. 9's path
    MapParams(3.0, 1e-9, 1e-9),  # elliptic-sawtooth limit, Fig. 2 (slopes ~5e8)
    MapParams(0.5, 0.4, 0.3),  # weak kicks, no islands of acceleration
]


def _ensemble(p: MapParams, n: int = 1000, seed: int = 3, threads: int = 2) -> Ensemble:
    rng = np.random.default_rng(seed)
    # Include exact kink positions and p values that push t = q + K f across integers.
    x = rng.random(n)
    x[:4] = [0.0, p.b1, 1.0 - p.b2, 0.5]
    q = rng.random(n) - 3.0  # negative momenta exercise the winding bookkeeping
    return Ensemble(p, x, q, threads=threads)


@pytest.mark.parametrize("p", CASES, ids=lambda p: f"K{p.K:.4g}-b{p.b1:g}-{p.b2:g}")
def test_kernel_equals_numpy_reference_bit_for_bit(p):
    """1000 points x 500 steps, started at global step 3 so renormalisation checks are off-phase."""
    ens = _ensemble(p)
    ens.step = 3  # a run resumed from step 3: the checks fall on global steps 8, 16, ...
    start = ens.state()
    ens.run(500, chunk_steps=97)
    expected = reference.advance(p, start, 500, step0=3)
    got = ens.state()
    for name in ("x", "q", "winding", "dx", "dp", "log_stretch"):
        np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
    assert np.all((got["x"] >= 0) & (got["x"] < 1)) and np.all((got["q"] >= 0) & (got["q"] < 1))


def test_renormalisation_was_exercised_and_matches_every_step_normalisation():
    """Threshold renormalisation (every 8 steps, |dx| > 1e100) against the textbook per-step one."""
    p = MapParams(3.0, 0.05, 0.02)
    ens = _ensemble(p, n=400)
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


def test_tangent_map_has_unit_determinant_in_the_kernel():
    """det DM = 1: propagate (1, 0) and (0, 1) one step with the kernel, form the 2x2 matrix."""
    p = MapParams(3.0, 0.1, 0.05)
    x = np.linspace(0, 1, 2001, endpoint=False)
    columns = []
    for tangent in ((1.0, 0.0), (0.0, 1.0)):
        ens = Ensemble(p, x, np.full_like(x, 0.3))
        st = ens.state()
        st["dx"][:], st["dp"][:] = tangent
        ens = Ensemble.from_state(p, st, 0)
        ens.run(1)
        columns.append((ens.array("dx").copy(), ens.array("dp").copy()))
    (a, c), (b, d) = columns
    det = a * d - b * c
    np.testing.assert_allclose(det, 1.0, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(np.stack([[a, b], [c, d]]).transpose(2, 0, 1), p.jacobian(x))


def test_results_do_not_depend_on_thread_count_or_chunking():
    """Bitwise identical for 1, 2 and 3 threads, any chunk length, and a run split in pieces."""
    p = MapParams(3.0, 0.1, 0.01)

    def final(threads, pieces, chunk):
        ens = Ensemble.sample(p, 1001, "torus", seed=5, threads=threads)
        for steps in pieces:
            ens.run(steps, chunk_steps=chunk)
        return ens.state()

    reference_state = final(1, [3000], 10_000)
    for threads, pieces, chunk in ((2, [3000], 64), (3, [200, 2800], 1), (2, [1, 999, 2000], 333)):
        other = final(threads, pieces, chunk)
        for name, values in reference_state.items():
            np.testing.assert_array_equal(values, other[name], err_msg=f"{name} threads={threads}")


def test_momentum_keeps_full_precision_far_from_the_origin():
    """An accelerator-mode point gains one unit per step; after 10^5 steps p ~ 1e5 and x is still exact."""
    p = MapParams(3.0, 0.1, 0.01)
    (x0,) = [x for w, x in theory.accelerator_modes(p) if w == 1]
    # Off the fixed point (p0 = 0.02): an orbit inside the L island, rotating around it.
    ens = Ensemble(p, np.array([x0]), np.array([0.02]), threads=1)
    ens.run(100_000)
    assert ens.momentum()[0] == pytest.approx(0.02 + 100_000, abs=0.2)
    assert 0.0 <= ens.array("x")[0] < 1.0


def test_state_is_56_bytes_per_point():
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 10, "torus")
    assert sum(ens.array(name).itemsize for name in ens.state()) == 56


def _devices():
    import warp as wp

    from warpratchet.kernels import init_warp

    init_warp()
    return [str(d) for d in wp.get_devices()]


@pytest.mark.parametrize("device", _devices())
def test_every_warp_device_gives_the_reference_result(device):
    """The same kernel on every device Warp sees (``cpu`` here; ``cuda:N`` where a GPU exists).

    The CPU build does not contract ``a*b + c`` into FMAs, so it is bitwise equal to NumPy. nvcc
    contracts by default; a last-bit difference then grows like the Lyapunov exponent, so on a
    GPU the comparison is over 5 steps, to 1e-12.
    """
    p = MapParams(3.0, 0.1, 0.01)
    steps = 100 if device == "cpu" else 5
    ens = Ensemble.sample(p, 777, "torus", seed=1, device=device)
    start = ens.state()
    ens.run(steps)
    expected = reference.advance(p, start, steps)
    got = ens.state()
    for name in ("x", "q", "winding", "dx", "dp", "log_stretch"):
        if device == "cpu":
            np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
        else:
            np.testing.assert_allclose(got[name], expected[name], rtol=1e-12, atol=1e-12, err_msg=name)
