"""Checking a sweep file: ``warpratchet verify`` for sweep files.

:func:`verify_sweep` reads every dataset and attribute (format v2 checksums every record, so a
damaged one is found) and cross-checks each valid row against what it must be: its ``K, b1,
b2`` equal the point's entry of ``parameters``, its seed is the point's own
(:func:`~warpratchet.sweep._run.point_seed`), its ``steps``/``init`` are the spec's, its domain
and ``A_theory`` are the closed forms', ``chaotic_fraction = chaotic_points / points``. Format
v1 files carry no checksums: the cross-checks are all that can be checked there, and the
report says so.
"""

from __future__ import annotations

import math
import os
from typing import Any

from .. import theory
from .._h5verify import read_everything
from ..errors import FileFormatError
from ..params import MapParams
from ..spec import SweepSpec, attr_value
from ._reading import first_line, open_for_reading, stored_params, valid_rows
from ._records import FORMAT, READABLE_VERSIONS
from ._run import point_seed

__all__ = ["verify_sweep", "row_problems"]


def row_problems(row: dict[str, Any], params: list[MapParams], spec: SweepSpec) -> list[str]:
    """What is wrong with one row of a sweep of ``params`` and ``spec`` (empty: consistent)."""
    i = row["index"]
    if not 0 <= i < len(params):
        return [f"row index {i} is outside the sweep's {len(params)} points"]
    p = params[i]
    out = []
    point = (p.K, p.b1, p.b2) if p.is_paper else (p.K, math.nan, math.nan)  # another force: NaN b1, b2
    if not all(
        a == b or (a != a and b != b) for a, b in zip((row["K"], row["b1"], row["b2"]), point, strict=True)
    ):
        out.append(f"(K, b1, b2) = {(row['K'], row['b1'], row['b2'])} but point {i} is {point}")
    if row["seed"] != point_seed(spec.seed, i):
        out.append(f"seed {row['seed']} is not point {i}'s seed {point_seed(spec.seed, i)}")
    if (row["steps"], row["init"]) != (spec.steps, spec.init):
        out.append(
            f"steps, init = {row['steps']}, {row['init']!r}; the sweep's are {spec.steps}, {spec.init!r}"
        )
    domain = theory.domain(p) if p.is_paper else "n/a"
    if row["domain"] != domain:
        out.append(f"domain {row['domain']!r} is not {domain!r}")
    expected = theory.acceleration(p) if p.K == 3.0 and p.is_paper else None
    if (expected is None) != math.isnan(row["A_theory"]) or (
        expected is not None and row["A_theory"] != expected
    ):
        out.append(f"A_theory = {row['A_theory']!r} is not the closed form's {expected!r}")
    if (
        not 0 < row["points"] <= spec.points
        or row["chaotic_fraction"] != row["chaotic_points"] / row["points"]
    ):
        out.append("points, chaotic_points and chaotic_fraction disagree")
    return [f"row of point {i}: {problem}" for problem in out]


def verify_sweep(path: str | os.PathLike) -> tuple[list[str], dict[str, Any]]:
    """Every problem of the sweep file at ``path`` (empty: clean) and what was checked.

    Raises
    ------
    FileFormatError
        The file is not a warpratchet sweep file (or not one this release reads) at all.
    """
    path = os.fspath(path)
    problems: list[str] = []
    with open_for_reading(path) as f:
        version = attr_value(f.attrs.get("format_version"))
        if version not in READABLE_VERSIONS:
            raise FileFormatError(f"{path}: sweep format version {version!r} is not supported")
        counts = read_everything(f, path, problems)
        checked = {"format": FORMAT, "format_version": int(version), **counts}
        if version == 1:
            checked["note"] = "format v1 has no checksums: only the rows' consistency can be checked"
        try:
            spec = SweepSpec.from_json(attr_value(f.attrs["spec"]))
            params = stored_params(f)
            rows = valid_rows(f, path)
        except (FileFormatError, OSError, KeyError, RuntimeError, ValueError) as exc:
            problems.append(f"cannot read the sweep's definition or rows ({first_line(exc)})")
            return problems, checked
    seen = set()
    for row in rows:
        problems.extend(row_problems(row, params, spec))
        if row["index"] in seen:
            problems.append(f"point {row['index']} has two rows")
        seen.add(row["index"])
    checked["rows"] = len(rows)
    return problems, checked
