"""The force ``f(x)`` of the map as one piece table: the single definition every body is made from.

The map (Eq. cpem) kicks with a continuous, zero-mean, periodic, piecewise-linear force. A
:class:`Force` is its piece table: knots ``0 = x_0 < x_1 < ... < x_{n-1} < 1`` and the values
``f(x_i)``, linear in between and ``f(1) = f(0)``; piece ``s`` is the affine function
``f = a_s x + d_s`` on ``[x_s, x_{s+1})``, exactly (Fractions). From the same table come

* the float64 *kernel form* of each piece (:attr:`Force.pieces`): ``f = v + a (x - u)``, with the
  operations a trivial coefficient does not need left out, and where ``x`` goes at a knot;
* the code of every body that evaluates the force: the Warp kernels' (portable Python and CPU
  C++, :func:`warp_source`, :func:`cpp_source`), the NumPy twin's (:meth:`Force.evaluate`) and
  the benchmarks' contenders' (Numba and C, :func:`python_source`, :func:`c_source`);
* the exact kicks of the periodic-orbit arithmetic (:meth:`Force.exact_kicks`) and the bounds
  the kernels rely on: ``max |f|`` and ``max |f'|`` (:attr:`Force.max_value`,
  :attr:`Force.max_slope`).

The paper's family (Eq. fx with Eq. mmc) is :meth:`Force.paper`; its float64 coefficients
``l1, l2, c`` are the closed forms of :func:`paper_coefficients` (correctly rounded factors), so
its kernels read them at run time and a sweep over ``b1, b2`` compiles nothing new. Any other
force is :meth:`Force.from_knots`; its coefficients are constants of its generated code.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .errors import ParameterError

__all__ = [
    "Force",
    "Piece",
    "Term",
    "paper_coefficients",
    "cpp_source",
    "c_source",
    "warp_source",
    "python_source",
    "parse_numbers",
    "numbers_text",
    "MAX_PIECES",
]

#: Most pieces a force may have (each is a compare and a select per step in the kernels).
MAX_PIECES = 16


@dataclass(frozen=True)
class Term:
    """A float64 coefficient of the kernel form: its value, and the field of the kernels'
    ``Coefficients`` struct that carries it at run time (``None``: a constant of the code)."""

    value: float
    field: str | None = None


@dataclass(frozen=True)
class Piece:
    """One piece in kernel form, ``f = value + slope (x - anchor)``, from the previous piece's
    ``end`` (0 for the first) to its own.

    ``closed`` says that the knot ``end`` belongs to this piece (``x <= end``) rather than to the
    next (``x < end``). A zero ``value`` or ``anchor`` and a slope of ``-1`` or ``1`` drop the
    operations they make trivial (``anchor - x``, ``slope x``): the same roundings with fewer
    operations.
    """

    end: Term
    closed: bool
    slope: Term
    anchor: Term
    value: Term


def paper_coefficients(b1: float, b2: float) -> tuple[float, float, float]:
    """``l1, l2, c`` of Eq. (mmc) in float64, each factor correctly rounded.

    ``l1 = (1-b1)(1-b1-b2) / (b1 (2-b1-b2))``, ``l2 = (1-b2)(1-b1-b2) / (b2 (2-b1-b2))``,
    ``c = (1-b2) / (2-b1-b2)``: good to a few ulps from ``b1 ~ 1e-300`` (the elliptic-sawtooth
    limit of Fig. 2) up to ``b1 + b2 -> 1`` (``1-b1-b2`` as ``fsum``: ``(1-b1)-b2`` would lose digits).
    """
    gap = math.fsum((1.0, -b1, -b2))
    two_minus_b = math.fsum((2.0, -b1, -b2))
    l1 = (1.0 - b1) * gap / (b1 * two_minus_b)
    l2 = (1.0 - b2) * gap / (b2 * two_minus_b)
    return l1, l2, (1.0 - b2) / two_minus_b


def _exact(name: str, value) -> Fraction:
    """A knot or value as a Fraction: ints, Fractions and decimal strings exactly, a float as the
    decimal it prints as (so ``0.3`` is ``3/10`` from Python as from the command line)."""
    try:
        if isinstance(value, float | np.floating):
            if not math.isfinite(value):
                raise ValueError
            return Fraction(repr(float(value)))
        return Fraction(value)
    except (ValueError, TypeError, ZeroDivisionError):
        raise ParameterError(f"{name} = {value!r} is not a finite real number") from None


def parse_numbers(name: str, value) -> tuple[Fraction, ...]:
    """Knots or values from text (``"0,0.3,0.6"``, ``"1/3"`` too) or a sequence, exactly."""
    items = value.split(",") if isinstance(value, str) else value
    try:
        items = list(items)
    except TypeError:
        raise ParameterError(f"{name} = {value!r} is not a comma-separated list of numbers") from None
    return tuple(_exact(f"{name}[{i}]", v.strip() if isinstance(v, str) else v) for i, v in enumerate(items))


def numbers_text(numbers: Sequence[Fraction]) -> str:
    """The exact text of :func:`parse_numbers`'s numbers (decimals where they end, else ``p/q``)."""
    return ",".join(map(_text, numbers))


