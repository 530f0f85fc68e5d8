"""Every periodic orbit of the torus map with its residue, and the families of them.

The torus map (Eq. cpem mod 1, in the kernels' variables ``x, q = p mod 1``) is affine on each
cell of a symbol ``(piece of Eq. fx, k = floor(q + K f), j)``; an itinerary of ``m`` symbols
composes to ``z -> A z + b`` with ``A = DM^m``, and a point of exact period ``m`` solves
``(A - I) z = -b`` inside the itinerary's cell. The package

* enumerates the itineraries with a non-empty cell by an exact tree search
  (:mod:`~warpratchet.orbits._search`, :mod:`~warpratchet.orbits._cells`), one least rotation
  per cycle;
* decides each one in exact integer arithmetic (:mod:`~warpratchet.orbits._exact`) for the
  paper's map at the float64 ``K, b1, b2`` (Eq. mmc solved exactly, so the force is exactly
  continuous and orbits through its kinks are not lost or doubled): solved and iterated
  exactly, half-open cells included, each orbit is found exactly once;
* reports each orbit's points, winding ``w`` (Eq. am), ``nu = w / m`` (Eq. AIn), Greene's residue
  ``R = (2 - tr DM^m) / 4`` and kind, and, where ``det(A - I) = 0``, the *families*: polygons of
  periodic points (at K = 3, ``DM^3 = I`` on the middle piece, Eq. eig, and the period-3
  families tile the islands of Appendices D-E: their areas are Eqs. SL, SR, and the rest of the
  torus is ``S_C`` of Eqs. SC1-SC3) or segments.

Public API: :func:`enumerate_orbits` (orbits, families and the search's cost),
:func:`periodic_orbits`, :func:`orbit_families`, :func:`orbits_report` (the CLI's JSON object)
and :func:`format_orbits` (its text form); and a brute-force cross-check of the search
(:mod:`~warpratchet.orbits._words`): :func:`all_words` of the force's alphabet, each word's affine
map (:func:`compose`, with :func:`word_kicks`) and its float64 fixed point
(:func:`fixed_points`), the symbols of the codes (:func:`symbol_table`). Pure: no Warp, no I/O.
"""

from ._enumerate import (
    KINDS,
    SLOPE_ULPS,
    Enumeration,
    Family,
    Orbit,
    enumerate_orbits,
    orbit_families,
    periodic_orbits,
)
from ._report import format_orbits, orbits_report
from ._words import all_words, compose, fixed_points, symbol_table, word_kicks

__all__ = [
    "KINDS",
    "SLOPE_ULPS",
    "Enumeration",
    "Family",
    "Orbit",
    "enumerate_orbits",
    "periodic_orbits",
    "orbit_families",
    "orbits_report",
    "format_orbits",
    "all_words",
    "compose",
    "fixed_points",
    "symbol_table",
    "word_kicks",
]
