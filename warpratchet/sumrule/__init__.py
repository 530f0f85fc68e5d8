"""Island census of the torus and the sum rule, Eq. (sum), for any K.

Sample the unit torus, iterate map and tangent, sort every point into the global chaotic
region ``C``, an island class ``nu = w/m`` (Eq. AIn) or "unidentified", and compare the routes
to the ratchet acceleration ``A``: Eq. (sum) ``A_sumrule = -sum_j S_j nu_j / S_C``, the mean
``A_n`` over ``C`` and ``K <f>_C``. One idea per module:

* :mod:`._indicators`: the chaos indicators of one Warp pass (FTLE, MEGNO, FLI), their masks
  and default thresholds;
* :mod:`._islands`: the per-point classification (``nu = w/m`` from the momentum record);
* :mod:`._areas`: the census (areas with errors) and the three routes to ``A``.
"""

from ..errors import renamed_globals
from ._areas import Census, IslandClass, census, lattice
from ._indicators import (
    INDICATORS,
    MEGNO_THRESHOLD,
    IndicatorEnsemble,
    chaotic_by,
    default_threshold,
    fli_threshold,
)
from ._islands import (
    CHECKPOINTS,
    DEFAULT_M_MAX,
    PointClasses,
    classify,
    excursion_bound,
    identify_nu,
    min_steps,
)

__all__ = [
    "INDICATORS",
    "MEGNO_THRESHOLD",
    "DEFAULT_M_MAX",
    "IndicatorEnsemble",
    "fli_threshold",
    "default_threshold",
    "chaotic_by",
    "CHECKPOINTS",
    "excursion_bound",
    "min_steps",
    "identify_nu",
    "lattice",
    "PointClasses",
    "classify",
    "IslandClass",
    "Census",
    "census",
]

#: ``CLASSIFIERS``, the former name of :data:`INDICATORS`, still works (DeprecationWarning).
__getattr__ = renamed_globals(__name__, {"CLASSIFIERS": "INDICATORS"}, globals())