def _text(value: Fraction) -> str:
    """An exact number as text: a finite decimal where there is one, else ``p/q``."""
    den = value.denominator
    twos = fives = 0
    while den % 2 == 0:
        den, twos = den // 2, twos + 1
    while den % 5 == 0:
        den, fives = den // 5, fives + 1
    if den != 1:
        return str(value)
    digits = max(twos, fives)
    scaled = abs(value.numerator) * 10**digits // value.denominator
    sign = "-" if value < 0 else ""
    whole, frac = divmod(scaled, 10**digits)
    return f"{sign}{whole}" + (f".{frac:0{digits}d}".rstrip("0") if digits else "")


def _fmt(value: Fraction) -> str:
    return f"{float(value):.6g}"


@dataclass(frozen=True, eq=False)
class Force:
    """The piece table of ``f`` (see the module docstring).

    Attributes
    ----------
    knots, values : tuple of Fraction
        ``x_0 = 0 < ... < x_{n-1} < 1`` and ``f(x_i)``, exact.
    pieces : tuple of Piece
        The float64 kernel form, one per piece, in order.
    family : str
        ``"paper"`` (Eq. fx, :meth:`paper`) or ``"pieces"`` (:meth:`from_knots`).
    """

    knots: tuple[Fraction, ...]
    values: tuple[Fraction, ...]
    pieces: tuple[Piece, ...]
    family: str

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def paper(cls, b1: float, b2: float) -> Force:
        """Eq. (fx): ``l1 x`` on ``[0, b1]``, ``c - x`` on ``(b1, 1 - b2)``, ``l2 (x - 1)`` after.

        The kernels read ``b1``, ``right = 1 - b2`` (float64), ``l1, l2, c``
        (:func:`paper_coefficients`) and ``K`` from their ``Coefficients`` struct.
        """
        l1, l2, c = paper_coefficients(b1, b2)
        B1, B2 = Fraction(b1), Fraction(b2)
        gap, two = 1 - B1 - B2, 2 - B1 - B2
        knots = (Fraction(0), B1, 1 - B2)
        values = (Fraction(0), (1 - B1) * gap / two, -(1 - B2) * gap / two)
        zero, one = Term(0.0), Term(1.0)
        pieces = (
            Piece(Term(b1, "b1"), True, Term(l1, "l1"), zero, zero),
            Piece(Term(1.0 - b2, "right"), False, Term(-1.0), Term(c, "c"), zero),
            Piece(one, False, Term(l2, "l2"), one, zero),
        )
        return cls(knots, values, pieces, "paper")

    @classmethod
    def from_knots(cls, knots: Sequence, values: Sequence) -> Force:
        """A force from its knots ``0 = x_0 < ... < x_{n-1} < 1`` and values ``f(x_i)``.

        Raises
        ------
        ParameterError
            (a ``ValueError``) If the knots do not start at 0, increase and stay below 1, if
            there are fewer than 2 or more than :data:`MAX_PIECES`, if the lengths differ, or if
            the mean ``int_0^1 f dx`` (Eq. mmc: the ratchet condition) is not exactly zero; the
            message says by how much.
        """
        xs, fs = parse_numbers("knots", knots), parse_numbers("values", values)
        n = len(xs)
        if not 2 <= n <= MAX_PIECES:
            raise ParameterError(f"knots has {n} entries, outside the allowed range 2 <= n <= {MAX_PIECES}")
        if len(fs) != n:
            raise ParameterError(f"values has {len(fs)} entries; it needs one per knot ({n})")
        if xs[0] != 0:
            raise ParameterError(f"knots[0] = {_fmt(xs[0])} is outside the allowed range knots[0] = 0")
        for i in range(1, n):
            if not xs[i - 1] < xs[i]:
                raise ParameterError(
                    f"knots[{i}] = {_fmt(xs[i])} is outside the allowed range knots[{i}] > knots[{i - 1}] "
                    f"= {_fmt(xs[i - 1])} (knots must increase)"
                )
        if not xs[-1] < 1:
            raise ParameterError(f"knots[{n - 1}] = {_fmt(xs[-1])} is outside the allowed range knots < 1")
        mean = _mean(xs, fs)
        if mean != 0:
            raise ParameterError(
                f"the force's mean int_0^1 f dx = {float(mean):.6g} is outside the allowed value 0 "
                f"(a ratchet has zero mean force, Eq. mmc; shift the values by {float(-mean):.6g})"
            )
        pieces = []
        for s in range(n):
            end = xs[s + 1] if s + 1 < n else Fraction(1)
            right_value = fs[s + 1] if s + 1 < n else fs[0]
            slope = (right_value - fs[s]) / (end - xs[s])
            # the last piece is written from x = 1, where x - 1 is exact for x near 1
            anchor, value = (Fraction(1), fs[0]) if s == n - 1 else (xs[s], fs[s])
            pieces.append(
                Piece(Term(float(end)), False, Term(float(slope)), Term(float(anchor)), Term(float(value)))
            )
        return cls(xs, fs, tuple(pieces), "pieces")

    # -- exact description ------------------------------------------------------------------------
    def fields(self) -> dict[str, float]:
        """The float64 coefficients the kernels read at run time, by field of their
        ``Coefficients`` struct (the paper's ``b1, right, l1, l2, c``; none for another force)."""
        terms = (t for piece in self.pieces for t in (piece.end, piece.slope, piece.anchor, piece.value))
        return {t.field: t.value for t in terms if t.field is not None}

    @property
    def n_pieces(self) -> int:
        return len(self.knots)

    def exact_pieces(self) -> tuple[tuple[Fraction, Fraction], ...]:
        """``(a_s, d_s)`` per piece, ``f = a_s x + d_s`` on piece ``s``, exactly."""
        out = []
        ends = (*self.knots[1:], Fraction(1))
        nexts = (*self.values[1:], self.values[0])
        for x0, x1, f0, f1 in zip(self.knots, ends, self.values, nexts, strict=True):
            a = (f1 - f0) / (x1 - x0)
            out.append((a, f0 - a * x0))
        return tuple(out)

    def exact_kicks(self, K: float) -> tuple[tuple[Fraction, Fraction], ...]:
        """``(K a_s, K d_s)`` per piece at the float64 ``K``, exactly (the orbit arithmetic)."""
        k = Fraction(K)
        return tuple((k * a, k * d) for a, d in self.exact_pieces())

    def exact_edges(self) -> tuple[tuple[Fraction, bool], ...]:
        """The knots ``x_1 .. x_{n-1}`` exactly, each with ``closed`` (it belongs to the piece on
        its left: ``x <= x_s``, the paper's ``b1``) as the kernels decide it."""
        return tuple((x, piece.closed) for x, piece in zip(self.knots[1:], self.pieces, strict=False))

    def piece_of(self, x: Fraction) -> int:
        """Piece of an exact ``x`` in ``[0, 1)``, by :meth:`exact_edges`."""
        for s, (edge, closed) in enumerate(self.exact_edges()):
            if x < edge or (closed and x == edge):
                return s
        return self.n_pieces - 1

    @property
    def strip(self) -> tuple[bool, ...]:
        """Per piece, whether ``f' > 0`` there: the hyperbolic strip (``B`` of Eq. B for the paper:
        ``|tr DM| = |2 + K f'| > 2`` for every ``K > 0``)."""
        return tuple(a > 0 for a, _ in self.exact_pieces())

    def strip_interval(self) -> tuple[float, float] | None:
        """``(start, width)``: the strip as one interval ``start <= x < start + width`` (mod 1),
        or None when its pieces are not one interval (or there are none)."""
        ends = (*self.knots[1:], Fraction(1))
        runs = [(self.knots[s0], ends[s1]) for s0, s1 in _strip_runs(self)]
        if len(runs) == 2 and runs[0][0] == 0 and runs[1][1] == 1:  # one interval across x = 1
            runs = [(runs[1][0] - 1, runs[0][1])]
        if len(runs) != 1:
            return None
        start, end = runs[0]
        return float(start), float(end - start)

    @property
    def max_value(self) -> Fraction:
        """``max |f|`` (at a knot)."""
        return max(abs(v) for v in self.values)

    @property
    def max_slope(self) -> Fraction:
        """``max |f'|``."""
        return max(abs(a) for a, _ in self.exact_pieces())

    def describe(self) -> str:
        """``knots = ..., values = ...`` in decimal, for messages and reports."""
        knots, values = ",".join(map(_fmt, self.knots)), ",".join(map(_fmt, self.values))
        return f"knots = {knots}, values = {values}"

    def as_strings(self) -> dict[str, str]:
        """``knots`` and ``values`` as comma-separated exact numbers (decimals where they end,
        else ``p/q``): what archives store and ``--knots``/``--values`` read back."""
        return {"knots": numbers_text(self.knots), "values": numbers_text(self.values)}

    def __repr__(self) -> str:
        text = self.as_strings()
        return f"Force.from_knots({text['knots'].split(',')!r}, {text['values'].split(',')!r})"

    @property
    def key(self) -> str:
        """A short hash of the table's kernel form (names the compiled modules of a non-paper force)."""
        text = repr([(p.end, p.closed, p.slope, p.anchor, p.value) for p in self.pieces])
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Force) and (self.knots, self.values, self.family) == (
            other.knots,
            other.values,
            other.family,
        )

    def __hash__(self) -> int:
        return hash((self.knots, self.values, self.family))

    # -- the NumPy body ---------------------------------------------------------------------------
    def select(self, x: np.ndarray) -> list[np.ndarray]:
        """Boolean masks ``x`` in piece ``s`` for ``s < n - 1`` (the last piece is the rest),
        compared with the float64 knots as the kernels compare them."""
        masks, taken = [], np.zeros(np.shape(x), dtype=bool)
        for piece in self.pieces[:-1]:
            inside = (x <= piece.end.value) if piece.closed else (x < piece.end.value)
            masks.append(inside & ~taken)
            taken = taken | inside
        return masks

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``f(x)`` and ``f'(x)`` for ``x`` in ``[0, 1)`` with the kernels' roundings (the NumPy body)."""
        x = np.asarray(x, dtype=np.float64)
        f = _np_piece(self.pieces[-1], x)
        slope = np.full(x.shape, self.pieces[-1].slope.value)
        for piece in reversed(self.pieces[:-1]):
            inside = (x <= piece.end.value) if piece.closed else (x < piece.end.value)
            f = np.where(inside, _np_piece(piece, x), f)
            slope = np.where(inside, piece.slope.value, slope)
        return f, slope

    def in_strip(self, x: np.ndarray) -> np.ndarray:
        """Whether ``x`` in ``[0, 1)`` lies in a piece of the strip (:attr:`strip`), as the kernels decide."""
        x = np.asarray(x, dtype=np.float64)
        inside = np.full(x.shape, self.strip[-1])
        for piece, strip in zip(reversed(self.pieces[:-1]), reversed(self.strip[:-1]), strict=True):
            below = (x <= piece.end.value) if piece.closed else (x < piece.end.value)
            inside = np.where(below, strip, inside)
        return inside


def _mean(xs: Sequence[Fraction], fs: Sequence[Fraction]) -> Fraction:
    ends = (*xs[1:], Fraction(1))
    nexts = (*fs[1:], fs[0])
    return sum(
        ((f0 + f1) / 2 * (x1 - x0) for x0, x1, f0, f1 in zip(xs, ends, fs, nexts, strict=True)), Fraction(0)
    )


def _np_piece(piece: Piece, x: np.ndarray) -> np.ndarray:
    """One piece in NumPy: the operations of :func:`_operations`, in their order."""
    env = {"x": x}

    def get(name: str):
        return getattr(piece, name[5:]).value if name.startswith("term:") else env[name]

    result = "x"
    for result, left, op, right in _operations(piece, 0):
        if not op:
            value = get(left)
            env[result] = value if isinstance(value, np.ndarray) else np.full(x.shape, value)
        elif not left:
            env[result] = -get(right)
        else:
            a, b = get(left), get(right)
            env[result] = a - b if op == "-" else (a + b if op == "+" else a * b)
    return env[result]


# -- the kernels' bodies, as code ------------------------------------------------------------------
def _operations(piece: Piece, s: int) -> list[tuple[str, str, str, str]]:
    """The operations of one piece, ``(result, left, op, right)``, in the order the NumPy body
    (:func:`_np_piece`) does them; ``x`` is the position and ``term:NAME`` a coefficient."""
    a, u, v = piece.slope.value, piece.anchor.value, piece.value.value
    out = f"f{s}"
    if a == 0.0:
        return [(out, "term:value", "", "")]
    if a == -1.0 and v == 0.0 and u != 0.0:
        return [(out, "term:anchor", "-", "x")]
    ops, d = [], "x"
    if u != 0.0:
        ops.append((f"d{s}", "x", "-", "term:anchor"))
        d = f"d{s}"
    if a == 1.0:
        y = d
    elif a == -1.0:
        ops.append((f"y{s}", "", "-", d))
        y = f"y{s}"
    else:
        ops.append((f"y{s}", "term:slope", "*", d))
        y = f"y{s}"
    ops.append((out, "term:value", "+", y) if v != 0.0 else (out, y, "", ""))
    return ops


def _term(piece: Piece, name: str, struct: str, literal) -> str:
    term = getattr(piece, name)
    if term.field is None:
        return literal(term.value)
    return f"{struct}.{term.field}" if struct else term.field


def _assignments(force: Force, struct: str, literal) -> list[tuple[str, str]]:
    """Every piece's operations as ``(name, expression)``, coefficients by field or literal."""
    out = []
    for s, piece in enumerate(force.pieces):
        for result, left, op, right in _operations(piece, s):
            left, right = (
                _term(piece, t[5:], struct, literal) if t.startswith("term:") else t for t in (left, right)
            )
            out.append((result, f"{left} {op} {right}" if op and left else (f"-{right}" if op else left)))
    return out


