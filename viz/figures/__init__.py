"""The figures of Dana & Roitberg, "Weak-Chaos Ratchet Accelerator", from warpratchet's own numbers.

``python -m viz figures --all --out figures/`` writes ``fig1.png`` ... ``fig12.png`` (and PDFs),
one module per family of figures:

* :mod:`.phase` -- Figs. 1, 2, 4: orbits of an ensemble started uniformly in the strip B (Eq. B)
  on the torus, with the period-1 accelerator modes (Eq. xp) marking the L and R islands.
* :mod:`.plane` -- Figs. 3, 5: closed forms over the (b1, b2) plane (Eq. lai; Eqs. Aa, Ab,
  b2max); Fig. 6: the Lyapunov exponent over a coarse grid of the plane (a sweep).
* :mod:`.acceleration` -- Figs. 7-9: A against sigma along the paper's three paths (sweeps with
  the paper's settings, 10^4 initial conditions in B and n = 120000 steps), with the closed forms.
* :mod:`.regions` -- Figs. 10-12: the regions B, B^(1), B^(2) and C = B u MB u M^2 B (Eq. Cs)
  from the membership tests of :mod:`warpratchet.regions`.

Shared: :mod:`.sweeps` (settings and the sweep files of Figs. 6-9), :mod:`.canvas` (matplotlib,
captions, output files, common axes), :mod:`.cli` (the command). Every parameter comes from
:mod:`warpratchet.paper`.

Sweeps are stored as ``<sweeps>/<name>.h5`` (default ``<out>/sweeps``) by
:func:`warpratchet.sweep.run_sweep` and reused when present: a file made with other settings is
an error, never overwritten. ``viz.report`` turns the same files into ``docs/validation.md``.
Figure files that already exist are not replaced unless ``--overwrite`` is given.

matplotlib is an optional dependency (extra ``figures``); it is imported only when figures are drawn.
"""

from ..paths import fig9_domain_edge
from .cli import FIGURES, main
from .sweeps import SWEEP_NAMES, Settings, load_or_run_sweep, settings_for, sweep_points

__all__ = [
    "FIGURES",
    "SWEEP_NAMES",
    "fig9_domain_edge",
    "Settings",
    "settings_for",
    "sweep_points",
    "load_or_run_sweep",
    "main",
]
