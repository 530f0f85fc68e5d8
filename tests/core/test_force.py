"""The force's piece table (warpratchet.force): refusals, the paper's family, and other forces
through the kernels, bit for bit against the NumPy twin."""

from fractions import Fraction

import numpy as np
import pytest

from warpratchet import kernels, reference
from warpratchet.ensemble import Ensemble
from warpratchet.errors import ParameterError
from warpratchet.force import Force
from warpratchet.orbits import enumerate_orbits
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
        pytest.param("0,0.3,0.6", "0,0.4,-0.4", "mean int_0^1 f dx = -0.02", id="mean-not-zero"),
        pytest.param("0,0.6,0.3", "0,0.4,-0.4", "knots[2] = 0.3", id="knots-not-increasing"),
        pytest.param("0.1,0.3,0.6", "0,0.4,-0.4", "knots[0] = 0.1", id="first-knot-not-0"),
        pytest.param("0,0.5,1", "0,0.4,-0.4", "knots[2] = 1", id="knot-at-1"),
        pytest.param("0,0.5", "0,0.4,-0.4", "values has 3 entries", id="lengths-differ"),
        pytest.param("0,x", "0,0", "knots[1] = 'x'", id="not-a-number"),
        pytest.param("0,0.25,0.5,0.75", "0,0.9,0,-0.9", "max |K f| = 2.7", id="kick-too-strong"),
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
    """Both step bodies (CPU C++ and portable Warp, generated from the table) and the one-point
    kernel against ``reference.advance``: 1003 points x 700 steps from global step 3, every state field."""
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

    for body in ("portable", "point"):  # "point": one point per thread, what a GPU runs
        arrays = [wp.array(start[n], dtype=wp.int64 if n == "winding" else wp.float64) for n in FIELDS]
        kernels.advance_map.launch("cpu", arrays, [], 3, 700, p, body=body)
        for name, array in zip(FIELDS, arrays, strict=True):
            np.testing.assert_array_equal(array.numpy(), expected[name], err_msg=f"{body} {name}")


def test_the_strip_sampler_draws_from_the_pieces_of_positive_slope():
    p = MapParams(3.0, table=FORCES[0])
    ens = Ensemble.sample(p, 5000, init="strip", seed=2)
    assert np.all(FORCES[0].in_strip(ens.state()["x"]))
    several = MapParams(3.0, table=FORCES[2])
    assert sum(FORCES[2].strip) > 1 and FORCES[2].strip_interval() is None
    with pytest.raises(ParameterError, match="has none or several"):
        Ensemble.sample(several, 100, init="strip")


def _independent_map(knots, values, K: float, m: int):
    """``z -> (M^m z, DM^m)`` on the lifted plane, with a force interpolated here (``np.interp``),
    not the table."""
    xs = np.array([float(Fraction(k)) for k in knots] + [1.0])
    fs = np.array([float(Fraction(v)) for v in values] + [float(Fraction(values[0]))])
    slopes = np.diff(fs) / np.diff(xs)

    def walk(z):
        x, p = z
        jac = np.eye(2)
        for _ in range(m):
            x = x % 1.0
            a = K * slopes[min(np.searchsorted(xs, x, side="right") - 1, len(slopes) - 1)]
            p = p + K * np.interp(x, xs, fs)
            x = x + p
            jac = np.array([[1.0 + a, 1.0], [a, 1.0]]) @ jac
        return np.array([x, p]), jac

    return walk


def _newton_cycles(knots, values, K: float, m: int, starts: int = 60) -> list[np.ndarray]:
    """Periodic points of period ``m`` by Newton's method on ``M^m(z) - z = 0`` (mod 1), from a
    ``starts x starts`` grid (:func:`_independent_map`)."""
    walk = _independent_map(knots, values, K, m)
    found = []
    grid = (np.arange(starts) + 0.5) / starts
    for x0 in grid:
        for p0 in grid:
            z = np.array([x0, p0])
            for _ in range(20):
                end, jac = walk(z)
                residual = (end - z + 0.5) % 1.0 - 0.5
                if np.max(np.abs(residual)) < 1e-13:
                    found.append(z % 1.0)
                    break
                try:
                    z = z - np.linalg.solve(jac - np.eye(2), residual)
                except np.linalg.LinAlgError:
                    break
    return found