def cpp_source(force: Force, struct: str = "p", kept: str = "") -> tuple[str, str]:
    """C++ (clang vector extensions, lane vector ``v_t`` and position ``x`` in scope, ``one`` and
    ``zero`` defined) for the CPU body: ``(force, strip)``.

    ``force`` defines ``f`` (the force), ``k_slope`` (``K f'``, each piece's ``K a`` rounded
    once) and ``kick = K f``; ``strip`` defines ``in_strip`` (1 in the strip, else 0) from the
    new ``x``. One operation per statement, so that every rounding is the scalar one. ``kept``:
    a C++ function in scope that each piece's value goes through before the choice of ``f``
    (the same value; the CPU body's way to keep the choice a blend, ``_step``).
    """

    def lit(value: float) -> str:
        return f"{value.hex()}" if value not in (0.0, 1.0) else ("one" if value == 1.0 else "zero")

    lines = []
    n = force.n_pieces
    for s, piece in enumerate(force.pieces[:-1]):
        op = "<=" if piece.closed else "<"
        lines.append(f"const auto in_{s} = x {op} {_term(piece, 'end', struct, lit)};")
    lines += [f"const v_t {result} = {expr};" for result, expr in _assignments(force, struct, lit)]
    values = [f"{kept}(f{s})" if kept else f"f{s}" for s in range(n)]
    lines.append("const v_t f = " + _select([f"in_{s}" for s in range(n - 1)], values) + ";")
    k_terms = []
    for piece in force.pieces:
        a = piece.slope
        if a.value == -1.0 and a.field is None:
            k_terms.append(f"-{struct}.K")
        elif a.value == 1.0 and a.field is None:
            k_terms.append(f"{struct}.K")
        else:
            k_terms.append(f"{struct}.K * {_term(piece, 'slope', struct, lit)}")
    lines.append("const v_t " + ", ".join(f"k{s} = {t}" for s, t in enumerate(k_terms)) + ";")
    lines.append(
        "const v_t k_slope = " + _select([f"in_{s}" for s in range(n - 1)], [f"k{s}" for s in range(n)]) + ";"
    )
    lines.append(f"const v_t kick = {struct}.K * f;")
    return "\n".join(lines) + "\n", f"const v_t in_strip = {_cpp_strip(force, struct, lit)} ? one : zero;\n"


