"""The parameter sets and stated numbers of Dana & Roitberg, "Weak-Chaos Ratchet Accelerator".

Every value the paper's figures, captions and text fix is typed here once; the figures and
scenes of ``viz``, the validation report and the tests read it from here. Labels are the
paper's (``Eq. (eig)`` is ``\\label{eig}``; "Fig. 7 caption" quotes the caption of Fig. 7).
Where the project had to choose something the paper leaves open (the spacing of b2 along a
path, the sampler of the initial conditions) the docstring says so.

Pure: no Warp, no I/O; imports only :mod:`warpratchet.params`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .params import MapParams

__all__ = [
    "REFERENCE",
    "K3",
    "Rotation",
    "ROTATIONS",
    "FIG1_WIDTHS",
    "FIG2_WIDTHS",
    "FIG1",
    "FIG2",
    "FIG4",
    "FIG10",
    "FIG11",
    "FIG12",
    "PLANE_EXTENT",
    "MAXIMAL_PATH_END",
    "Path",
    "FIG7",
    "FIG7_INSET",
    "FIG8",
    "FIG9",
    "PATHS",
    "POINTS",
    "STEPS",
    "SAMPLER",
    "FIG8_SMALL_SIGMA_A",
    "FIG8_LIMIT",
    "FIG9_SIGMA",
    "FIG9_ENSEMBLE",
]

#: The paper, as an archive's ``references`` attribute cites it.
REFERENCE = 'I. Dana and V. B. Roitberg, "Weak-Chaos Ratchet Accelerator", Phys. Rev. E'

#: The kick strength of the exact theory (Sec. IV, Eqs. Aa, Ab; Appendices B-E): Figs. 3-8, 10-12.
K3 = 3.0


# -- Figs. 1 and 2: three rotation angles of Eq. (eig) ---------------------------------------------
@dataclass(frozen=True)
class Rotation:
    """One rotation angle of the elliptic middle branch, Eq. (eig): ``2 cos(alpha) = 2 - K``.

    Attributes
    ----------
    panel : str
        The panel of Figs. 1 and 2, ``"a"``, ``"b"`` or ``"c"``.
    alpha : float
        The rotation angle (radians).
    K : float
        The kick strength ``K = 2 - 2 cos(alpha)`` (dimensionless).
    K_stated : float
        ``K`` as the caption of Fig. 1 prints it (``K = 3``, ``K ~ 3.618``, ``K ~ 2.7247``).
    text, tex : str
        ``alpha`` in plain text and in matplotlib TeX.
    """

    panel: str
    alpha: float
    K: float
    K_stated: float
    text: str
    tex: str


def _K_of_alpha(alpha: float) -> float:
    # Eq. (eig); the same expression as warpratchet.theory.K_from_alpha (a pure module may not
    # import theory), and tests/core/test_paper.py checks that the two agree bit for bit.
    return 2.0 - 2.0 * math.cos(alpha)


_GOLDEN_ALPHA = math.pi * (math.sqrt(5.0) - 1.0) / 2.0

#: Fig. 1 caption: "(a) alpha = 2 pi/3 (K = 3); (b) alpha = 6 pi/5 (K ~ 3.618); (c) alpha =
#: pi (sqrt 5 - 1)/2 (K ~ 2.7247)", the integrable, rational and irrational cases of Sec. III B.
#: Panel (a) is K = 3 exactly: 2 - 2 cos(2 pi/3) rounds to 2.9999999999999996, and the K = 3
#: theory (Sec. IV) applies only at K = 3.
ROTATIONS: tuple[Rotation, Rotation, Rotation] = (
    Rotation("a", 2.0 * math.pi / 3.0, K3, 3.0, "2 pi/3", r"$\alpha=2\pi/3$"),
    Rotation("b", 6.0 * math.pi / 5.0, _K_of_alpha(6.0 * math.pi / 5.0), 3.618, "6 pi/5", r"$\alpha=6\pi/5$"),
    Rotation(
        "c",
        _GOLDEN_ALPHA,
        _K_of_alpha(_GOLDEN_ALPHA),
        2.7247,
        "pi (sqrt 5 - 1)/2",
        r"$\alpha=\pi(\sqrt{5}-1)/2$",
    ),
)

#: Fig. 1 caption: ``b1 = 0.05``, ``b2 = 0.02``.
FIG1_WIDTHS = (0.05, 0.02)
#: Fig. 2 caption: "very small b1 = b2 = 10^-7", near the elliptic sawtooth map, Eq. (saw).
FIG2_WIDTHS = (1e-7, 1e-7)
#: Fig. 1, panels (a), (b), (c): the maps of :data:`ROTATIONS` with :data:`FIG1_WIDTHS`.
FIG1: tuple[MapParams, ...] = tuple(MapParams(r.K, *FIG1_WIDTHS) for r in ROTATIONS)
#: Fig. 2, panels (a), (b), (c): "the same values of alpha (or K) as in Fig. 1", :data:`FIG2_WIDTHS`.
FIG2: tuple[MapParams, ...] = tuple(MapParams(r.K, *FIG2_WIDTHS) for r in ROTATIONS)

# -- single parameter sets ----------------------------------------------------------------------
#: Fig. 4 caption: K = 3, b1 = 0.226, b2 = 0.02; only the right island exists (domain R, Eq. cb).
FIG4 = MapParams(K3, 0.226, 0.02)
#: Fig. 10 caption: K = 3, b1 = 0.1, b2 = 0.05 (the regions B, B^(1), B^(2), Eqs. B, B1e, B2e).
FIG10 = MapParams(K3, 0.1, 0.05)
#: Fig. 11: "the union of the three regions shown in Fig. 10" (Eq. Cs); both islands exist.
FIG11 = FIG10
#: Fig. 12 caption: K = 3, b1 = 0.3, b2 = 0.03; only the right island exists.
FIG12 = MapParams(K3, 0.3, 0.03)

#: Figs. 3, 5, 6 show the (b1, b2) plane up to 1/2 on both axes, where the domain lines of
#: Fig. 3 meet the axes: F(0) = (K - 2)/(K - 1) = 1/2 at K = 3 (Eq. lai).
PLANE_EXTENT = 0.5
#: The maximal path of Eq. (b2max) "terminates at b1 = b2 = 1/6, on the boundary of the LR domain".
MAXIMAL_PATH_END = 1.0 / 6.0


# -- Figs. 7-9: the paths of A against sigma --------------------------------------------------------
@dataclass(frozen=True)
class Path:
    """A path through the (b1, b2) plane along which a figure plots A against sigma.

    Attributes
    ----------
    figure : str
        Where the paper shows it, e.g. ``"Fig. 7"``.
    K : float
        Kick strength along the path.
    kind : {"maximal", "line", "fixed-b1"}
        ``b1`` as a function of ``b2``: Eq. (b2max); the line ``b1 = b2 / a`` of Eq. (Ama); or a
        fixed ``b1`` (the names of ``warpratchet sweep --path``).
    b2_range : tuple of float
        ``(low, high)``, both included: the interval of the caption.
    b2_spacing : float
        Distance between neighbouring b2 values. The captions say only "distributed uniformly";
        the spacing is the project's choice, 0.005 (inset: 0.00025), which puts points on both ends.
    a : float, optional
        Slope parameter of ``kind="line"``.
    b1 : float, optional
        The fixed ``b1`` of ``kind="fixed-b1"``.
    """

    figure: str
    K: float
    kind: Literal["maximal", "line", "fixed-b1"]
    b2_range: tuple[float, float]
    b2_spacing: float
    a: float | None = None
    b1: float | None = None

    @property
    def count(self) -> int:
        """Number of b2 values at :attr:`b2_spacing`, both ends included."""
        low, high = self.b2_range
        return round((high - low) / self.b2_spacing) + 1

    def b2_values(self, count: int | None = None) -> np.ndarray:
        """``count`` (default :attr:`count`) evenly spaced b2 on :attr:`b2_range`, shape ``(count,)``."""
        return np.linspace(*self.b2_range, self.count if count is None else count)


#: Fig. 7 caption: the maximal path, Eq. (b2max), "b2 distributed uniformly on 0.005 <= b2 <= 0.165".
FIG7 = Path("Fig. 7", K3, "maximal", (0.005, 0.165), 0.005)
#: Fig. 7 caption: "the inset ... smaller values of b2, distributed uniformly on 0.00025 <= b2 <= 0.00475".
FIG7_INSET = Path("Fig. 7, inset", K3, "maximal", (0.00025, 0.00475), 0.00025)
#: Fig. 8 caption: "the path b1 = 3 b2 with 0.005 <= b2 <= 0.1" (Eq. Ama with a = 1/3).
FIG8 = Path("Fig. 8", K3, "line", (0.005, 0.1), 0.005, a=1.0 / 3.0)
#: Fig. 9 caption: "K = 2.99 on the path b1 = 0.25 and 0.005 <= b2 <= 0.14".
FIG9 = Path("Fig. 9", 2.99, "fixed-b1", (0.005, 0.14), 0.005, b1=0.25)
#: The paths by the stem of their sweep files (``<sweeps>/fig7.h5`` ...).
PATHS: dict[str, Path] = {"fig7": FIG7, "fig7_inset": FIG7_INSET, "fig8": FIG8, "fig9": FIG9}

#: Fig. 7 caption: "averaging (p_n - p_0)/n over an ensemble of 10^4 initial conditions".
POINTS = 10_000
#: Fig. 7 caption: "n = 120000" iterations.
STEPS = 120_000
#: Where the initial conditions start: uniformly in the strip B (Eq. B), as the caption of Fig. 2
#: says of its ensemble. For Figs. 7-9 the caption asks only for points "in the chaotic region";
#: B lies in it and every chaotic orbit enters B (Sec. IV), so the project starts there too.
SAMPLER = "strip"

# -- numbers the captions state -------------------------------------------------------------------
#: Fig. 8 caption: "For small sigma, A ~ 0.12".
FIG8_SMALL_SIGMA_A = 0.12
#: Fig. 8 caption: "the predicted limiting value of A = 0.125 from Eq. (Ama) (a = 1/3)".
FIG8_LIMIT = 0.125
#: Fig. 9 caption: "The Lyapunov exponent on the path varies in the interval 0.4787 < sigma < 0.8326".
FIG9_SIGMA = (0.4787, 0.8326)
#: The ensemble that reproduces :data:`FIG9_SIGMA`, as RunSpec/SweepSpec keywords: initial
#: conditions uniform on the torus, chaotic when the FTLE is "positive", i.e. above the
#: ``(1 + ln n)/n`` of a regular orbit (the caption of Fig. 7: "initial conditions in the chaotic
#: region, i.e., all having positive finite-time Lyapunov exponents"). The paper does not say
#: where its initial conditions lie; this choice is the project's, fixed by the sigma range:
#: within 0.1% at both ends, where the strip B (:data:`SAMPLER`) misses by 6-13% with any chaos
#: criterion and the torus with the stricter default threshold by +1.8% at b2 = 0.005
#: (docs/validation.md, Fig. 9). MEGNO > 4 on the torus gives the same set (sigma to 1e-4);
#: the FTLE rule needs no extra accumulators, so archives, resumes and histories work unchanged.
FIG9_ENSEMBLE = {"init": "torus", "threshold_rule": "positive"}
