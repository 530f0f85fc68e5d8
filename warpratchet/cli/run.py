"""``warpratchet run``: iterate an ensemble and report A and the Lyapunov exponent.

Its flags are the :class:`~warpratchet.spec.RunSpec` fields (``--K --b1 --b2 --points --steps
--seed --init --threads --device --chunk-steps --threshold``) plus the output options of
:mod:`.sinks` (``--out`` archive, ``--rerun`` recording). :func:`run_report` and
:func:`print_report` are also ``resume``'s output.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from typing import Any

from ..spec import RunSpec
from .common import Interrupted, ProgressBar, emit_json, print_warnings, spec_flags, spec_from_args
from .sinks import add_archive_flags, add_rerun_flags, archive_plan, rerun_sink

#: The RunSpec settings ``run`` takes as flags: all but the classifier (``run`` reports the FTLE's
#: A and Lyapunov exponent; ``sumrule`` has the other indicators).
RUN_SETTINGS = tuple(f.name for f in dataclasses.fields(RunSpec) if f.name != "classifier")


def add(sub) -> None:
    p = sub.add_parser("run", help="iterate an ensemble and report A and the Lyapunov exponent")
    spec_flags(p, RUN_SETTINGS)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_archive_flags(p)
    add_rerun_flags(p)


def run_report(ensemble, seconds: float, steps_run: int, threshold: float | None) -> dict[str, Any]:
    """The JSON object of ``run`` and ``resume``: parameters, A, FTLE statistics, speed."""
    from .. import theory
    from ..ensemble import STATE_FIELDS
    from ..observables import summarize

    # Views of the live state (zero-copy on the CPU): a copy would double the memory a run needs.
    live = {name: ensemble.array(name) for name in STATE_FIELDS}
    summary = summarize(live, ensemble.step, threshold).as_dict()
    del summary["step"]  # the report's "steps" is the ensemble's step
    # A, A_stderr, lyapunov (+ _std, _min), chaotic_fraction, chaotic_points, threshold, and
    # whether A can be trusted: reliable, reason, classification_bound (observables.reliability)
    p = ensemble.params
    return {
        "K": p.K,
        "b1": p.b1,
        "b2": p.b2,
        "points": ensemble.points,
        "steps": ensemble.step,
        "seed": ensemble.seed,
        "init": ensemble.sampler,
        "threads": ensemble.threads,
        "A_theory": theory.summary(p)["A"],
        **summary,
        "seconds": seconds,
        "point_steps_per_second": ensemble.points * steps_run / seconds if seconds > 0 else None,
    }


def _number(value: float, spec: str) -> str:
    """``value`` formatted, or ``n/a`` for NaN (no chaotic point: nothing to average)."""
    return "n/a" if value is None or math.isnan(value) else format(value, spec)


def print_report(report: dict[str, Any], as_json: bool) -> None:
    """:func:`run_report` as one JSON object, or as four lines for a human (five if A is unreliable)."""
    if as_json:
        emit_json(report)
        return
    a_theory = report["A_theory"]
    print(
        f"K = {report['K']}, b1 = {report['b1']}, b2 = {report['b2']}: "
        f"{report['points']} points x {report['steps']} steps ({report['init']}, seed {report['seed']})"
    )
    print(
        f"  A           = {_number(report['A'], '.6g')} +- {_number(report['A_stderr'], '.2g')}"
        + ("" if a_theory is None else f"   (theory {a_theory:.6g})")
    )
    if not report["reliable"]:
        print(f"  UNRELIABLE  : {report['reason']}")
    print(
        f"  lyapunov    = {_number(report['lyapunov'], '.6g')} (min {_number(report['lyapunov_min'], '.4g')})"
        f" over {report['chaotic_fraction']:.4f} of the points"
    )
    if report["point_steps_per_second"]:
        print(f"  {report['seconds']:.2f} s, {report['point_steps_per_second'] / 1e6:.0f} M point-steps/s")


def _archive(args: argparse.Namespace, spec: RunSpec, plan: dict[str, Any]):
    """``(sink, ensemble)``: a new archive of a sampled ensemble, or the archive resumed (same run)."""
    import warnings

    from ..archive import ArchiveSink, ArchiveWarning
    from ..ensemble import Ensemble

    if "resume" in plan and plan["resume"] == spec.steps:  # complete: report it, touch nothing
        from ..archive import open_archive

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ArchiveWarning)
            with open_archive(args.out) as arc:
                ensemble = arc.ensemble(threads=spec.threads, device=spec.device)
        print_warnings(caught)
        return None, ensemble
    if "resume" in plan:  # the same command again: continue where the archive stands
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ArchiveWarning)
            sink, ensemble = ArchiveSink.resume(args.out, threads=spec.threads, device=spec.device)
        print_warnings(caught)
        return sink, ensemble
    ensemble = Ensemble.sample(
        spec.params, spec.points, spec.init, spec.seed, device=spec.device, threads=spec.threads
    )
    return ArchiveSink(args.out, ensemble, **plan), ensemble


def command(args: argparse.Namespace) -> int:
    from ..ensemble import Ensemble

    spec = spec_from_args(args)
    plan = archive_plan(args, spec)  # bad archive flags fail before any work
    recorder = rerun_sink(args, spec)  # so do bad recording flags
    observers = [ProgressBar(disable=args.quiet)]
    chunk_steps = spec.chunk_steps
    sink = None
    if plan is not None:
        sink, ensemble = _archive(args, spec, plan)
        if sink is not None:
            observers.append(sink)
            chunk_steps = sink.chunk_steps
    else:
        ensemble = Ensemble.sample(
            spec.params, spec.points, spec.init, spec.seed, device=spec.device, threads=spec.threads
        )
    if recorder is not None:
        observers.append(recorder)  # its frames end chunks themselves (Observer.next_stop)
    first = ensemble.step
    start = time.perf_counter()
    try:
        ensemble.run(spec.steps - first, observers, chunk_steps=chunk_steps)
    except KeyboardInterrupt:
        # Ensemble.run stops between chunks, so the step is exact (and the sinks are closed).
        detail = f"at step {ensemble.step} of {spec.steps}"
        if sink is not None:
            detail += (
                f"; {args.out} keeps the checkpoint at step {sink.checkpoint_step}: "
                "run the same command again to continue"
            )
        raise Interrupted(detail) from None
    finally:
        if sink is not None:
            sink.close()
    seconds = time.perf_counter() - start
    report = run_report(ensemble, seconds, spec.steps - first, spec.threshold)
    if plan is not None:
        report["archive"] = args.out
    if recorder is not None and args.rerun is not None:
        report["recording"] = args.rerun
    print_report(report, args.json)
    return 0
