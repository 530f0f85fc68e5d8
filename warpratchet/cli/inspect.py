"""``warpratchet inspect``: parameters, progress and latest summary of an archive (also while it runs).

Progress is the verified checkpoint, the rows, and (format v2, which stores the run's target step)
the percentage done: at the checkpoint (what a rerun keeps) and, where it differs, at the newest
row (how far a live run is), with an estimate of the kernel time left from the recorded wall
times. A
damaged or non-finite checkpoint is a ``warpratchet: warning:`` line on stderr naming what a
resume would start from instead.
"""

from __future__ import annotations

import argparse
import warnings

from .common import emit_json, print_warnings


def add(sub) -> None:
    p = sub.add_parser("inspect", help="parameters, progress and latest summary of an archive")
    p.add_argument("archive", help="HDF5 archive written by run --out")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _duration(seconds: float) -> str:
    """``42 s``, ``3 min 20 s``, ``2 h 05 min``."""
    seconds = round(seconds)
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def command(args: argparse.Namespace) -> int:
    from .. import theory
    from ..archive import ArchiveWarning, open_archive

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(args.archive) as arc:
            info = arc.info()
            info["A_theory"] = theory.summary(arc.params)["A"]
    print_warnings(caught)
    if args.json:
        emit_json(info)
        return 0
    p, s, v, last = info["params"], info["settings"], info["versions"], info["latest"]
    version = f"v{info['format_version']}.{info['format_minor']}"
    print(f"{info['path']}: {info['format']} {version}, created {info['created']}")
    if "knots" in p:
        print(f"  K = {p['K']}, knots = {p['knots']}, values = {p['values']}")
    else:
        print(
            f"  K = {p['K']}, b1 = {p['b1']}, b2 = {p['b2']}  (l1 = {p['l1']:.6g}, l2 = {p['l2']:.6g}, "
            f"c = {p['c']:.6g})"
        )
    snaps = (
        f"snapshots of {s['snapshot_points']} points every {s['snapshot_every']} steps"
        if s["snapshot_every"]
        else "no snapshots"
    )
    init = s["init"]
    print(
        f"  {s['points']} points ({init}, seed {s['seed']}), chunks of {s['chunk_steps']} steps, "
        f"checkpoint every {s['checkpoint_every']}, {snaps}"
    )
    print(
        f"  progress: checkpoint at step {info['checkpoint_step']}, {info['rows']} series rows, "
        f"{info['snapshots']} snapshots"
    )
    if info["target_step"] is not None:
        done = (
            f"  target: step {info['target_step']}, {100 * info['done']:.1f}% done at the checkpoint "
            "(where a rerun continues)"
        )
        if info["latest_done"] != info["done"]:
            done += f", {100 * info['latest_done']:.1f}% at the newest row"
        if info["eta_seconds"] == 0:
            done += " (complete)"
        elif info["eta_seconds"] is not None:
            done += f", about {_duration(info['eta_seconds'])} of kernel time to go"
            done += f" at {info['steps_per_second']:.3g} steps/s"
        print(done)
    if last is None:
        print("  latest: no chunk recorded yet")
    else:
        a_theory = "" if info["A_theory"] is None else f"   (theory {info['A_theory']:.6g})"
        print(
            f"  latest (step {last['step']}): A = {last['A']:.6g} +- {last['A_stderr']:.2g}{a_theory}, "
            f"lyapunov = {last['lyapunov']:.6g} over {last['chaotic_fraction']:.4f} of the points"
        )
    h = info["history"]
    if h is not None and "convergence" in h:
        c = h["convergence"]
        print(
            f"  history: {h['rows']} rows, {h['blocks']} block records; at its last row A_n - A_n/2 = "
            f"{c['drift']:+.2g} (z = {c['drift_z']:+.2f}), robust stderr {c['A_stderr_robust']:.2g}: "
            f"{c['verdict']}"
        )
    elif h is not None:
        print("  history: no row recorded yet")
    print("  written by " + ", ".join(f"{k} {val}" for k, val in v.items()))
    return 0
