"""Map parameters of the weak-chaos ratchet accelerator.

The map (Eq. cpem of Dana & Roitberg) is the generalized kicked rotor

    p' = p + K f(x),    x' = x + p'  (mod 1),    0 < K < 4,

with the continuous, piecewise-linear, zero-mean force of Eq. (fx)

    f(x) = l1 x          for 0 <= x <= b1,
           c - x         for b1 < x < 1 - b2,
           l2 (x - 1)    for 1 - b2 <= x < 1,

whose slopes and offset follow from continuity and the ratchet condition
``int_0^1 f dx = 0`` (Eq. mmc, derived in Appendix A).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError, check_real

# check_real is re-exported for callers that import it from here (its home is errors.py).
__all__ = ["MapParams", "check_real"]


@dataclass(frozen=True)
class MapParams:
    """The three free parameters of the map and the derived force coefficients.

    Parameters
    ----------
    K : float
        Kick strength, ``0 < K < 4`` (the middle branch of ``DM`` is elliptic, Eq. eig).
    b1, b2 : float
        Widths of the left and right hyperbolic branches of the force (Eq. fx);
        ``b1 > 0``, ``b2 > 0``, ``b1 + b2 < 1``.

    Raises
    ------
    ParameterError
        (a ``ValueError``) If any parameter is not a finite real number in its allowed range;
        the message names the value and the range.
    """

    K: float
    b1: float
    b2: float

    def __post_init__(self) -> None:
        K = check_real("K", self.K, 0, 4, low_open=True, high_open=True)
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

    # -- derived coefficients, Eq. (mmc) ------------------------------------------------------
    @property
    def b(self) -> float:
        """Total width ``b = b1 + b2`` of the hyperbolic strip B (Eq. B)."""
        return self.b1 + self.b2

    @property
    def _gap(self) -> float:
        # 1 - b1 - b2 correctly rounded: (1 - b1) - b2 would lose digits as b1 + b2 -> 1.
        return math.fsum((1.0, -self.b1, -self.b2))

    @property
    def l1(self) -> float:
        """Left slope ``l1 = (1-b1)(1-b1-b2) / (b1 (2-b1-b2))``, Eq. (mmc).

        Each factor is correctly rounded, so ``l1`` is good to a few ulps from ``b1 ~ 1e-300``
        (the elliptic-sawtooth limit of Fig. 2) up to ``b1 + b2 -> 1``.
        """
        b1, b2 = self.b1, self.b2
        return (1.0 - b1) * self._gap / (b1 * math.fsum((2.0, -b1, -b2)))

    @property
    def l2(self) -> float:
        """Right slope ``l2 = (1-b2)(1-b1-b2) / (b2 (2-b1-b2))``, Eq. (mmc)."""
        b1, b2 = self.b1, self.b2
        return (1.0 - b2) * self._gap / (b2 * math.fsum((2.0, -b1, -b2)))

    @property
    def c(self) -> float:
        """Offset of the middle branch ``c = (1-b2) / (2-b1-b2)``, Eq. (mmc)."""
        return (1.0 - self.b2) / math.fsum((2.0, -self.b1, -self.b2))

    @property
    def alpha(self) -> float:
        """Rotation angle of the elliptic middle branch, ``2 cos(alpha) = 2 - K`` (Eq. eig)."""
        return math.acos(1.0 - 0.5 * self.K)

    def as_dict(self, derived: bool = True) -> dict[str, float]:
        """Parameters and derived coefficients, as stored in archives and JSON output.

        With ``derived=False`` only ``K, b1, b2``, under RunSpec's names (a run's settings, a report).
        """
        free = {"K": self.K, "b1": self.b1, "b2": self.b2}
        return {**free, "l1": self.l1, "l2": self.l2, "c": self.c} if derived else free

    # -- the force, Eq. (fx), in NumPy ----------------------------------------------------------
    def force(self, x: np.ndarray | float) -> np.ndarray:
        """Force ``f(x)`` of Eq. (fx) for ``x`` in ``[0, 1)`` (periodically continued).

        Parameters
        ----------
        x : array_like, shape (n,)
            Positions (dimensionless, unit period).

        Returns
        -------
        ndarray, shape (n,)
            ``f(x)``, the same branch selection as the Warp kernel.
        """
        x = np.mod(np.asarray(x, dtype=np.float64), 1.0)
        return np.where(
            x <= self.b1, self.l1 * x, np.where(x < 1.0 - self.b2, self.c - x, self.l2 * (x - 1.0))
        )

    def force_slope(self, x: np.ndarray | float) -> np.ndarray:
        """Slope ``f'(x)`` (``l1``, ``-1`` or ``l2``), the entry of ``DM`` (Eq. fx)."""
        x = np.mod(np.asarray(x, dtype=np.float64), 1.0)
        return np.where(x <= self.b1, self.l1, np.where(x < 1.0 - self.b2, -1.0, self.l2))

    def jacobian(self, x: np.ndarray | float) -> np.ndarray:
        """Tangent map ``DM`` at ``x``, shape ``(..., 2, 2)`` acting on ``(dx, dp)``.

        From ``p' = p + K f(x)`` and ``x' = x + p'``:
        ``dp' = K f' dx + dp`` and ``dx' = (1 + K f') dx + dp``; ``det DM = 1``.
        """
        kf = self.K * self.force_slope(x)
        one = np.ones_like(kf)
        return np.stack([np.stack([one + kf, one], -1), np.stack([kf, one], -1)], -2)