@pytest.mark.parametrize("m", [1, 2, 3])
def test_exact_orbits_are_the_roots_an_independent_newton_search_finds(m):
    """Every root Newton's method finds from a 60 x 60 grid of starts lies on an exact orbit of a
    period dividing m (to 1e-9), and for m <= 2 every exact orbit point is such a root."""
    knots, values = ["0", "0.25", "0.75", "0.95"], ["-0.2", "0.3", "0", "-0.66"]
    p = MapParams(3.0, table=Force.from_knots(knots, values))
    # M^m = identity also on orbits of every period d dividing m
    orbits = [o for d in range(1, m + 1) if m % d == 0 for o in enumerate_orbits(p, d).orbits]
    assert orbits and all(o.kind != "parabolic" for o in orbits)  # isolated: Newton's method sees them
    exact = np.concatenate([np.stack([o.x, o.p], -1) for o in orbits])
    roots = np.array(_newton_cycles(knots, values, p.K, m))

    def torus_distance(a, b):
        d = np.abs(a[:, None, :] - b[None, :, :])
        return np.minimum(d, 1.0 - d).max(-1)

    to_exact = torus_distance(roots, exact).min(1)
    to_roots = torus_distance(exact, roots).min(1)
    assert np.all(to_exact < 1e-9), f"{np.count_nonzero(to_exact >= 1e-9)} roots off every exact orbit"
    if m <= 2:  # at m = 3 some cells are too thin for a 60 x 60 grid of starts: a third of the points
        assert np.all(to_roots < 1e-9), f"{np.count_nonzero(to_roots >= 1e-9)} exact points no root reached"


def test_the_sum_rule_balances_for_a_force_whose_islands_have_period_2_and_4():
    """Eq. (sum) for another force: ``A`` from the census's island areas against the direct mean
    over the chaotic component, within 4 (sigma_sumrule + sigma_direct) (a bound on the standard
    deviation of a difference of correlated estimates) plus the bias bound 2 S_unidentified / S_C
    (an unidentified point carries ``|nu| <= 2``)."""
    from warpratchet.sumrule import census

    p = MapParams(3.0, table=Force.from_knots(["0", "0.25", "0.75", "0.95"], ["-0.2", "0.3", "0", "-0.66"]))
    result = census(p, 4096, points=40_000, seed=1, m_max=8)
    assert result.theory is None and result.knots == "0,0.25,0.75,0.95"
    half = result.island(0.5)
    assert half is not None and half.area > 5 * half.area_stderr  # the period-2 chain carries the rule
    assert abs(result.A_direct) > 5 * result.A_direct_stderr
    bias = 2.0 * result.unidentified_area / result.S_C
    tolerance = 4.0 * (result.A_sumrule_stderr + result.A_direct_stderr) + bias
    assert abs(result.A_sumrule - result.A_direct) <= tolerance


