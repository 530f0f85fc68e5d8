"""Chaos indicators of one Warp pass: the FTLE, MEGNO and the FLI, and the masks they give.

:class:`IndicatorEnsemble` runs :func:`warpratchet.kernels.advance_map_indicators`, which
advances map and tangent exactly as the plain kernel does (bitwise the same orbit) and also
accumulates MEGNO (Cincotta & Simo 2000) and the fast Lyapunov indicator of the map ``M^8``
at every renormalisation checkpoint. :func:`chaotic_by` turns any of the three into a mask
with its default threshold (:func:`default_threshold`).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from .. import kernels
from ..ensemble import Ensemble
from ..errors import check_choice, renamed_keyword
from ..observables import default_lyapunov_threshold, lyapunov
from ..params import MapParams
from ..spec import INDICATORS  # the one definition: RunSpec's ``indicator`` choices

__all__ = [
    "INDICATORS",
    "MEGNO_THRESHOLD",
    "IndicatorEnsemble",
    "fli_threshold",
    "default_threshold",
    "chaotic_by",
]

#: Mean MEGNO above which an orbit counts as chaotic. Regular orbits tend to 2 (0 when the
#: tangent map is periodic, as in the period-1 islands at K = 3 where ``DM^3 = I``, Eq. eig);
#: chaotic ones grow like ``sigma n / 2``. Twice the regular limit leaves room for the O(1)
#: oscillations of short runs.
MEGNO_THRESHOLD = 4.0

_INDICATOR_FIELDS = kernels.INDICATOR_FIELDS


class IndicatorEnsemble(Ensemble):
    """An :class:`~warpratchet.ensemble.Ensemble` whose runs also accumulate MEGNO and the FLI.

    Same constructor and :meth:`run`; the orbit and tangent are bitwise those of a plain
    ensemble. The indicators need the whole orbit from step 0, so there is no ``from_state``.
    """

    def __init__(self, params: MapParams, x0, p0, **kwargs) -> None:
        super().__init__(params, x0, p0, **kwargs)
        self._indicators = {
            name: wp.zeros(self.points, dtype=wp.float64, device=self.device) for name in _INDICATOR_FIELDS
        }

    @classmethod
    def from_state(cls, *args, **kwargs):
        raise ValueError("an IndicatorEnsemble must start at step 0: MEGNO and FLI need the whole orbit")

    # Ensemble's subclass hooks: the indicator kernel and its accumulators; the chunked,
    # multi-threaded run loop (and observers) are reused unchanged.
    _kernel = kernels.advance_map_indicators

    def _extra_arrays(self) -> list:
        return [self._indicators[name] for name in _INDICATOR_FIELDS]

    def indicators(self) -> dict[str, np.ndarray]:
        """Copies of ``fli`` (``max_j ln|v_8j|``) and ``megno`` (``<Y>`` of ``M^8``), shape ``(points,)``.

        Both refer to the last checkpoint ``8 * (step // 8)``; NaN before the first one.
        """
        checkpoints = self.step // kernels.RENORM_CHECK_EVERY
        fli = np.array(self._indicators["fli"].numpy(), copy=True)
        ysum = self._indicators["megno_ysum"].numpy()
        megno = ysum / checkpoints if checkpoints else np.full(self.points, np.nan)
        if not checkpoints:
            fli[:] = np.nan
        return {"fli": fli, "megno": megno}


def fli_threshold(step: int) -> float:
    """FLI above which an orbit counts as chaotic after ``step`` iterations: ``2 ln n``.

    A regular orbit has ``|v_n| <= a + b n``, so ``FLI <= ln(a + b) + ln n``; ``2 ln n`` admits any
    ``a + b <= n`` (an island whose shear exceeds ``n`` is not resolved after ``n`` steps anyway).
    A chaotic orbit passes it once ``sigma n > 2 ln n``.
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the FLI needs at least one iteration")
    return 2.0 * math.log(step)


@renamed_keyword("classifier", "indicator")
def default_threshold(indicator: str, step: int) -> float:
    """The default chaos threshold of ``indicator`` after ``step`` iterations.

    ``"ftle"``: :func:`~warpratchet.observables.default_lyapunov_threshold`;
    ``"megno"``: :data:`MEGNO_THRESHOLD`; ``"fli"``: :func:`fli_threshold`.
    """
    indicator = check_choice("indicator", indicator, INDICATORS)
    if indicator == "ftle":
        return default_lyapunov_threshold(step)
    if indicator == "megno":
        return MEGNO_THRESHOLD
    return fli_threshold(step)


@renamed_keyword("classifier", "indicator")
def chaotic_by(
    indicator: str,
    state: dict[str, np.ndarray],
    indicators: dict[str, np.ndarray],
    step: int,
    threshold: float | None = None,
) -> np.ndarray:
    """Boolean mask, shape ``(points,)``: the indicator's value ``> threshold``.

    ``"ftle"`` reads the FTLE of ``state``, ``"megno"`` and ``"fli"`` the arrays of
    :meth:`IndicatorEnsemble.indicators`; ``threshold`` defaults to :func:`default_threshold`.
    """
    limit = default_threshold(indicator, step) if threshold is None else threshold
    values = lyapunov(state, step) if indicator == "ftle" else indicators[indicator]
    return values > limit
