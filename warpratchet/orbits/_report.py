"""What ``warpratchet orbits`` prints: one JSON object, or a text table built from it.

Pure: no Warp, no I/O (the caller prints).
"""

from __future__ import annotations

from collections import Counter

from ..params import MapParams, map_text
from ._enumerate import KINDS, SLOPE_ULPS, Enumeration, Family, Orbit, enumerate_orbits
from ._symbols import describe

__all__ = ["orbits_report", "format_orbits", "orbit_json", "family_json"]


def orbit_json(orbit: Orbit, pieces: int = 3) -> dict:
    """One orbit as JSON: points, winding ``w``, ``nu = w/m`` (Eq. AIn), residue, kind, itinerary."""
    return {
        "x": orbit.x.tolist(),
        "p": orbit.p.tolist(),
        "winding": orbit.winding,
        "nu": orbit.nu,
        "residue": orbit.residue,
        "residue_tolerance": orbit.residue_tolerance,
        "kind": orbit.kind,
        "itinerary": describe(orbit.itinerary, pieces),
    }


def family_json(family: Family, pieces: int = 3) -> dict:
    """One family as JSON: itinerary, winding, ``nu``, shape, vertices ``[[x, p], ...]``, areas."""
    return {
        "itinerary": describe(family.itinerary, pieces),
        "winding": family.winding,
        "nu": family.nu,
        "residue": family.residue,
        "kind": family.kind,
        "shape": family.shape,
        "vertices": family.vertices.tolist(),
        "area": family.area,
        "invariant_area": family.invariant_area,
        "linear_part": "identity" if family.identity else "shear",
    }


def orbits_report(params: MapParams, period: int, *, enumeration: Enumeration | None = None) -> dict:
    """The JSON object of ``warpratchet orbits --K --b1 --b2 --period M --json``.

    Keys: ``K, b1, b2, period``; ``orbits`` (:func:`orbit_json`, sorted by ``nu``, then ``x_0``);
    ``families`` (:func:`family_json`); ``counts`` of orbits by kind and of families;
    ``slope_ulps`` (the parabolic tolerance's basis, see :class:`~warpratchet.orbits.Orbit`);
    ``search`` (tree nodes, candidate itineraries, seconds).

    Parameters
    ----------
    params : MapParams
    period : int
        Exact period ``m >= 1``.
    enumeration : Enumeration, optional
        A finished :func:`~warpratchet.orbits.enumerate_orbits` for ``(params, period)``.
    """
    result = enumeration if enumeration is not None else enumerate_orbits(params, period)
    if (result.params, result.period) != (params, period):
        raise ValueError(
            f"enumeration is for {result.params}, period {result.period}, not {params}, period {period}"
        )
    kinds = Counter(orbit.kind for orbit in result.orbits)
    return {
        **params.as_dict(derived=False),
        "period": result.period,
        "orbits": [orbit_json(orbit, params.table.n_pieces) for orbit in result.orbits],
        "families": [family_json(family, params.table.n_pieces) for family in result.families],
        "counts": {**{kind: kinds.get(kind, 0) for kind in KINDS}, "families": len(result.families)},
        "slope_ulps": SLOPE_ULPS,
        "search": {"nodes": result.nodes, "candidates": result.candidates, "seconds": result.seconds},
    }


#: Text columns: (header, alignment and width, number format, value).
_ORBIT_COLUMNS = (
    ("kind", "<11", "", lambda o: o["kind"]),
    ("w", ">3", "", lambda o: o["winding"]),
    ("nu", ">8", ".4f", lambda o: o["nu"]),
    ("residue", ">13", ".6g", lambda o: o["residue"]),
    ("x0", ">19", ".17f", lambda o: o["x"][0]),
    ("p0", ">19", ".17f", lambda o: o["p"][0]),
)
_FAMILY_COLUMNS = (
    ("family", "<11", "", lambda f: f["shape"]),
    ("w", ">3", "", lambda f: f["winding"]),
    ("nu", ">8", ".4f", lambda f: f["nu"]),
    ("area", ">13", ".6g", lambda f: f["area"]),
    ("invariant area", ">19", ".6g", lambda f: f["invariant_area"]),
    ("vertices", ">8", "", lambda f: len(f["vertices"])),
)


def _table(columns, rows) -> list[str]:
    if not rows:
        return []
    header = " ".join(f"{name:{width}}" for name, width, _, _ in columns)
    return [header] + [
        " ".join(f"{value(row):{width}{number}}" for _, width, number, value in columns) for row in rows
    ]


def format_orbits(report: dict) -> str:
    """A text table of an :func:`orbits_report`: one line per orbit (its first point), then the families."""
    counts = report["counts"]
    title = (
        f"period-{report['period']} orbits at {map_text(report)}: "
        + ", ".join(f"{counts[kind]} {kind}" for kind in KINDS)
        + f", {counts['families']} families ({report['search']['seconds']:.2f} s)"
    )
    lines = [title, *_table(_ORBIT_COLUMNS, report["orbits"]), *_table(_FAMILY_COLUMNS, report["families"])]
    return "\n".join(lines)