def test_a_sweep_over_K_of_another_force_is_stored_resumed_and_verified(tmp_path):
    """sweep.k_path with a table: rows with NaN b1, b2 and domain "n/a"; a sweep file stores the
    force, resumes (the same rows, nothing recomputed), verifies, and refuses another force."""
    from warpratchet import sweep
    from warpratchet.sweep import verify_sweep

    table = Force.from_knots(["0", "0.25", "0.75", "0.95"], ["-0.2", "0.3", "0", "-0.66"])
    points = sweep.k_path([2.8, 3.0], table=table)
    spec = sweep.SweepSpec(points=1000, steps=2000, init="torus")
    out = tmp_path / "s.h5"
    rows = sweep.run_sweep(points, spec, out=out)
    assert [row["K"] for row in rows] == [2.8, 3.0]
    assert all(np.isnan(row["b1"]) and row["domain"] == "n/a" and np.isfinite(row["A"]) for row in rows)
    computed = []
    again = sweep.run_sweep(points, spec, out=out, on_row=computed.append)
    assert not computed and [row["A"] for row in again] == [row["A"] for row in rows]
    assert sweep.read_definition(out)[0] == points
    problems, _ = verify_sweep(out)
    assert problems == []
    other = sweep.k_path([2.8, 3.0], table=FORCES[0])
    with pytest.raises(ValueError, match="holds a different sweep"):
        sweep.run_sweep(other, spec, out=out)
    with pytest.raises(ParameterError, match="these points have 2 forces"):
        sweep.run_sweep([*points, MapParams(3.0, 0.1, 0.01)], spec, out=tmp_path / "t.h5")


def test_an_archive_stores_the_force_and_resumes_it_bit_for_bit(tmp_path, capsys):
    """run --out with --knots/--values, then resume to twice the steps: the archive's map is the
    force, and the resumed state is the uninterrupted run's, bit for bit."""
    import json

    from warpratchet.archive import open_archive
    from warpratchet.cli import main

    force = ["--knots", "0,0.25,0.75,0.95", "--values", "-0.2,0.3,0,-0.66"]
    out = str(tmp_path / "run.h5")
    common = ["--K", "3", *force, "--points", "500", "--seed", "4", "--init", "torus", "--quiet", "--json"]
    assert main(["run", *common, "--steps", "1000", "--out", out]) == 0
    capsys.readouterr()
    assert main(["resume", out, "--steps", "2000", "--knots", "0,0.25,0.75,0.95", "--quiet", "--json"]) == 0
    resumed = json.loads(capsys.readouterr().out)
    params = MapParams(3.0, table=Force.from_knots(force[1].split(","), force[3].split(",")))
    direct = Ensemble.sample(params, 500, "torus", 4).run(2000)
    with open_archive(out) as arc:
        assert arc.params == params and arc.checkpoint_step == 2000
        state = arc.checkpoint()[0]
    for name in FIELDS:
        np.testing.assert_array_equal(state[name], direct.state()[name], err_msg=name)
    assert resumed["knots"] == "0,0.25,0.75,0.95" and resumed["A"] == direct.summary(warn=False).A
    assert main(["resume", out, "--steps", "3000", "--knots", "0,0.5", "--quiet"]) == 2
    assert "disagrees with the archive's knots" in capsys.readouterr().err


@pytest.mark.parametrize("body", ["cpu", "portable"])
def test_transport_counts_of_another_force_equal_the_numpy_twins(body):
    """Return times to the force's strip and flights (``advance_map_transport``) against
    ``transport._twin``, 1003 points x 1500 steps from global step 5, count for count."""
    import warp as wp

    from warpratchet.kernels._transport import BINS, CARRY_FIELDS, advance_map_transport
    from warpratchet.transport import _twin as twin

    p = MapParams(3.0, table=Force.from_knots(["0", "0.25", "0.75", "0.95"], ["-0.2", "0.3", "0", "-0.66"]))
    x, q = _start(p.table)
    state = Ensemble(p, x, q, threads=1).state()
    carry = twin.initial_carry(p, state["x"], 5)
    expected_state, expected_carry, expected = twin.advance(p, state, carry, 1500, step0=5)
    assert expected[0].sum() > 1000 and expected[1].sum() > 1000 and expected[2].sum() > 1000
    arrays = [wp.array(state[k], dtype=wp.int64 if k == "winding" else wp.float64) for k in FIELDS]
    extra = [wp.array(carry[k], dtype=wp.int64) for k in CARRY_FIELDS]
    counts = wp.zeros(3 * BINS, dtype=wp.int64)
    advance_map_transport.launch("cpu", arrays, [*extra, counts], 5, 1500, p, body=body)
    np.testing.assert_array_equal(counts.numpy().reshape(3, BINS), expected)
    for name, array in zip(CARRY_FIELDS, extra, strict=True):
        np.testing.assert_array_equal(array.numpy(), expected_carry[name], err_msg=name)
    for name, array in zip(FIELDS, arrays, strict=True):
        np.testing.assert_array_equal(array.numpy(), expected_state[name], err_msg=name)


