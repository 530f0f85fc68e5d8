"""The verdicts of the validation report: each sweep row of Figs. 7-9 against its closed form.

The test. A point passes when ``|A - A_theory| < 4 A_stderr + beta``: ``A_stderr`` is the sampling
error of the ensemble mean (independent initial conditions) and ``beta`` bounds the bias of a
finite run started in the strip B, which is not the invariant measure on C:

    E<A_n> - A = B(n) / n,    B(T) = sum_{s < T} (E<p_{s+1} - p_s> - A).

``B(T)`` stops changing once the ensemble has spread over C (a few hundred steps even for the
weakest chaos of Fig. 7), so :func:`bias_bound` re-runs the first ``T0 = min(1000, n/4)`` steps of
the very same ensemble (same points, sampler and seed as the sweep row), estimates
``B(T0) = T0 (<A_T0> - A_n)`` and takes ``beta = (|B(T0)| + 4 se(B(T0)) + (1 - f) T0 K) / n``.
The last term covers orbits that the FTLE threshold left out of the mean (chaotic fraction
``f``): each moves ``B`` by at most ``T0 K`` (|K f(x)| < K/2, Eq. fx). ``beta`` is typically a
few per cent of the standard error at the paper's n = 120000.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from warpratchet import paper, theory
from warpratchet.ensemble import Ensemble
from warpratchet.observables import finite_time_acceleration
from warpratchet.params import MapParams
from warpratchet.sweep import read_sweep

from .command import command_name

__all__ = [
    "Z_MAX",
    "REQUIRED",
    "BiasBound",
    "bias_window",
    "bias_bound",
    "CheckedRow",
    "closed_form",
    "check_rows",
    "load_sweeps",
    "sigma_stderr",
    "sigma_range",
    "rises",
    "robust_stderr",
]

#: Standard errors allowed between numerics and closed form (plus the bias bound).
Z_MAX = 4.0
#: The sweep files the report needs (``fig6.h5`` is used when present): ``fig9`` is the strip
#: ensemble on Fig. 9's path, ``fig9_paper`` the paper's (:data:`warpratchet.paper.FIG9_ENSEMBLE`).
REQUIRED = ("fig7", "fig7_inset", "fig8", "fig9", "fig9_paper")


# -- the bias of a run started in B ------------------------------------------------------------
@dataclass(frozen=True)
class BiasBound:
    """Transient estimate for one sweep row (see the module docstring).

    ``offset`` is ``B(T0)`` and ``offset_stderr`` its standard error (momentum units);
    ``bound`` is ``beta``, per iteration, in the units of A.
    """

    window: int
    offset: float
    offset_stderr: float
    bound: float


def bias_window(steps: int) -> int:
    """``T0 = min(1000, n/4)``: past the relaxation onto C, short next to ``n``."""
    return max(1, min(1000, steps // 4))


def bias_bound(row: dict[str, Any], threads: int | None = None) -> BiasBound:
    """``beta`` for one sweep row, from a re-run of the first ``T0`` steps of its own ensemble.

    Parameters
    ----------
    row : dict
        A sweep row (:data:`warpratchet.sweep.ROW_FIELDS`): ``K, b1, b2, points, init, seed,
        steps, A, A_stderr, chaotic_fraction``.
    threads : int, optional
        CPU threads for the re-run.
    """
    params = MapParams(row["K"], row["b1"], row["b2"])
    n = int(row["steps"])
    window = bias_window(n)
    ensemble = Ensemble.sample(params, int(row["points"]), row["init"], int(row["seed"]), threads=threads)
    ensemble.run(window)
    # Per-point displacement minus window * A_n: its mean is B(T0).
    shifted = window * (finite_time_acceleration(ensemble.state(), window) - row["A"])
    offset = float(shifted.mean())
    offset_se = math.hypot(float(shifted.std(ddof=1)) / math.sqrt(shifted.size), window * row["A_stderr"])
    left_out = (1.0 - row["chaotic_fraction"]) * window * params.K
    return BiasBound(window, offset, offset_se, (abs(offset) + Z_MAX * offset_se + left_out) / n)


# -- checks -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckedRow:
    """One sweep row against its closed form."""

    row: dict[str, Any]
    theory: float
    bias: BiasBound

    @property
    def deviation(self) -> float:
        return self.row["A"] - self.theory

    @property
    def z(self) -> float:
        """Deviation in standard errors."""
        return self.deviation / self.row["A_stderr"]

    @property
    def tolerance(self) -> float:
        return Z_MAX * self.row["A_stderr"] + self.bias.bound

    @property
    def passed(self) -> bool:
        return abs(self.deviation) < self.tolerance

    @property
    def drifting(self) -> bool:
        """A_n still moves between n/2 and n by more than 3 of its standard errors (the row's verdict)."""
        return self.row["verdict"] == "drifting"

    @property
    def result(self) -> str:
        """``pass``, ``**FAIL**``, or, for a row whose A still drifts, ``drifting (z = ...)`` instead of
        ``pass`` (``**FAIL**, drifting`` for both): its A is not yet the n -> infinity limit."""
        drift = f"drifting (z = {self.row['drift_z']:+.1f})"
        if not self.passed:
            return "**FAIL**, " + drift if self.drifting else "**FAIL**"
        return drift if self.drifting else "pass"


def closed_form(name: str, row: dict[str, Any]) -> float:
    """The paper's A for a row: Eq. (Aa)/(Ab) at K = 3; for Fig. 9 (K = 2.99) Eq. (Ab) at K = 3."""
    if name in ("fig9", "fig9_paper"):
        return float(theory.acceleration(MapParams(paper.K3, row["b1"], row["b2"])))
    value = theory.acceleration(MapParams(row["K"], row["b1"], row["b2"]))
    if value is None:  # pragma: no cover - every path of Figs. 7 and 8 is at K = 3
        raise ValueError(f"no closed form at K = {row['K']!r}")
    return float(value)


def check_rows(name: str, rows: list[dict[str, Any]], threads: int | None = None) -> list[CheckedRow]:
    """Every row of a sweep with its closed form and bias bound, sorted by b2."""
    rows = sorted(rows, key=lambda r: r["b2"])
    return [CheckedRow(r, closed_form(name, r), bias_bound(r, threads)) for r in rows]


def load_sweeps(directory: Path) -> dict[str, list[dict[str, Any]]]:
    """Rows of every sweep file the report uses; ``ValueError`` naming any that is missing."""
    missing = [n for n in REQUIRED if not (directory / f"{n}.h5").exists()]
    if missing:
        raise ValueError(
            f"--sweeps {directory}: no {', '.join(m + '.h5' for m in missing)}; "
            f"make them with: {command_name('figures')} --only fig7,fig8,fig9 --sweeps DIR ..."
        )
    out = {n: read_sweep(directory / f"{n}.h5") for n in REQUIRED}
    if (directory / "fig6.h5").exists():
        out["fig6"] = read_sweep(directory / "fig6.h5")
    for name, rows in out.items():
        if not rows:
            raise ValueError(f"{directory / (name + '.h5')} holds no finished points")
    return out


# -- statistics of a sweep ------------------------------------------------------------------------
def sigma_stderr(row: dict[str, Any]) -> float:
    """Standard error of a row's sigma: FTLE spread over the chaotic orbits / sqrt(their number)."""
    return row["lyapunov_std"] / math.sqrt(max(row["chaotic_points"], 1))


def sigma_range(rows: list[dict[str, Any]]) -> tuple[float, float]:
    """Smallest and largest sigma of a sweep."""
    sigma = [r["lyapunov"] for r in rows]
    return min(sigma), max(sigma)


def robust_stderr(row: dict[str, Any]) -> float:
    """A row's robust standard error, never below the plain one (older sweep files: the plain one)."""
    robust = row["A_stderr_robust"]
    return max(row["A_stderr"], robust) if math.isfinite(robust) else row["A_stderr"]


def rises(checked: list[CheckedRow], robust: bool = False) -> list[tuple[float, float, float]]:
    """Neighbouring points (sorted by b2) where A rises by more than Z_MAX combined standard errors
    (the plain ones, or the robust ones)."""
    error = robust_stderr if robust else (lambda row: row["A_stderr"])
    out = []
    for left, right in zip(checked, checked[1:], strict=False):
        se = math.hypot(error(left.row), error(right.row))
        z = (right.row["A"] - left.row["A"]) / se
        if z > Z_MAX:
            out.append((left.row["b2"], right.row["b2"], z))
    return out
