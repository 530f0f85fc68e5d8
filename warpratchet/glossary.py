"""The units and long name of every quantity warpratchet stores, worded once.

Archives label their datasets with it (``units`` and ``long_name`` attributes, ``docs/archive.md``)
and sweep files their columns (``column_units`` and ``column_long_names``, ``docs/sweeps.md``).
One concept, one entry: A is stored in an archive's ``/series`` and in a sweep's rows under the
same name and reads the same in both; a summary field is described here once, not per file.

Keys are a quantity's own name (a field of :class:`~warpratchet.observables.Summary`, of the
per-point state, of the transport carry), or ``group/name`` for a dataset that means something
of its own in that group: an archive group (``series/step``) or a sweep's records (``rows/seed``,
the point's own seed). :func:`describe` looks for ``group/name`` first, then ``name``. Momentum
and position are in units of the map's period (dimensionless, "1"); rates are per iteration.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from .transport._histograms import HISTOGRAMS

__all__ = ["GLOSSARY", "describe"]

#: ``(units, long_name)`` by key (module docstring).
GLOSSARY: dict[str, tuple[str, str]] = {
    # The per-point state (/initial, checkpoint slots) and the transport carry.
    "x": ("1", "position x in [0, 1)"),
    "q": ("1", "fractional momentum p mod 1, in [0, 1)"),
    "winding": ("1", "whole units of momentum gained since step 0"),
    "p0": ("1", "initial momentum; p_n = floor(p0) + winding + q"),
    "dx": ("1", "tangent vector, x component"),
    "dp": ("1", "tangent vector, p component"),
    "log_stretch": ("1", "natural log of the tangent norm removed by renormalisation"),
    "last_visit": ("iteration", "global step of the point's last visit to B; -1 none yet"),
    "flight_gain": ("1", "whole units gained per step by the run in progress; 0 none"),
    "flight_start": ("iteration", "global step of the first step of the run in progress"),
    # The fields of a Summary, in /series and in a sweep's rows.
    "A": ("1/iteration", "mean acceleration A_n of Eq. (An) over chaotic points"),
    "A_stderr": ("1/iteration", "standard error of A: std / sqrt(chaotic points)"),
    "lyapunov": ("1/iteration", "mean finite-time Lyapunov exponent of chaotic points"),
    "lyapunov_std": ("1/iteration", "standard deviation of the FTLE of chaotic points"),
    "lyapunov_min": ("1/iteration", "smallest FTLE of a chaotic point"),
    "chaotic_fraction": ("1", "fraction of points with FTLE above threshold"),
    "chaotic_points": ("1", "number of points with FTLE above threshold"),
    "threshold": ("1/iteration", "FTLE threshold of the chaotic mask"),
    # An archive's groups.
    "series/step": ("iteration", "step at the end of the chunk"),
    "series/wall_time": ("s", "kernel seconds of the chunk"),
    "series/unix_time": ("seconds since 1970-01-01 00:00:00 UTC", "when the row was written"),
    "snapshots/step": ("iteration", "step of the snapshot"),
    "snapshots/indices": ("1", "sorted indices of the subsample's points in the ensemble"),
    "snapshots/p": ("1", "momentum p mod 1, in [0, 1)"),
    "snapshots/p_unwrapped": (
        "1",
        "momentum p_n = p0 + n A_n, not mod 1 (derived: p, finite_time_acceleration, /initial/p0)",
    ),
    "snapshots/ftle": ("1/iteration", "finite-time Lyapunov exponent of each point"),
    "snapshots/finite_time_acceleration": ("1/iteration", "A_n of Eq. (An) of each point"),
    "progress/series_rows": ("1", "valid rows of /series (raised after they are on disk)"),
    "progress/snapshot_rows": ("1", "valid snapshots of /snapshots (raised after they are on disk)"),
    "progress/target_step": ("iteration", "step the last run session aims at; -1 before the first"),
    "progress/history_rows": ("1", "valid rows of /history (raised after they are on disk)"),
    "progress/block_rows": ("1", "valid block records of /history (raised after they are on disk)"),
    "history/step": ("iteration", "step n of the history row"),
    "history/A": ("1/iteration", "mean acceleration A_n of Eq. (An) over chaotic points at n"),
    "history/sigma": ("1/iteration", "mean finite-time Lyapunov exponent of chaotic points at n"),
    "history/chaotic_fraction": ("1", "fraction of points chaotic at n"),
    "history/chaotic_points": ("1", "number of points chaotic at n"),
    "history/var_dp_all": ("1", "variance of p_n - p_0 over all points"),
    "history/var_dp_chaotic": ("1", "variance of p_n - p_0 over the chaotic points"),
    "history/block_step": ("iteration", "end of a time block, floor(target j / blocks)"),
    "history/block_indices": ("1", "sorted indices of the block subsample's points in the ensemble"),
    "history/block_gain": ("1", "p_n - p_0 of each subsample point at the block end"),
    "history/block_ftle": ("1/iteration", "finite-time Lyapunov exponent of each subsample point"),
    "checkpoint/current": ("1", "slot of the newest complete checkpoint: 0 = a, 1 = b, -1 none"),
    "checkpoint/step": ("iteration", "step of the state in this slot; -1 while written or unused"),
    "transport/step": ("iteration", "step at the end of the chunk"),
    "transport/counts": ("1", f"completed runs per log2 bin of length, rows {', '.join(HISTOGRAMS)}"),
    "transport/rows": ("1", "valid rows of /transport (raised after they are on disk)"),
    "transport/spread_steps": ("iteration", "steps of the spread rows (round(10^(k/8)))"),
    "transport/spread": ("1", "per group of points: count, mean, squared deviations of p_n - p_0 (chaotic)"),
    # The columns of a sweep's rows that mean something of their own there.
    "rows/index": ("1", "position of the point in the sweep"),
    "rows/K": ("1", "kick strength K (Eq. cpem)"),
    "rows/b1": ("1", "left strip width b1 (Eq. fx)"),
    "rows/b2": ("1", "right strip width b2 (Eq. fx)"),
    "rows/domain": ("", "domain of Fig. 3: LR, L, R or none"),
    "rows/A_theory": ("1/iteration", "A of Eqs. (Aa)/(Ab) at K = 3; NaN elsewhere"),
    "rows/points": ("1", "ensemble size run"),
    "rows/steps": ("iteration", "iterations run"),
    "rows/seed": ("1", "the point's own seed, point_seed(spec.seed, index)"),
    "rows/init": ("", "sampler of the initial ensemble"),
    "rows/threshold_rule": ("", "rule of the default threshold: strict or positive"),
    "rows/A_stderr_robust": ("1/iteration", "robust standard error of A (batch means over time)"),
    "rows/drift": ("1/iteration", "A_n - A_n/2, the drift of A over the second half of the run"),
    "rows/drift_z": ("1", "the drift in units of its standard error"),
    "rows/verdict": ("", "converged, drifting (|drift_z| > 3), too short or undefined"),
    "rows/diffusion_exponent": ("1", "mu of the block-gain variance ~ T^mu (1 diffusive, 2 ballistic)"),
    "rows/seconds": ("s", "wall time of the ensemble run"),
}


def describe(group: str, name: str) -> tuple[str, str]:
    """``(units, long_name)`` of dataset or column ``name`` of ``group`` (``"series"``, ``"rows"``).

    ``group/name`` if the glossary has it, else the quantity ``name`` (a ``KeyError`` if neither).
    """
    return GLOSSARY.get(f"{group}/{name}") or GLOSSARY[name]