def test_the_portable_body_of_another_force_compiles_for_cuda(tmp_path):
    """The generated portable body (what CUDA runs) of the 6-piece force, through NVRTC."""
    import warp as wp

    archs = sorted(getattr(wp._src.context.runtime, "nvrtc_supported_archs", None) or [])
    if not archs:
        pytest.skip("Warp has no NVRTC on this machine (CUDA-enabled warp-lang needed)")
    module = kernels.advance_map.for_force(FORCES[2]).portable.module
    assert module is not kernels.advance_map.portable.module
    (artifact,) = wp.compile_aot_module(module, arch=86 if 86 in archs else archs[-1], module_dir=tmp_path)
    assert artifact.stat().st_size > 0


#: FORCES[2]: its pieces of positive slope are two intervals.
SEVERAL_STRIPS = ["--knots", "0,0.15,0.3,0.45,0.6,0.8", "--values", "0.05,0.3,-0.1,0.25,-0.2,-0.20625"]


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["run", "--K", "3", "--knots", "0,0.3,0.6", "--values", "0,0.4,-0.4"], "mean int_0^1 f dx = -0.02"),
        (
            ["orbits", "--K", "3", "--knots", "0,0.6,0.3", "--values", "0,0.4,-0.4", "--period", "1"],
            "knots[2]",
        ),
        (["sumrule", "--K", "3", "--knots", "0,0.5", "--values", "0.7,-0.7"], "max |K f| = 2.1"),
        (
            ["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--knots", "0,0.5", "--values", "0,0"],
            "two forces",
        ),
        (["theory", "--K", "3", "--knots", "0,0.5"], "values is missing"),
        (["run", "--K", "3", *SEVERAL_STRIPS, "--init", "strip"], "has none or several"),
    ],
)
def test_the_cli_refuses_a_bad_force_in_one_line_with_status_2(capsys, argv, needle):
    from support import refused

    assert needle in refused(capsys, argv)


@pytest.mark.parametrize(
    ("given", "text"),
    [("0.3", "0.3"), (0.3, "0.3"), ("1/3", "1/3"), (Fraction(-7, 40), "-0.175"), ("1e-3", "0.001"), (2, "2")],
)
def test_numbers_are_exact_and_their_text_reads_back_the_same(given, text):
    from warpratchet.force import numbers_text, parse_numbers

    (value,) = parse_numbers("knots", [given])
    assert numbers_text([value]) == text and parse_numbers("knots", text) == (value,)


def test_a_flat_piece_makes_families_of_parabolic_orbits_that_the_map_returns_exactly():
    """The 4-piece force with a piece of slope 0 has, at K = 3 and period 3, families (polygons of
    periodic points); the independent map returns every polygon's centroid to itself (mod 1)."""
    knots, values = ["0", "0.2", "0.5", "0.7"], ["0", "0.2", "-0.1", "-0.1"]
    p = MapParams(3.0, table=Force.from_knots(knots, values))
    families = [f for f in enumerate_orbits(p, 3).families if f.shape == "polygon"]
    assert families and all(f.area > 0 for f in families)
    walk = _independent_map(knots, values, p.K, 3)
    for family in families:
        z = family.vertices.mean(0)
        end, jac = walk(z)
        assert np.max(np.abs((end - z + 0.5) % 1.0 - 0.5)) < 1e-12
        assert np.allclose(jac, np.eye(2)) or np.isclose(np.trace(jac), 2.0)  # parabolic: tr DM^3 = 2