def _select(conditions: list[str], values: list[str]) -> str:
    expr = values[-1]
    for cond, value in zip(reversed(conditions), reversed(values[:-1]), strict=True):
        expr = f"{cond} ? {value} : ({expr})" if expr != values[-1] else f"{cond} ? {value} : {expr}"
    return expr


def _strip_runs(force: Force) -> list[tuple[int, int]]:
    """Runs ``[s0, s1]`` of consecutive strip pieces (the last run may wrap past x = 1)."""
    runs, s = [], 0
    strip = force.strip
    while s < force.n_pieces:
        if strip[s]:
            t = s
            while t + 1 < force.n_pieces and strip[t + 1]:
                t += 1
            runs.append((s, t))
            s = t + 1
        else:
            s += 1
    return runs


def _strip_tests(force: Force, struct: str, literal, negate) -> list[str]:
    """One comparison (or pair) per run of strip pieces: ``x`` at or below a run's last edge, at
    or above its first (the opposite of the edge's own test, ``negate``)."""
    tests = []
    n = force.n_pieces
    for s0, s1 in _strip_runs(force):
        parts = []
        if s0 > 0:
            edge = force.pieces[s0 - 1]
            parts.append(negate(edge.closed, _term(edge, "end", struct, literal)))
        if s1 < n - 1:
            edge = force.pieces[s1]
            op = "<=" if edge.closed else "<"
            parts.append(f"x {op} {_term(edge, 'end', struct, literal)}")
        tests.append(parts)
    return tests


