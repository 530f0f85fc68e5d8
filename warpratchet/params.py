"""Map parameters of the weak-chaos ratchet accelerator.

The map (Eq. cpem of Dana & Roitberg) is the generalized kicked rotor

    p' = p + K f(x),    x' = x + p'  (mod 1),    0 < K < 4,

with a continuous, piecewise-linear, zero-mean force ``f``, defined once as a piece table in
:mod:`warpratchet.force`: the paper's family of Eq. (fx) (strip widths ``b1, b2``, slopes and
offset from Eq. mmc, Appendix A), or any other table (``MapParams(K, table=Force.from_knots(...))``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .errors import ParameterError, check_real
from .force import Force, paper_coefficients

# check_real is re-exported for callers that import it from here (its home is errors.py).
__all__ = ["MapParams", "check_real", "map_text"]


def _paper_coefficient(index: int, name: str, doc: str) -> property:
    """The property ``name``: coefficient ``index`` of :func:`warpratchet.force.paper_coefficients`,
    which only the paper's force has."""

    def coefficient(self: MapParams) -> float:
        self.require_paper(name)
        return paper_coefficients(self.b1, self.b2)[index]

    coefficient.__doc__ = doc
    return property(coefficient)


@dataclass(frozen=True)
class MapParams:
    """The map's parameters: ``K`` and the force, the paper's ``b1, b2`` or a piece table.

    Parameters
    ----------
    K : float
        Kick strength, ``0 < K < 4`` (the middle branch of ``DM`` is elliptic, Eq. eig).
    b1, b2 : float
        Widths of the left and right hyperbolic branches of the force (Eq. fx);
        ``b1 > 0``, ``b2 > 0``, ``b1 + b2 < 1``. Left out (None) with ``table``.
    table : Force, optional
        Any other force (:meth:`warpratchet.force.Force.from_knots`); for the paper's family it
        is :meth:`~warpratchet.force.Force.paper` of ``b1, b2``, filled in.

    Raises
    ------
    ParameterError
        (a ``ValueError``) If any parameter is not a finite real number in its allowed range;
        the message names the value and the range.
    """

    K: float
    b1: float | None = None
    b2: float | None = None
    table: Force | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        K = check_real("K", self.K, 0, 4, low_open=True, high_open=True)
        if self.table is not None and self.table.family != "paper":
            if self.b1 is not None or self.b2 is not None:
                raise ParameterError("b1, b2 and a force table are two forces: give one of them")
            if not isinstance(self.table, Force):
                raise ParameterError(f"table = {self.table!r} is not a warpratchet.force.Force")
            object.__setattr__(self, "K", K)
            return
        b1 = check_real("b1", self.b1)
        b2 = check_real("b2", self.b2)
        # The strip widths are bounded jointly (b1 + b2 < 1), which no single-value range says; the
        # messages keep the form "b1 > 0" of release 0.1.
        for name, width in (("b1", b1), ("b2", b2)):
            if not width > 0.0:
                raise ParameterError(f"{name} = {width!r} is outside the allowed range {name} > 0")
        if not b1 + b2 < 1.0:
            raise ParameterError(f"b1 + b2 = {b1 + b2!r} is outside the allowed range b1 + b2 < 1")
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "b1", b1)
        object.__setattr__(self, "b2", b2)
        object.__setattr__(self, "table", Force.paper(b1, b2))

    @property
    def is_paper(self) -> bool:
        """Whether the force is the paper's family of Eq. (fx) (``b1, b2`` given)."""
        return self.table.family == "paper"

    def require_paper(self, name: str) -> None:
        """:class:`ParameterError` naming ``name`` unless the force is Eq. (fx) (``b1, b2``)."""
        if not self.is_paper:
            raise ParameterError(
                f"{name} belongs to the paper's force of Eq. (fx); this map's force has "
                f"{self.table.describe()}"
            )

    def __repr__(self) -> str:
        if self.is_paper:
            return f"MapParams(K={self.K!r}, b1={self.b1!r}, b2={self.b2!r})"
        return f"MapParams(K={self.K!r}, table={self.table!r})"

    # -- derived coefficients, Eq. (mmc) ------------------------------------------------------
    @property
    def b(self) -> float:
        """Total width ``b = b1 + b2`` of the hyperbolic strip B (Eq. B)."""
        self.require_paper("b")
        return self.b1 + self.b2

    l1 = _paper_coefficient(0, "l1", "Left slope ``l1`` of Eq. (mmc).")
    l2 = _paper_coefficient(1, "l2", "Right slope ``l2`` of Eq. (mmc).")
    c = _paper_coefficient(2, "c", "Offset ``c`` of the middle branch, Eq. (mmc).")

    @property
    def alpha(self) -> float:
        """Rotation angle of the elliptic middle branch, ``2 cos(alpha) = 2 - K`` (Eq. eig)."""
        return math.acos(1.0 - 0.5 * self.K)

    def as_dict(self, derived: bool = True) -> dict[str, float]:
        """Parameters and derived coefficients, as stored in archives and JSON output.

        With ``derived=False`` only ``K, b1, b2``, under RunSpec's names (a run's settings, a report).
        Another force gives ``K`` and its ``knots``, ``values`` (decimal strings, exact).
        """
        if not self.is_paper:
            return {"K": self.K, **self.table.as_strings()}
        free = {"K": self.K, "b1": self.b1, "b2": self.b2}
        return {**free, "l1": self.l1, "l2": self.l2, "c": self.c} if derived else free

    # -- the force in NumPy (the kernels' roundings, from the piece table) -----------------------
    def force(self, x: np.ndarray | float) -> np.ndarray:
        """Force ``f(x)`` (Eq. fx for the paper's family) for ``x`` in ``[0, 1)`` (periodically continued).

        Parameters
        ----------
        x : array_like, shape (n,)
            Positions (dimensionless, unit period).

        Returns
        -------
        ndarray, shape (n,)
            ``f(x)``, the same branch selection and roundings as the Warp kernels.
        """
        return self.table.evaluate(np.mod(np.asarray(x, dtype=np.float64), 1.0))[0]

    def force_slope(self, x: np.ndarray | float) -> np.ndarray:
        """Slope ``f'(x)`` (``l1``, ``-1`` or ``l2`` for Eq. fx), the entry of ``DM``."""
        return self.table.evaluate(np.mod(np.asarray(x, dtype=np.float64), 1.0))[1]

    def jacobian(self, x: np.ndarray | float) -> np.ndarray:
        """Tangent map ``DM`` at ``x``, shape ``(..., 2, 2)`` acting on ``(dx, dp)``.

        From ``p' = p + K f(x)`` and ``x' = x + p'``:
        ``dp' = K f' dx + dp`` and ``dx' = (1 + K f') dx + dp``; ``det DM = 1``.
        """
        kf = self.K * self.force_slope(x)
        one = np.ones_like(kf)
        return np.stack([np.stack([one + kf, one], -1), np.stack([kf, one], -1)], -2)


def map_text(values: Mapping) -> str:
    """``K = 3, b1 = 0.1, b2 = 0.01``, or ``K = 2, knots = ..., values = ...`` for another force."""
    if values.get("knots") is not None:
        return f"K = {values['K']}, knots = {values['knots']}, values = {values['values']}"
    return f"K = {values['K']}, b1 = {values['b1']}, b2 = {values['b2']}"
