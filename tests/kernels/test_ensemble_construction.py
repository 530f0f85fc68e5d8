"""Building an ensemble in place (issue 12, item 7): the same points, no full-size temporaries."""

import numpy as np
import pytest

from warpratchet.ensemble import (
    _BUILD_CHUNK,
    STATE_FIELDS,
    Ensemble,
    sample_grid,
    sample_strip,
    sample_torus,
)
from warpratchet.params import MapParams

P = MapParams(3.0, 0.1, 0.01)
#: More points than one build chunk, and not a multiple of it.
N = _BUILD_CHUNK + 12_345


def _expected(init: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The samplers' own full-size arrays, as Ensemble.sample used them before it built in chunks."""
    rng = np.random.default_rng(seed)
    return {"strip": lambda: sample_strip(P, n, rng), "torus": lambda: sample_torus(n, rng)}.get(
        init, lambda: sample_grid(n)
    )()


@pytest.mark.parametrize("init", ["strip", "torus", "grid"])
def test_sample_builds_the_samplers_points_bit_for_bit(init):
    x, p = _expected(init, N, seed=7)
    built = Ensemble.sample(P, N, init, seed=7, threads=1).state()
    reference = Ensemble(P, x, p, threads=1).state()  # the element-wise path of user arrays
    assert built["x"].size == x.size
    for name in STATE_FIELDS:
        np.testing.assert_array_equal(built[name], reference[name], err_msg=name)
    np.testing.assert_array_equal(built["p0"], p)
    np.testing.assert_array_equal(built["dx"], np.ones_like(x))


def test_user_arrays_give_the_initial_state_of_the_docstring():
    x0 = np.array([-1e-300, 0.25, 1.5, -0.75])
    p0 = np.array([2.5, -0.25, 0.0, -3.0])
    s = Ensemble(P, x0, p0, threads=1).state()
    np.testing.assert_array_equal(s["x"], [0.0, 0.25, 0.5, 0.25])  # mod 1; -1e-300 mod 1 rounds to 1 -> 0
    np.testing.assert_array_equal(s["q"], [0.5, 0.75, 0.0, 0.0])
    np.testing.assert_array_equal(s["p0"], p0)
    np.testing.assert_array_equal(s["winding"], 0)
    np.testing.assert_array_equal(s["dx"], 1.0)
    np.testing.assert_array_equal(s["dp"], 0.0)
    np.testing.assert_array_equal(s["log_stretch"], 0.0)


def test_from_state_copies_the_state():
    ens = Ensemble.sample(P, 1000, "torus", seed=1, threads=1).run(50)
    state = ens.state()
    again = Ensemble.from_state(P, state, ens.step, threads=1)
    state["x"][:] = 0.5  # the caller's dict is not the ensemble's state
    for name, values in ens.state().items():
        np.testing.assert_array_equal(again.array(name), values, err_msg=name)


def test_the_initial_conditions_are_named_init_and_sampler_still_works():
    # One name, init, as in RunSpec, --init and the archive's settings; sampler= keeps working.
    sampled = Ensemble.sample(P, 64, "torus", seed=3, threads=1)
    assert (sampled.init, sampled.seed) == ("torus", 3)
    assert Ensemble(P, np.zeros(4), np.zeros(4), threads=1).init == "user"
    with pytest.warns(DeprecationWarning, match=r"Ensemble\(sampler=\.\.\.\) is spelled init="):
        old = Ensemble(P, np.zeros(4), np.zeros(4), threads=1, sampler="strip", seed=1)
    assert old.init == "strip"
    with pytest.warns(DeprecationWarning, match=r"from_state\(sampler=\.\.\.\) is spelled init="):
        again = Ensemble.from_state(P, sampled.state(), sampled.step, threads=1, sampler="torus")
    assert again.init == "torus"
    with pytest.warns(DeprecationWarning, match="Ensemble.sampler is spelled Ensemble.init"):
        assert sampled.sampler == "torus"
    with pytest.raises(TypeError, match="give init= only"):
        Ensemble(P, np.zeros(4), np.zeros(4), sampler="strip", init="strip")