def _cpp_strip(force: Force, struct: str, literal) -> str:
    tests = _strip_tests(force, struct, literal, lambda closed, e: f"x {'>' if closed else '>='} {e}")
    if not tests:
        return "(x != x)"
    terms = [
        f"({' & '.join(f'({t})' for t in parts)})" if len(parts) > 1 else f"({parts[0]})" for parts in tests
    ]
    return terms[0] if len(terms) == 1 else "(" + " | ".join(terms) + ")"


def warp_source(force: Force, name: str, struct: str = "Any") -> str:
    """Python source of two ``wp.func``s for the portable body: ``name(x, p)`` returns ``f`` and
    ``f'``, ``name_strip(x, p)`` 1.0 where ``x`` is in the strip, else 0.0; ``p`` is annotated
    ``struct`` (the kernels' ``Coefficients``, a name the source is executed with).

    Written with ``wp.where`` as the step's other selects, constants as ``wp.float64(repr)``.
    """

    def lit(value: float) -> str:
        return "one" if value == 1.0 else ("zero" if value == 0.0 else f"wp.float64({value!r})")

    n = force.n_pieces
    body = ["    one = wp.float64(1.0)", "    zero = wp.float64(0.0)"]
    for s, piece in enumerate(force.pieces[:-1]):
        op = "<=" if piece.closed else "<"
        body.append(f"    in_{s} = x {op} {_term(piece, 'end', 'p', lit)}")
    body += [f"    {result} = {expr}" for result, expr in _assignments(force, "p", lit)]
    f = f"f{n - 1}"
    slope = _term(force.pieces[-1], "slope", "p", lit)
    for s in reversed(range(n - 1)):
        f = f"wp.where(in_{s}, f{s}, {f})"
        slope = f"wp.where(in_{s}, {_term(force.pieces[s], 'slope', 'p', lit)}, {slope})"
    body.append(f"    f = {f}")
    body.append(f"    slope = {slope}")
    body.append("    return f, slope")
    strip_tests = _strip_tests(force, "p", lit, lambda closed, e: f"x {'>' if closed else '>='} {e}")
    terms = [
        " and ".join(parts) if len(parts) == 1 else "(" + " and ".join(parts) + ")" for parts in strip_tests
    ]
    strip = " or ".join(terms) if terms else "False"
    return (
        f"def {name}(x: wp.float64, p: {struct}):\n"
        + "\n".join(body)
        + f"\n\n\ndef {name}_strip(x: wp.float64, p: {struct}):\n"
        + "    one = wp.float64(1.0)\n    zero = wp.float64(0.0)\n"
        + f"    return wp.where({strip}, one, zero)\n"
    )


