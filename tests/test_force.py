"""The force's piece table (warpratchet.force): refusals, the paper's family, and other forces
through the kernels, bit for bit against the NumPy twin."""

from fractions import Fraction

import numpy as np
import pytest

from warpratchet import kernels, reference
from warpratchet.ensemble import Ensemble
from warpratchet.errors import ParameterError
from warpratchet.force import Force
from warpratchet.params import MapParams
from warpratchet.spec import RunSpec

kernels.init_warp()
FIELDS = ("x", "q", "winding", "dx", "dp", "log_stretch")


def zero_mean(knots, values):
    """``values`` with one more value, the last, that makes the mean exactly zero.

    The mean of a periodic piecewise-linear ``f`` is ``sum_i v_i (x_{i+1} - x_{i-1}) / 2``
    (trapezoids, ``x_{-1} = x_{n-1} - 1``, ``x_n = 1``), linear in the values.
    """
    xs = [Fraction(str(x)) for x in knots]
    n = len(xs)
    weights = [
        ((xs[i + 1] if i + 1 < n else Fraction(1)) - (xs[i - 1] if i > 0 else xs[-1] - 1)) / 2
        for i in range(n)
    ]
    vs = [Fraction(str(v)) for v in values]
    last = -sum(w * v for w, v in zip(weights, vs, strict=False)) / weights[-1]
    return [str(x) for x in xs], [str(v) for v in [*vs, last]]


#: Forces of 3 to 6 pieces; the second has slopes 1, -1 and 0 (the kernel form's short cuts).
FORCES = [
    Force.from_knots(*zero_mean([0, 0.25, 0.5], [0, 0.3])),
    Force.from_knots([0, 0.2, 0.5, 0.7], [0, 0.2, -0.1, -0.1]),
    Force.from_knots(*zero_mean([0, 0.15, 0.3, 0.45, 0.6, 0.8], [0.05, 0.3, -0.1, 0.25, -0.2])),
]


def paper_kicks(p: MapParams):
    """``(K a_s, K d_s)`` of Eq. (fx) with Eq. (mmc), derived here from the paper, exactly."""
    K, b1, b2 = Fraction(p.K), Fraction(p.b1), Fraction(p.b2)
    b = b1 + b2
    c = (1 - b2) / (2 - b)
    l1 = (1 - b1) * (1 - b) / (b1 * (2 - b))
    l2 = (1 - b2) * (1 - b) / (b2 * (2 - b))
    return ((K * l1, Fraction(0)), (-K, K * c), (K * l2, -K * l2))


def test_the_slopes_short_cuts_are_exercised():
    slopes = {float(a) for a, _ in FORCES[1].exact_pieces()}
    assert {1.0, -1.0, 0.0} <= slopes


@pytest.mark.parametrize(
    ("knots", "values", "message"),
    [
        ("0,0.3,0.6", "0,0.4,-0.4", "mean int_0^1 f dx = -0.02"),
        ("0,0.6,0.3", "0,0.4,-0.4", "knots[2] = 0.3"),
        ("0.1,0.3,0.6", "0,0.4,-0.4", "knots[0] = 0.1"),
        ("0,0.5,1", "0,0.4,-0.4", "knots[2] = 1"),
        ("0,0.5", "0,0.4,-0.4", "values has 3 entries"),
        ("0,x", "0,0", "knots[1] = 'x'"),
        ("0,0.25,0.5,0.75", "0,0.9,0,-0.9", "max |K f| = 2.7"),
    ],
)
def test_a_force_is_refused_in_one_line_naming_the_value(knots, values, message):
    with pytest.raises(ParameterError) as info:
        RunSpec(K=3, knots=knots, values=values)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_the_tangent_bound_refuses_a_force_too_steep_for_the_renormalisation():
    knots, values = zero_mean(["0", "1e-30", "0.5"], ["0", "0.1"])
    steep = Force.from_knots(knots, values)
    assert steep.max_slope == Fraction(10**29)
    with pytest.raises(ParameterError, match=r"max \|f'\| = 1e\+29 is outside the range"):
        RunSpec(K=3, knots=",".join(knots), values=",".join(values))


@pytest.mark.parametrize(("b1", "b2"), [(0.1, 0.01), (0.3, 0.03), (1e-9, 1e-9), (0.25, 0.07)])
def test_the_paper_table_is_eq_fx_exactly_and_its_float_form_the_closed_forms(b1, b2):
    p = MapParams(3.0, b1, b2)
    table = p.table
    # exact kicks against Eq. (mmc) derived independently
    assert table.exact_kicks(p.K) == paper_kicks(p)
    assert [piece.slope.value for piece in table.pieces] == [p.l1, -1.0, p.l2]
    assert table.pieces[1].anchor.value == p.c and table.pieces[0].end.value == b1
    assert table.pieces[1].end.value == 1.0 - b2
    # continuity and the ratchet condition, exactly
    f = [a * x + d for (a, d), x in zip(table.exact_pieces(), table.knots, strict=True)]
    assert f == list(table.values) and table.max_value < Fraction(1, 2)


@pytest.mark.parametrize("table", FORCES, ids=lambda t: f"{t.n_pieces}pieces")
def test_the_numpy_body_agrees_with_the_exact_table(table):
    x = np.random.default_rng(1).random(2000)
    f, slope = table.evaluate(x)
    exact = [table.exact_pieces()[table.piece_of(Fraction(v))] for v in x]
    np.testing.assert_allclose(
        f, [float(a * Fraction(v) + d) for (a, d), v in zip(exact, x, strict=True)], atol=1e-15
    )
    np.testing.assert_array_equal(slope, [float(a) for a, _ in exact])


def _start(table: Force, n: int = 1003) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    x = rng.random(n)
    x[: table.n_pieces] = [float(k) for k in table.knots]  # every knot, where the pieces meet
    return x, rng.random(n) - 2.0


@pytest.mark.parametrize("table", FORCES, ids=lambda t: f"{t.n_pieces}pieces")
def test_kernels_of_another_force_equal_the_numpy_twin_bit_for_bit(table):
    """Both step bodies (CPU C++ and portable Warp, generated from the table) against
    ``reference.advance``: 1003 points x 700 steps from global step 3, every state field."""
    p = MapParams(3.0, table=table)
    x, q = _start(table)
    ens = Ensemble(p, x, q, threads=2)
    ens.step = 3
    start = ens.state()
    ens.run(700, chunk_steps=301)
    expected = reference.advance(p, start, 700, step0=3)
    got = ens.state()
    for name in FIELDS:
        np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
    assert np.count_nonzero(got["log_stretch"]) > 10 and np.count_nonzero(got["winding"]) > 100
    import warp as wp

    arrays = [wp.array(start[n], dtype=wp.int64 if n == "winding" else wp.float64) for n in FIELDS]
    kernels.advance_map.launch("cpu", arrays, [], 3, 700, p, body="portable")
    for name, array in zip(FIELDS, arrays, strict=True):
        np.testing.assert_array_equal(array.numpy(), expected[name], err_msg=f"portable {name}")


def test_the_strip_sampler_draws_from_the_pieces_of_positive_slope():
    p = MapParams(3.0, table=FORCES[0])
    ens = Ensemble.sample(p, 5000, init="strip", seed=2)
    assert np.all(FORCES[0].in_strip(ens.state()["x"]))
    several = MapParams(3.0, table=FORCES[2])
    assert sum(FORCES[2].strip) > 1 and FORCES[2].strip_interval() is None
    with pytest.raises(ParameterError, match="has none or several"):
        Ensemble.sample(several, 100, init="strip")
