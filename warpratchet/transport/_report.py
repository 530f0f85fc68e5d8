"""What ``warpratchet run --transport`` reports: one JSON object, or lines for a human.

Pure: no Warp, no I/O (the caller prints).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ._fits import DiffusionFit, tail_fit
from ._histograms import HISTOGRAMS, Histograms

__all__ = ["transport_report", "format_transport", "counts_transport"]


def counts_transport(ensemble: Any) -> bool:
    """Whether ``ensemble`` counts return times and flights (a ``TransportEnsemble``)."""
    return callable(getattr(ensemble, "transport_state", None))


def transport_report(
    completed: Histograms, still_open: Histograms, diffusion: DiffusionFit
) -> dict[str, Any]:
    """The ``"transport"`` object of ``run --json``.

    Keys: ``return_times`` (``edges``, ``counts``, ``open``) and ``flights`` (``edges``,
    ``counts_plus``, ``counts_minus``, ``open_plus``, ``open_minus``): completed runs per log2
    bin (edges in steps) and the runs still open at the end, binned by their length so far;
    ``mu``, ``mu_stderr`` and ``mu_fit`` (:class:`~warpratchet.transport._fits.DiffusionFit`);
    ``tail_exponents``: ``return_times``, ``flights_plus``, ``flights_minus``
    (:class:`~warpratchet.transport._fits.TailFit`).
    """
    bins = max(completed.used_bins(), still_open.used_bins())
    out = completed.as_dict(bins)
    out["return_times"]["open"] = still_open.return_times[:bins].tolist()
    out["flights"]["open_plus"] = still_open.flights_plus[:bins].tolist()
    out["flights"]["open_minus"] = still_open.flights_minus[:bins].tolist()
    fit = diffusion.as_dict()
    out["mu"] = fit.pop("mu")
    out["mu_stderr"] = fit.pop("stderr")
    out["mu_fit"] = fit
    out["tail_exponents"] = {
        name: tail_fit(getattr(completed, name), completed.step).as_dict() for name in HISTOGRAMS
    }
    return out


def _value(value: float | None, spec: str) -> str:
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def _tail(fit: dict) -> str:
    if fit["reason"]:
        return f"no tail exponent ({fit['reason']})"
    lo, hi = fit["lengths"]
    verdict = "" if fit["power_law"] else "; NOT a power law over this range"
    return (
        f"alpha = {fit['alpha']:.3f} +- {fit['stderr']:.3f} over lengths {lo}..{hi - 1} ({fit['counts']} "
        f"runs, p = {fit['p_value']:.2g}{verdict}, truncation bias < {fit['truncation_bias']:.2g})"
    )


def _counts(edges: list[int], counts: list[int]) -> str:
    return " ".join(f"{lo}:{c}" for lo, c in zip(edges, counts, strict=False) if c) or "none"


def format_transport(report: dict[str, Any]) -> str:
    """:func:`transport_report` as lines: mu, then each histogram (bin start: count) with its tail."""
    fit = report["mu_fit"]
    if math.isnan(report["mu"] if report["mu"] is not None else math.nan):
        mu = f"  mu          = n/a ({fit['reason']})"
    else:
        error = f" +- {_value(report['mu_stderr'], '.2g')}"
        mu = (
            f"  mu          = {report['mu']:.4f}{error} (V(n) ~ n^mu over steps {fit['first_step']}.."
            f"{fit['last_step']}, {fit['rows']} rows; error: jackknife over {fit['groups']} groups of points)"
        )
        if fit["reason"]:
            mu += f"; {fit['reason']}"
    returns, flights = report["return_times"], report["flights"]
    tails = report["tail_exponents"]
    lines = [mu]
    rows = (
        ("returns    ", "gaps", returns["counts"], "return_times"),
        ("flights +  ", "runs", flights["counts_plus"], "flights_plus"),
        ("flights -  ", "runs", flights["counts_minus"], "flights_minus"),
    )
    for label, unit, counts, name in rows:
        lines.append(
            f"  {label} : {int(np.sum(counts))} {unit}, by bin start: {_counts(returns['edges'], counts)}"
        )
        lines.append(f"                {_tail(tails[name])}")
    return "\n".join(lines)