def python_source(force: Force, name: str, arguments: Sequence[str] | None = None) -> str:
    """Python source of a scalar function ``name(x, *arguments)`` returning ``f, f'``, one branch
    a piece (the benchmarks' Numba contender). ``arguments``: the run-time coefficients
    (:meth:`Force.fields`) in the order the function takes them (default: that of ``fields``)."""

    def lit(value: float) -> str:
        return repr(value)

    fields = ", ".join(force.fields() if arguments is None else arguments)
    lines = [f"def {name}(x{', ' if fields else ''}{fields}):"]
    ops = {}
    for result, expr in _assignments(force, "", lit):
        ops.setdefault(int(result[1:]), []).append(f"{result} = {expr}")
    for s, piece in enumerate(force.pieces):
        if s < force.n_pieces - 1:
            op = "<=" if piece.closed else "<"
            lines.append(f"    {'if' if s == 0 else 'elif'} x {op} {_term(piece, 'end', '', lit)}:")
        else:
            lines.append("    else:" if s else "    if True:")
        lines += [f"        {line}" for line in ops[s]]
        lines.append(f"        return f{s}, {_term(piece, 'slope', '', lit)}")
    return "\n".join(lines) + "\n"


#: The C of each instruction set :func:`c_source` writes: lane type, mask type, broadcast,
#: arithmetic, comparisons and ``blend(mask, if_false, if_true)``.
_C_ISAS = {
    "c": {
        "vec": "double",
        "mask": "int",
        "set1": "{0}",
        "+": "{0} + {1}",
        "-": "{0} - {1}",
        "*": "{0} * {1}",
        "neg": "-{0}",
        "<=": "{0} <= {1}",
        "<": "{0} < {1}",
        "blend": "{0} ? {2} : {1}",
    },
    "avx2": {
        "vec": "__m256d",
        "mask": "__m256d",
        "set1": "_mm256_set1_pd({0})",
        "+": "_mm256_add_pd({0}, {1})",
        "-": "_mm256_sub_pd({0}, {1})",
        "*": "_mm256_mul_pd({0}, {1})",
        "neg": "_mm256_xor_pd({0}, _mm256_set1_pd(-0.0))",
        "<=": "_mm256_cmp_pd({0}, {1}, _CMP_LE_OQ)",
        "<": "_mm256_cmp_pd({0}, {1}, _CMP_LT_OQ)",
        "blend": "_mm256_blendv_pd({1}, {2}, {0})",
    },
    "avx512": {
        "vec": "__m512d",
        "mask": "__mmask8",
        "set1": "_mm512_set1_pd({0})",
        "+": "_mm512_add_pd({0}, {1})",
        "-": "_mm512_sub_pd({0}, {1})",
        "*": "_mm512_mul_pd({0}, {1})",
        # -d flips the sign bit (0 - d would give +0 for d = +0); AVX-512F has no xor_pd
        "neg": "_mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512({0}), "
        "_mm512_set1_epi64(INT64_MIN)))",
        "<=": "_mm512_cmp_pd_mask({0}, {1}, _CMP_LE_OQ)",
        "<": "_mm512_cmp_pd_mask({0}, {1}, _CMP_LT_OQ)",
        "blend": "_mm512_mask_blend_pd({0}, {1}, {2})",
    },
}


