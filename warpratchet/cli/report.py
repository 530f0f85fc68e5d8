"""What ``run``, ``resume`` and ``run --scheduler`` print: the report as JSON or as lines for a human."""

from __future__ import annotations

import math
from typing import Any

from ..params import map_text
from .common import emit_json

__all__ = ["run_report", "print_report", "history_report"]


def run_report(
    ensemble, seconds: float, steps_run: int, threshold: float | None, threshold_rule: str
) -> dict[str, Any]:
    """The JSON object of ``run`` and ``resume``: parameters, A, FTLE statistics, speed."""
    from .. import theory
    from ..transport import counts_transport

    # The summary the run's history (and archive) computed at this step already, not a new one.
    summary = ensemble.summary(threshold, threshold_rule, warn=False).as_dict()
    del summary["step"]  # the report's "steps" is the ensemble's step
    # A, A_stderr, lyapunov (+ _std, _min), chaotic_fraction, chaotic_points, threshold, and
    # whether A can be trusted: reliable, reason, classification_bound (observables.reliability)
    p = ensemble.params
    return {
        **p.as_dict(derived=False),
        "points": ensemble.points,
        "steps": ensemble.step,
        "seed": ensemble.seed,
        "init": ensemble.init,
        "threads": ensemble.threads,
        "A_theory": theory.summary(p)["A"],
        **summary,
        "seconds": seconds,
        "point_steps_per_second": ensemble.points * steps_run / seconds if seconds > 0 else None,
        **({"transport": ensemble.report()} if counts_transport(ensemble) else {}),
    }


def _number(value: float, spec: str) -> str:
    """``value`` formatted, or ``n/a`` for NaN (no chaotic point: nothing to average)."""
    return "n/a" if value is None or math.isnan(value) else format(value, spec)


def _theory_line(report: dict[str, Any]) -> str:
    """The closed form beside A: its value, its equation and the distance in standard errors, or
    why there is none."""
    from .. import theory
    from ..params import MapParams

    a_theory = report["A_theory"]
    if a_theory is None and report.get("knots") is not None:
        return "  theory      : none for this force (the closed forms of Sec. IV are for Eq. (fx))"
    if a_theory is None:
        return "  theory      : none at K != 3 (the closed forms of Sec. IV hold at K = 3 only)"
    domain = theory.domain(MapParams(report["K"], report["b1"], report["b2"]))
    source = {"LR": "Eq. (Aa)", "L": "Eq. (Ab), mirrored", "R": "Eq. (Ab)"}.get(domain, "no island: 0")
    line = f"  theory      = {a_theory:.6g} /iteration, {source}"
    stderr, a = report["A_stderr"], report["A"]
    if a is not None and stderr and math.isfinite(a) and math.isfinite(stderr) and stderr > 0:
        line += f": A - theory = {(a - a_theory) / stderr:+.2f} standard errors"
    return line


def _chaos_line(report: dict[str, Any]) -> str:
    """The Lyapunov exponent and the FTLE threshold behind "chaotic", named with its rule."""
    from ..observables import lyapunov_threshold, rule_formula

    threshold, rule = report["threshold"], report.get("threshold_rule", "strict")
    named = f"FTLE > {_number(threshold, '.3g')}"
    if threshold == lyapunov_threshold(report["steps"], rule):
        named += f" = {rule_formula(rule)} at n = {report['steps']} (rule {rule})"
    return (
        f"  lyapunov    = {_number(report['lyapunov'], '.6g')} /iteration "
        f"(min {_number(report['lyapunov_min'], '.4g')}) over the chaotic points, "
        f"{report['chaotic_fraction']:.4f} of all: {named}"
    )


def print_report(report: dict[str, Any], as_json: bool) -> None:
    """:func:`run_report` as one JSON object, or as lines for a human: A with one standard error
    and its units, the closed form and the distance to it in standard errors, the FTLE threshold
    behind "chaotic", the convergence verdict, what was written."""
    if as_json:
        emit_json(report)
        return
    print(
        f"{map_text(report)}: {report['points']} points x {report['steps']} steps "
        f"({report['init']}, seed {report['seed']})"
    )
    print(
        f"  A           = {_number(report['A'], '.6g')} +- {_number(report['A_stderr'], '.2g')} /iteration"
        " (+- one standard error; momentum in units of the map's period)"
    )
    print(_theory_line(report))
    if not report["reliable"]:
        print(f"  UNRELIABLE  : {report['reason']}")
    print(_chaos_line(report))
    if report.get("verdict") is not None:
        print(
            f"  convergence : A_n - A_n/2 = {_number(report['drift'], '+.2g')} "
            f"(z = {_number(report['drift_z'], '+.2f')}), robust stderr "
            f"{_number(report['A_stderr_robust'], '.2g')}: {report['verdict']}"
        )
    if "transport" in report:
        from ..transport import format_transport

        print(format_transport(report["transport"]))
    if report["point_steps_per_second"]:
        print(f"  {report['seconds']:.2f} s, {report['point_steps_per_second'] / 1e6:.3g} M point-steps/s")
    if report.get("recording"):
        import os

        path = report["recording"]
        size = os.path.getsize(path) / 1e6 if os.path.exists(path) else 0.0
        print(f"  wrote {path}: {report.get('recording_frames')} frames, {size:.1f} MB (view: rerun {path})")


def history_report(history, threshold_rule: str) -> dict[str, Any]:
    """The keys ``run`` and ``resume`` add for the history: the verdict, and the rows under ``history``.

    ``A_stderr_robust``, ``drift`` (A_n - A_n/2), ``drift_z``, ``verdict`` and ``diffusion_exponent``
    (:meth:`warpratchet.history.History.convergence`); ``history`` is a dict of equal-length lists
    (``step``, ``A``, ``A_stderr``, ``sigma``, ``chaotic_fraction``, ``chaotic_points``,
    ``var_dp_all``, ``var_dp_chaotic``).
    """
    verdict = history.convergence()
    return {
        "threshold_rule": threshold_rule,
        "A_stderr_robust": verdict.A_stderr_robust,
        "drift": verdict.drift,
        "drift_z": verdict.drift_z,
        "verdict": verdict.verdict,
        "diffusion_exponent": verdict.exponent,
        "history": history.as_dict(),
    }