def test_run_says_why_another_force_has_no_closed_form(capsys):
    """At K = 3 the report must not blame K for the missing theory: the force is the reason."""
    from warpratchet.cli import main

    argv = ["run", "--K", "3", "--knots", "0,0.25,0.75,0.95", "--values", " -0.2,0.3,0,-0.66"]
    assert main([*argv, "--points", "64", "--steps", "64", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "theory      : none for this force" in out and "K != 3" not in out


_C_KICKS = """
#include "force.h"
#define LANES {lanes}
void kicks(int64_t n, const double *x, double K, const double *coefficients, double *kick, double *k_slope)
{{
    const force_t m = force_set(K{arguments});
    for (int64_t i = 0; i < n; i += LANES) {{
        {load}
        force_kick(xv, &m, &kv, &sv);
        {store}
    }}
}}
"""
_C_LANES = {
    "c": (1, "double xv = x[i], kv, sv;", "kick[i] = kv; k_slope[i] = sv;", ()),
    "avx2": (
        4,
        "__m256d xv = _mm256_loadu_pd(x + i), kv, sv;",
        "_mm256_storeu_pd(kick + i, kv); _mm256_storeu_pd(k_slope + i, sv);",
        ("-mavx2",),
    ),
    "avx512": (
        8,
        "__m512d xv = _mm512_loadu_pd(x + i), kv, sv;",
        "_mm512_storeu_pd(kick + i, kv); _mm512_storeu_pd(k_slope + i, sv);",
        ("-mavx512f",),
    ),
}


def _cpu_has(flag: str) -> bool:
    with open("/proc/cpuinfo") as cpuinfo:
        return any(line.startswith("flags") and f" {flag}" in line for line in cpuinfo)


@pytest.mark.parametrize("isa", sorted(_C_LANES))
@pytest.mark.parametrize(
    "table", [Force.paper(0.1, 0.01), *FORCES], ids=lambda t: f"{t.family}{t.n_pieces}pieces"
)
def test_the_c_of_a_force_gives_the_numpy_twins_kicks_bit_for_bit(tmp_path, table, isa):
    """The benchmarks' C (:func:`warpratchet.force.c_source`), compiled with gcc as they are
    (``-ffp-contract=off``), against ``K f`` and ``K f'`` of the NumPy body on every knot and
    4000 random points; where the CPU lacks the instruction set it is compiled only."""
    import ctypes
    import shutil
    import subprocess

    from warpratchet.force import c_source

    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is not on PATH")
    lanes, load, store, flags = _C_LANES[isa]
    fields = table.fields()
    arguments = "".join(f", coefficients[{i}]" for i in range(len(fields)))
    (tmp_path / "force.h").write_text(c_source(table, isa))
    (tmp_path / "kicks.c").write_text(
        _C_KICKS.format(lanes=lanes, arguments=arguments, load=load, store=store)
    )
    library = tmp_path / "kicks.so"
    command = [gcc, "-O2", "-ffp-contract=off", *flags, "-fPIC", "-shared", f"-I{tmp_path}"]
    done = subprocess.run(
        [*command, "-o", str(library), str(tmp_path / "kicks.c")], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr
    if isa != "c" and not _cpu_has(flags[0][2:]):
        return
    rng = np.random.default_rng(7)
    x = np.concatenate(
        [[float(k) for k in table.knots], [np.nextafter(float(k), 0) for k in table.knots[1:]]]
    )
    x = np.concatenate([x, rng.random(4000 - x.size)])
    K = 2.75
    kick, k_slope = np.empty_like(x), np.empty_like(x)
    f64 = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    function = ctypes.CDLL(str(library)).kicks
    function.argtypes = [ctypes.c_int64, f64, ctypes.c_double, f64, f64, f64]
    function(x.size, x, K, np.array([*fields.values(), 0.0]), kick, k_slope)
    f, slope = table.evaluate(x)
    np.testing.assert_array_equal(kick.view(np.int64), (K * f).view(np.int64))
    np.testing.assert_array_equal(k_slope.view(np.int64), (K * slope).view(np.int64))
