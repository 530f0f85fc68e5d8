"""Periodic orbits (warpratchet.orbits): closed forms, an independent brute force, the kernel
arithmetic, the Jacobians, the island census and the exact areas at K = 3.

The brute force and the exact map below are written here from Eqs. (cpem) and (fx) alone,
without the module's search, cells or integer arithmetic.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warpratchet import MapParams, reference, theory
from warpratchet.force import Force
from warpratchet.orbits import (
    KINDS,
    all_words,
    compose,
    enumerate_orbits,
    fixed_points,
    format_orbits,
    orbit_families,
    orbits_report,
    periodic_orbits,
    symbol_table,
    word_kicks,
)
from warpratchet.sumrule import census

U = 2.0**-53
K3 = MapParams(3.0, 0.1, 0.01)  # domain LR; the right strip is steep (1 + K l2 ~ 141)
K299 = MapParams(2.99, 0.25, 0.05)  # Fig. 9's path: islands with nu = +-1/3, +-2/3
OTHER = MapParams(1.7, 0.2, 0.3)  # weak kicks


# -- an independent exact map: Fractions straight from Eqs. (cpem), (fx) -------------------------------
class FractionMap:
    """The paper's torus map in Fractions: Eq. (fx) with Eq. (mmc) solved exactly at the float64
    ``K, b1, b2`` (continuous and of zero mean); ``k = floor(t)``, ``j = [x + q' >= 1]`` (Eq. cpem)."""

    def __init__(self, p: MapParams):
        K, b1, b2 = Fraction(p.K), Fraction(p.b1), Fraction(p.b2)
        # Eq. (mmc) from continuity at b1 and 1 - b2 and zero mean, re-derived here:
        # l1 b1 = c - b1, c - (1 - b2) = -l2 b2, int f = 0 -> c = (1 - b2) / (2 - b1 - b2).
        c = (1 - b2) / (2 - b1 - b2)
        l1, l2 = (c - b1) / b1, (1 - b2 - c) / b2
        self.K, self.b1, self.right, self.c = K, b1, 1 - b2, c
        self.kicks = [(K * l1, Fraction(0)), (-K, K * c), (K * l2, -K * l2)]

    def piece(self, x):
        return 0 if x <= self.b1 else (1 if x < self.right else 2)

    def kick(self, x):
        """``K f(x)``."""
        ka, kd = self.kicks[self.piece(x)]
        return ka * x + kd

    def step(self, x, q):
        """``(x', q', piece, k, j)``."""
        t = q + self.kick(x)
        k = math.floor(t)
        q1 = t - k
        j = 1 if x + q1 >= 1 else 0
        return x + q1 - j, q1, self.piece(x), k, j


def brute_force(p: MapParams, m: int) -> set[frozenset]:
    """Every orbit of exact period ``m``, from all ``30^m`` words (not only least rotations).

    Float64 prefilter: the fixed point of each rotation of each word must lie in the cell of
    the rotation's first symbol, up to a computed bound on the float solve's error,
    ``64 u ||(A - I)^-1|| (||A|| + ||b|| + 1)``. Then an exact solve and exact iteration
    (:class:`FractionMap`) decide.
    Degenerate words (``det(A - I) = 0``, families) are left out. Returns the cycles as
    frozensets of exact points.
    """
    words = all_words(p, m)
    n = len(words)
    kicks = np.array([[float(v) for v in kick] for kick in FractionMap(p).kicks])  # (3, 2)
    symbols = symbol_table(len(kicks))
    right = 1.0 - p.b2
    keep = np.ones(n, dtype=bool)
    # The words are closed under rotation: each rotation's map is that of another row.
    code = len(symbols) ** np.arange(m)
    row_of = np.empty(n, dtype=np.int64)
    row_of[words @ code] = np.arange(n)
    all_A, all_b = compose(words, kicks)
    for r in range(m):  # rotation r starts with symbol r
        row = row_of[np.roll(words, -r, axis=1) @ code]
        A, b = all_A[row], all_b[row]
        x, q, det = fixed_points(A, b)
        with np.errstate(divide="ignore"):
            inverse_norm = (np.abs(A - np.eye(2)).sum(-1).max(-1) + 1.0) / np.abs(det)
        # z = -(A - I)^-1 b with A, b good to ~m u |A|, u |b| (z in the unit square):
        tol = 64 * U * inverse_norm * (np.abs(A).sum(-1).max(-1) + np.abs(b).max(-1) + 1)
        s, k, j = symbols[words[:, r]].T
        ka, kd = kicks[s, 0], kicks[s, 1]
        with np.errstate(invalid="ignore"):  # nan where det = 0, dropped below
            t = q + ka * x + kd
        in_piece = np.where(
            s == 0,
            x <= p.b1 + tol,
            np.where(s == 1, (x >= p.b1 - tol) & (x <= right + tol), x >= right - tol),
        )
        xs = x + t - k
        keep &= (np.abs(det) > 0) & (x >= -tol) & (x <= 1 + tol) & (q >= -tol) & (q <= 1 + tol) & in_piece
        keep &= (t >= k - tol) & (t <= k + 1 + tol) & np.where(j == 0, xs <= 1 + tol, xs >= 1 - tol)
    fm = FractionMap(p)
    found = set()
    for word in words[keep]:
        steps = [symbols[w] for w in word]
        A = [[Fraction(1), Fraction(0)], [Fraction(0), Fraction(1)]]
        b = [Fraction(0), Fraction(0)]
        for s, k, j in steps:
            ka, kd = fm.kicks[s]
            A = [
                [(1 + ka) * A[0][0] + A[1][0], (1 + ka) * A[0][1] + A[1][1]],
                [ka * A[0][0] + A[1][0], ka * A[0][1] + A[1][1]],
            ]
            b = [(1 + ka) * b[0] + b[1] + kd - int(k) - int(j), ka * b[0] + b[1] + kd - int(k)]
        det = (A[0][0] - 1) * (A[1][1] - 1) - A[0][1] * A[1][0]
        if det == 0:
            continue
        x = -((A[1][1] - 1) * b[0] - A[0][1] * b[1]) / det
        q = -(-A[1][0] * b[0] + (A[0][0] - 1) * b[1]) / det
        if not (0 <= x < 1 and 0 <= q < 1):
            continue
        points, z = [], (x, q)
        for s, k, j in steps:
            points.append(z)
            x1, q1, *symbol = fm.step(*z)
            if tuple(symbol) != (s, k, j):
                break
            z = (x1, q1)
        else:
            if z == (x, q) and len(set(points)) == m:  # returns, with least period m
                found.add(frozenset(points))
    return found


def _cycles(orbits) -> set[frozenset]:
    return {frozenset(o.exact) for o in orbits if o.residue != 0.0}


# -- closed forms --------------------------------------------------------------------------------------
def _period_one_closed_form(p: MapParams) -> dict:
    """Period-1 points: q = 0 and K f(x) = k (x' = x + q' - j = x forces q' = j = 0), Eq. (xp).

    With K f = ka x + kd on each piece (:class:`FractionMap`): middle x = c - k/K (Eq. xp),
    R = K/4 (DM = [[1 - K, 1], [-K, 1]], Eq. eig); left x = k/(K l1), right x = 1 + k/(K l2),
    R = -K l/4. Returns {x (exact): (k, R exact)}.
    """
    fm = FractionMap(p)
    out = {}
    for k in range(-2, 3):
        for piece, (ka, kd) in enumerate(fm.kicks):
            x = (k - kd) / ka
            if 0 <= x < 1 and fm.piece(x) == piece:
                out[x] = (k, (2 - (2 + ka)) / 4)
    return out


def test_acceptance_period_one_at_K3():
    """``warpratchet orbits --K 3 --b1 0.1 --b2 0.01 --period 1``: the elliptic orbits have R = 0.75."""
    report = orbits_report(K3, 1)
    json.dumps(report)  # serialisable as it stands
    elliptic = [o for o in report["orbits"] if o["kind"] == "elliptic"]
    assert sorted(o["winding"] for o in elliptic) == [-1, 0, 1]
    for o in elliptic:
        assert o["residue"] == 0.75
        assert o["x"] == [float(FractionMap(K3).c - Fraction(o["winding"], 3))] and o["p"] == [
            0.0
        ]  # Eq. (xp)
        assert o["nu"] == o["winding"] and o["itinerary"] == [["middle", o["winding"], 0]]
    assert report["counts"] == {"elliptic": 3, "hyperbolic": 3, "parabolic": 0, "families": 0}
    assert {"orbits", "families", "period", "K", "b1", "b2"} <= set(report)
    assert "3 elliptic, 3 hyperbolic" in format_orbits(report)


@settings(max_examples=60, deadline=None)
@given(
    K=st.floats(0.05, 3.95),
    b1=st.floats(1e-4, 0.6),
    b2=st.floats(1e-4, 0.6),
)
def test_period_one_orbits_are_the_closed_form(K, b1, b2):
    if b1 + b2 >= 0.95:
        return
    p = MapParams(K, b1, b2)
    expected = _period_one_closed_form(p)
    orbits = periodic_orbits(p, 1)
    assert {o.exact[0][0]: (o.winding, Fraction(o.residue)) for o in orbits}.keys() == expected.keys()
    for o in orbits:
        k, residue = expected[o.exact[0][0]]
        assert o.exact[0][1] == 0 and o.p[0] == 0.0 and o.winding == k
        assert o.residue == float(residue)
        assert o.kind == ("elliptic" if 0 < residue < 1 else "hyperbolic")


def test_parabolic_orbits_at_K2():
    """tr(S_a S_b) = 2 + 2a + 2b + ab for S_c = [[1 + c, 1], [c, 1]]: with the middle slope b = -K = -2
    it is -2 whatever a, so every period-2 orbit with one middle step has R = 1 exactly (parabolic),
    and the middle fixed point R = K/4 = 1/2."""
    p = MapParams(2.0, 0.1, 0.02)
    assert [(o.kind, o.residue) for o in periodic_orbits(p, 1) if o.itinerary[0] // 10 == 1] == [
        ("elliptic", 0.5)
    ]
    mixed = [o for o in periodic_orbits(p, 2) if sorted(s // 10 for s in o.itinerary) in ([0, 1], [1, 2])]
    assert mixed
    for o in mixed:
        assert o.residue == 1.0 and o.kind == "parabolic"


@settings(max_examples=25, deadline=None)
@given(K=st.floats(0.05, 3.95), b1=st.floats(1e-3, 0.6), b2=st.floats(1e-3, 0.6))
def test_brute_force_agrees_at_random_parameters(K, b1, b2):
    if b1 + b2 >= 0.95:
        return
    p = MapParams(K, b1, b2)
    for m in (1, 2):
        assert _cycles(periodic_orbits(p, m)) == brute_force(p, m), f"period {m}"


# -- every orbit, once -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("p", "periods"), [(K3, 4), (K299, 4), (OTHER, 3)], ids=["K3", "K2.99", "K1.7"])
def test_brute_force_over_all_words_finds_the_same_orbits(p, periods):
    """Every isolated orbit of period <= 4 that any of the 30^m words yields, and no other."""
    for m in range(1, periods + 1):
        assert _cycles(periodic_orbits(p, m)) == brute_force(p, m), f"period {m}"


def test_the_brute_force_takes_its_alphabet_from_the_forces_table():
    """Another force (4 pieces): 40 symbols, and each isolated orbit the search finds is the
    float64 fixed point of its own itinerary among all 40^m words."""
    p = MapParams(3.0, table=Force.from_knots([0, 0.25, 0.75, 0.95], [-0.2, 0.3, 0, -0.66]))
    assert symbol_table(4).shape == (40, 3) and len(word_kicks(p)) == 4
    for m in (1, 2):
        words = all_words(p, m)
        assert words.shape == (40**m, m)
        x, q, _ = fixed_points(*compose(words, word_kicks(p)))
        orbits = [o for o in periodic_orbits(p, m) if o.residue != 0.0]
        assert orbits, f"period {m}"
        for o in orbits:
            (row,) = np.flatnonzero((words == o.itinerary).all(axis=1))
            assert (x[row], q[row]) == pytest.approx((o.x[0], o.p[0] % 1.0), abs=1e-9)


@pytest.mark.parametrize("p", [K3, K299], ids=["K3", "K2.99"])
def test_each_cycle_once_with_its_least_period_and_least_rotation(p):
    seen: dict = {}
    for m in range(1, 6):
        for o in periodic_orbits(p, m):
            assert len(set(o.exact)) == m  # least period m
            rotations = [o.itinerary[i:] + o.itinerary[:i] for i in range(m)]
            assert o.itinerary == min(rotations)
            for point in o.exact:
                assert point not in seen, f"{point} in two cycles (periods {seen.get(point)} and {m})"
                seen[point] = m
            assert o.kind in KINDS and o.nu == o.winding / m


def test_orbits_through_the_kinks_at_K3():
    """At K = 3 periodic orbits run through the kinks x = b1, 1 - b2 (corners of C, Eq. Cs). With a
    force continuous only to an ulp (float64 l1, c) such an orbit can vanish or split; the paper's
    force is exactly continuous, so each is found once, in the closed piece (left: x <= b1, right:
    x >= 1 - b2)."""
    fm = FractionMap(K3)
    (ka0, kd0), (ka1, kd1), (ka2, kd2) = fm.kicks
    assert ka0 * fm.b1 + kd0 == ka1 * fm.b1 + kd1 and ka1 * fm.right + kd1 == ka2 * fm.right + kd2
    on_kink = 0
    for o in periodic_orbits(K3, 3):
        for (x, _), symbol in zip(o.exact, o.itinerary, strict=True):
            if x in (fm.b1, fm.right):
                on_kink += 1
                assert symbol // 10 == (0 if x == fm.b1 else 2)
    assert on_kink >= 7


def test_winding_is_the_momentum_gain():
    """w = p_m - p_0 = sum of K f(x_i) over the exact orbit (Eq. am), without the symbol bookkeeping."""
    for p in (K3, K299):
        fm = FractionMap(p)
        for m in range(1, 5):
            for o in periodic_orbits(p, m):
                assert sum(fm.kick(x) for x, _ in o.exact) == o.winding


# -- the project's own arithmetic ------------------------------------------------------------------------
def _one_step(p: MapParams, x: np.ndarray, q: np.ndarray):
    zeros = np.zeros_like(x)
    state = {
        "x": x,
        "q": q,
        "winding": zeros.astype(np.int64),
        "dx": zeros,
        "dp": zeros,
        "log_stretch": zeros,
    }
    out = reference.advance(p, state, 1)
    return out["x"], out["q"]


def _torus_distance(a, b):
    d = np.abs(a - b) % 1.0
    return np.minimum(d, 1.0 - d)


def _local_error(p: MapParams, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(||DM||_inf, bound)`` for one step of ``reference`` from correctly rounded points: each
    coordinate is within u of the exact one, which one step spreads by ``||DM||``; the step rounds
    a handful of numbers below 3 (Eq. fx, ``|K f| < 2``), and its float64 ``l1, l2, c`` are within
    a few ulps of Eq. (mmc), which moves ``K f`` by a few ulps of 2: ``2^-52 (||DM||_inf + 16)``
    in all (16 * 2^-52 = 32 u)."""
    norms = np.abs(p.jacobian(x)).sum(-1).max(-1)
    return norms, 2.0**-52 * (norms + 16)


def _iterate(p: MapParams, x: np.ndarray, q: np.ndarray, steps: int):
    """``steps`` steps of ``reference`` and the first-order bound on the distance from the exact
    images: the local error of step ``i`` carried by the product of the later Jacobians."""
    jacobians, locals_ = [], []
    for _ in range(steps):
        jacobians.append(p.jacobian(x))
        locals_.append(_local_error(p, x)[1])
        x, q = _one_step(p, x, q)
    bound = np.zeros_like(x)
    carry = np.broadcast_to(np.eye(2), (x.size, 2, 2))
    for jac, local in zip(reversed(jacobians), reversed(locals_), strict=True):
        bound = bound + np.abs(carry).sum(-1).max(-1) * local
        carry = carry @ jac
    return x, q, bound


@pytest.mark.parametrize("p", [K3, K299, OTHER], ids=["K3", "K2.99", "K1.7"])
def test_orbits_are_orbits_of_the_kernel_arithmetic(p):
    """Each point, stepped once by ``warpratchet.reference`` (the kernels' bitwise twin), lands on
    the next one within the rounding bound of :func:`_local_error`; iterated m times, the first
    point returns within :func:`_iterate`'s bound (measured: at most 60 ulps for the elliptic
    orbits, 0.6 of the bound for the hyperbolic ones)."""
    for m in range(1, 6):
        for o in periodic_orbits(p, m):
            _, local = _local_error(p, o.x)
            x1, q1 = _one_step(p, o.x, o.p)
            assert np.all(_torus_distance(x1, np.roll(o.x, -1)) <= local)
            assert np.all(_torus_distance(q1, np.roll(o.p, -1)) <= local)
            x, q, bound = _iterate(p, o.x[:1], o.p[:1], m)
            assert _torus_distance(x, o.x[:1])[0] <= bound[0] and _torus_distance(q, o.p[:1])[0] <= bound[0]


@pytest.mark.parametrize("p", [K3, K299, OTHER], ids=["K3", "K2.99", "K1.7"])
def test_residue_is_that_of_the_product_of_jacobians(p):
    """R = (2 - tr)/4 of DM(x_{m-1}) ... DM(x_0) from ``MapParams.jacobian`` at the reported points;
    a float64 product of m matrices is within ``m u prod ||DM||`` entrywise (times 2 for the trace)."""
    for m in range(1, 6):
        for o in periodic_orbits(p, m):
            product = np.eye(2)
            for jac in p.jacobian(o.x):
                product = jac @ product
            norms = np.abs(p.jacobian(o.x)).sum(-1).max(-1)
            tolerance = 2 * m * U * math.prod(norms) + o.residue_tolerance
            assert abs((2.0 - np.trace(product)) / 4.0 - o.residue) <= tolerance
            if o.kind == "hyperbolic":
                assert o.residue < -o.residue_tolerance or o.residue > 1 + o.residue_tolerance


# -- islands: the census and the exact areas at K = 3 ----------------------------------------------------
@pytest.mark.parametrize(("p", "periods"), [(K3, 3), (K299, 6)], ids=["K3", "K2.99"])
def test_elliptic_orbits_carry_the_census_islands(p, periods):
    """The nu of the elliptic orbits up to period M are the census's island classes of period <= M.

    Every elliptic orbit's class has census points (its island is big enough here), and every
    class the census resolves (area above 5 standard errors; single sticky orbits of C make
    classes of a few points) has an elliptic orbit with that nu."""
    elliptic = {
        Fraction(o.winding, o.period)
        for m in range(1, periods + 1)
        for o in periodic_orbits(p, m)
        if o.kind == "elliptic"
    }
    result = census(p, 16_000, points=40_000, seed=5)
    classes = {Fraction(i.w, i.m): i for i in result.islands if i.m <= periods}
    assert elliptic <= set(classes)
    assert {nu for nu, i in classes.items() if i.area > 5 * i.area_stderr} <= elliptic
    if p.K == 3.0:
        assert elliptic == {-1, 0, 1}
    else:
        assert elliptic == {-1, Fraction(-2, 3), Fraction(-1, 3), 0, Fraction(1, 3), Fraction(2, 3)}


@pytest.mark.parametrize(
    ("b1", "b2"), [(0.1, 0.01), (0.05, 0.02), (0.3, 0.03), (0.03, 0.3)], ids=["LR", "LR-Fig1", "R", "L"]
)
def test_period_three_families_tile_the_islands_at_K3(b1, b2):
    """At K = 3 the middle piece has DM^3 = I (Eq. eig): the islands are period-3 families. Their areas
    are Eqs. (SL), (SR) exactly, and the rest of the torus is S_C of Eqs. (SC1)-(SC3)."""
    p = MapParams(3.0, b1, b2)
    areas: dict = defaultdict(float)
    for family in orbit_families(p, 3):
        assert family.residue == 0.0 and family.kind == "parabolic" and family.period == 3
        areas[family.nu] += family.invariant_area
        if family.shape == "polygon":
            assert family.identity and family.area > 0
        else:
            assert family.area == 0.0 and len(family.vertices) == 2
    assert math.isclose(areas[1.0], theory.area_left(p), rel_tol=1e-12, abs_tol=1e-15)
    assert math.isclose(areas[-1.0], theory.area_right(p), rel_tol=1e-12, abs_tol=1e-15)
    assert math.isclose(1.0 - sum(areas.values()), theory.area_chaotic(p), rel_tol=1e-12)


def test_family_points_return_under_the_kernel_arithmetic():
    """Interior points of every K = 3 period-3 polygon family return after 3 steps of ``reference``
    within the rounding bound (DM^3 = I there: a few ulps)."""
    rng = np.random.default_rng(4)
    polygons = [f for f in orbit_families(K3, 3) if f.shape == "polygon"]
    assert len(polygons) == 6
    for family in polygons:
        weights = rng.dirichlet(np.ones(len(family.vertices)), size=50)
        x, q = (weights @ family.vertices).T
        x1, q1, bound = _iterate(K3, x, q, 3)
        assert np.all(_torus_distance(x1, x) <= bound) and np.all(_torus_distance(q1, q) <= bound)
        assert bound.max() <= 2.0**-52 * 1000


def test_no_elliptic_orbits_beyond_period_one_at_K3():
    """Sec. III C: 'there appear to be no higher-period AIs at K = 3' (checked here up to period 5)."""
    for m in range(2, 6):
        assert not [o for o in periodic_orbits(K3, m) if o.kind == "elliptic"]


# -- bad input -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("period", [0, -1, 2.5, True, "3"])
def test_bad_period_is_refused_in_one_line(period):
    with pytest.raises(ValueError, match=r"period = .* is outside the allowed range period >= 1") as info:
        enumerate_orbits(K3, period)
    assert "\n" not in str(info.value)


def test_params_must_be_MapParams():
    with pytest.raises(ValueError, match="is not a MapParams"):
        enumerate_orbits((3.0, 0.1, 0.01), 1)


def test_benchmark_quick(capsys):
    """benchmarks/orbits.py runs and reports consistent rows (no timings checked)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "orbits.py"
    spec = importlib.util.spec_from_file_location("orbits_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [(c["K"], c["b1"], c["b2"]) for c in report["cases"]] == module.CASES
    for case in report["cases"]:
        assert [row["period"] for row in case["rows"]] == [1, 2, 3, 4]
        for row in case["rows"]:
            assert row["candidates"] <= row["nodes"] <= sum(30**d for d in range(row["period"] + 1))
            assert row["brute_force_extrapolated_seconds"] > 0
    families = report["k3_families"]
    assert math.isclose(families["one_minus_families"], families["S_C"], rel_tol=1e-12)