def c_source(force: Force, isa: str = "c", arguments: Sequence[str] | None = None) -> str:
    """C of the force for the benchmarks' C contenders: a header, for ``isa`` ``"c"`` (scalar),
    ``"avx2"`` or ``"avx512"`` (intrinsics), with the operations of :func:`cpp_source` in its order.

    ``force_t`` holds ``K``, the run-time coefficients and ``k0 .. k{n-1}`` (``K f'`` on each
    piece, each ``K a`` rounded once), broadcast to the lanes; ``force_set(K, arguments...)``
    makes one, where ``arguments`` are the run-time coefficients in the order it takes them
    (default: that of :meth:`Force.fields`; a name the force does not use goes unused).
    ``force_kick(x, &m, &kick, &k_slope)`` gives ``kick = K f(x)`` and ``K f'(x)``.
    """
    ops = _C_ISAS.get(isa)
    if ops is None:
        raise ParameterError(f"isa = {isa!r} is outside the allowed values {', '.join(map(repr, _C_ISAS))}")
    fields = tuple(force.fields() if arguments is None else arguments)
    missing = set(force.fields()) - set(fields)
    if missing:
        raise ParameterError(
            f"arguments = {fields!r} lack the force's run-time coefficients {sorted(missing)}"
        )
    vec, mask = ops["vec"], ops["mask"]

    def lit(value: float) -> str:
        return ops["set1"].format("1.0" if value == 1.0 else value.hex())

    def operand(piece: Piece, name: str) -> str:
        if name == "x" or not name.startswith("term:"):
            return name
        return _term(piece, name[5:], "m->", lit).replace("m->.", "m->")

    n = force.n_pieces
    body = []
    for s, piece in enumerate(force.pieces[:-1]):
        edge = operand(piece, "term:end")
        body.append(f"const {mask} in_{s} = {ops['<=' if piece.closed else '<'].format('x', edge)};")
    for s, piece in enumerate(force.pieces):
        for result, left, op, right in _operations(piece, s):
            if not op:
                expr = operand(piece, left)
            elif not left:
                expr = ops["neg"].format(operand(piece, right))
            else:
                expr = ops[op].format(operand(piece, left), operand(piece, right))
            body.append(f"const {vec} {result} = {expr};")

    def select(values: list[str]) -> str:
        expr = values[-1]
        for s in reversed(range(n - 1)):
            expr = ops["blend"].format(
                f"in_{s}", expr if s == n - 2 or isa != "c" else f"({expr})", values[s]
            )
        return expr

    body.append(f"const {vec} f = {select([f'f{s}' for s in range(n)])};")
    body.append(f"*k_slope = {select([f'm->k{s}' for s in range(n)])};")
    body.append(f"*kick = {ops['*'].format('m->K', 'f')};")
    k_terms = []
    for piece in force.pieces:
        a = piece.slope
        if a.field is None and a.value in (-1.0, 1.0):
            k_terms.append("-K" if a.value == -1.0 else "K")
        else:
            k_terms.append(f"K * {a.field if a.field is not None else a.value.hex()}")
    members = ", ".join(("K", *force.fields(), *(f"k{s}" for s in range(n))))
    values = [ops["set1"].format(t) for t in ("K", *force.fields(), *k_terms)]
    parameters = ", ".join(f"double {name}" for name in ("K", *fields))
    guard = f"WARPRATCHET_FORCE_{isa.upper()}_H"
    lines = [
        f"/* The force f of the map in {isa}, written by warpratchet.force.c_source from the piece table",
        f"   ({force.describe()}). */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "#include <stdint.h>",
        *(() if isa == "c" else ("#include <immintrin.h>",)),
        "",
        f"typedef struct {{\n    {vec} {members};\n}} force_t;",
        "",
        f"static inline force_t force_set({parameters})",
        "{",
        *(f"    (void){name};" for name in fields if name not in force.fields()),
        f"    const force_t m = {{{', '.join(values)}}};",
        "    return m;",
        "}",
        "",
        f"static inline void force_kick({vec} x, const force_t *m, {vec} *kick, {vec} *k_slope)",
        "{",
        *(f"    {line}" for line in body),
        "}",
        "",
        "#endif",
    ]
    return "\n".join(lines) + "\n"
