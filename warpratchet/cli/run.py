"""``warpratchet run``: iterate an ensemble and report A and the Lyapunov exponent.

Its flags are the :class:`~warpratchet.spec.RunSpec` fields (``--K --b1 --b2 --points --steps
--seed --init --threads --device --chunk-steps --threshold``) plus the output options of
:mod:`.sinks` (``--out`` archive, ``--rerun`` recording) and ``--transport`` (return times to B,
flights, mu and tail exponents: :mod:`warpratchet.transport`). :func:`run_report` and
:func:`print_report` are also ``resume``'s output.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from typing import Any

from ..spec import RunSpec
from .common import (
    HOW_TO_CONTINUE,
    ProgressBar,
    add_long_flag,
    check_duration,
    print_warnings,
    spec_flags,
    spec_from_args,
    stopping,
)
from .report import history_report, print_report, run_report
from .sharded import add_cluster_flags, check_cluster_flags
from .sinks import add_archive_flags, add_rerun_flags, archive_plan, rerun_sink

#: The RunSpec settings ``run`` takes as flags: all but the indicator (``run`` reports the FTLE's
#: A and Lyapunov exponent; ``sumrule`` has the other indicators).
RUN_SETTINGS = tuple(f.name for f in dataclasses.fields(RunSpec) if f.name != "indicator")


def add(sub) -> None:
    p = sub.add_parser("run", help="iterate an ensemble and report A and the Lyapunov exponent")
    spec_flags(p, RUN_SETTINGS)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_long_flag(p)
    p.add_argument(
        "--transport",
        action="store_true",
        help="also count return times to the strip B and flights (log2 histograms), and fit the "
        'diffusion exponent mu and the tail exponents: adds "transport" to --json',
    )
    add_archive_flags(p)
    add_rerun_flags(p)
    add_cluster_flags(p)


def _archive(args: argparse.Namespace, spec: RunSpec, plan: dict[str, Any], history):
    """``(sink, ensemble, history)``: a new archive of a sampled ensemble (keeping ``history``), or
    the archive resumed (same run) with the history it keeps."""
    import warnings

    from ..archive import ArchiveSink, ArchiveWarning

    if "resume" in plan and plan["resume"] == spec.steps:  # complete: report it, touch nothing
        from ..archive import open_archive

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ArchiveWarning)
            with open_archive(args.out) as arc:
                ensemble = arc.ensemble(threads=spec.threads, device=spec.device)
                history = arc.history or history
        print_warnings(caught)
        _say(args, f"{args.out} holds all {spec.steps} steps already: its report, nothing run")
        return None, ensemble, history
    if "resume" in plan:  # the same command again: continue where the archive stands
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ArchiveWarning)
            sink, ensemble = ArchiveSink.resume(
                args.out, threads=spec.threads, device=spec.device, how_to_continue=HOW_TO_CONTINUE
            )
        print_warnings(caught)
        _say(args, f"continuing {args.out} from its checkpoint at step {ensemble.step} to step {spec.steps}")
        # An archive written before histories existed: record this session's rows, not archived.
        return sink, ensemble, sink.history or history
    ensemble = _sample(args, spec)
    sink = ArchiveSink(args.out, ensemble, history=history, how_to_continue=HOW_TO_CONTINUE, **plan)
    return sink, ensemble, history


def _say(args: argparse.Namespace, message: str) -> None:
    """One line on stderr about what the command does with an existing archive (not with --quiet)."""
    if not args.quiet:
        print(f"warpratchet: {message}", file=sys.stderr)


def _sample(args: argparse.Namespace, spec: RunSpec):
    """The run's ensemble: a TransportEnsemble with ``--transport``, else a plain Ensemble."""
    if args.transport:
        from ..transport import TransportEnsemble as kind
    else:
        from ..ensemble import Ensemble as kind
    ensemble = kind.sample(
        spec.params, spec.points, spec.init, spec.seed, device=spec.device, threads=spec.threads
    )
    if args.transport:
        ensemble.classify_with(spec.threshold, spec.threshold_rule)  # its spread's chaotic points
    return ensemble


def _check_duration(args: argparse.Namespace, spec: RunSpec) -> None:
    """UsageError for a run that cannot end within a day, unless ``--long`` (:func:`.check_duration`)."""
    what = f"{spec.points} points x {spec.steps} steps"
    check_duration(args, what, spec.points * spec.steps, spec.threads, spec.device)


def command(args: argparse.Namespace) -> int:
    from ..history import History

    spec = spec_from_args(args)
    if check_cluster_flags(args):
        from . import sharded

        return sharded.command(args, spec)
    _check_duration(args, spec)
    plan = archive_plan(args, spec)  # bad archive flags fail before any work
    recorder = rerun_sink(args, spec)  # so do bad recording flags
    observers = [ProgressBar(disable=args.quiet)]
    chunk_steps = spec.chunk_steps
    sink = None
    # The history: log-spaced rows and block gains, for the convergence verdict (in the archive too).
    history = History(spec.threshold, spec.threshold_rule)
    if plan is not None:
        sink, ensemble, history = _archive(args, spec, plan, history)
        observers.append(history)
        if sink is not None:
            observers.append(sink)
            chunk_steps = sink.chunk_steps
    else:
        ensemble = _sample(args, spec)
        observers.append(history)
    if recorder is not None:
        observers.append(recorder)  # its frames end chunks themselves (Observer.next_stop)
    first = ensemble.step
    start = time.perf_counter()

    def stopped() -> str:
        # Ensemble.run stops between chunks, so the step is exact; an archive wrote its row and
        # checkpoint there and is closed.
        detail = f"at step {ensemble.step} of {spec.steps}"
        if sink is not None:
            detail += (
                f"; {args.out} keeps the checkpoint at step {sink.checkpoint_step}: "
                "run the same command again to continue"
            )
        return detail

    with stopping(stopped):
        try:
            ensemble.run(spec.steps - first, observers, chunk_steps=chunk_steps)
        finally:
            if sink is not None:
                sink.close()
    seconds = time.perf_counter() - start
    report = run_report(ensemble, seconds, spec.steps - first, spec.threshold, spec.threshold_rule)
    report.update(history_report(history, spec.threshold_rule))
    if plan is not None:
        report["archive"] = args.out
    if recorder is not None and args.rerun is not None:
        report["recording"] = args.rerun
        report["recording_frames"] = len(recorder.frames)
    print_report(report, args.json)
    return 0
