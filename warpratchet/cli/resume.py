"""``warpratchet resume``: continue an archived run (``run --out``) to a total number of steps.

The run's settings are the archive's; the map and ensemble flags are optional and, when given,
must equal the archive's (a guard against resuming the wrong file). Output: ``run``'s report.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

from ..spec import LEGACY_NAMES
from .common import (
    HOW_TO_CONTINUE,
    ProgressBar,
    UsageError,
    add_long_flag,
    check_duration,
    print_warnings,
    spec_flag,
    spec_flags,
    stopping,
)
from .report import history_report, print_report, run_report

#: Settings that may be given to check them against the archive.
CHECKED = ("K", "b1", "b2", "knots", "values", "points", "seed", "init")


def add(sub) -> None:
    p = sub.add_parser("resume", help="continue an archived run (run --out) to a total number of steps")
    p.add_argument("archive", help="HDF5 archive written by run --out")
    spec_flag(
        p,
        "steps",
        default=None,
        required=True,
        help="total iterations to reach (beyond the archive's checkpoint)",
    )
    spec_flags(
        p,
        CHECKED,
        **{name: {"default": None, "help": "optional: must equal the archive's"} for name in CHECKED},
    )
    spec_flags(p, ("threads", "device"))
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_long_flag(p)


def _archived(arc) -> dict:
    """The archive's settings under RunSpec's names (format v1 wrote ``sampler`` for ``init``)."""
    stored = {LEGACY_NAMES.get(key, key): value for key, value in arc.settings.items()}
    return {**stored, **arc.params.as_dict(), "points": arc.points}


def _report_complete(args: argparse.Namespace, caught: list) -> int:
    """The report of an archive already at ``--steps`` (as ``run --out`` gives one): nothing run."""
    from ..archive import ArchiveWarning, open_archive

    with warnings.catch_warnings(record=True) as more:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(args.archive) as arc:
            ensemble = arc.ensemble(threads=args.threads, device=args.device)
            history = arc.history
    print_warnings([*caught, *more])
    if not args.quiet:
        print(
            f"warpratchet: {args.archive} holds all {args.steps} steps already: its report, nothing run",
            file=sys.stderr,
        )
    settings = arc.settings
    report = run_report(ensemble, 0.0, 0, settings["threshold"], settings["threshold_rule"])
    if history is not None:
        report.update(history_report(history, settings["threshold_rule"]))
    report["archive"] = args.archive
    print_report(report, args.json)
    return 0


def command(args: argparse.Namespace) -> int:
    from ..archive import ArchiveSink, ArchiveWarning, open_archive, run_to

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(args.archive) as arc:
            archived = _archived(arc)
            start_step = arc.checkpoint_step
        for key in CHECKED:
            asked = getattr(args, key)
            stored = archived.get(key)
            if asked is not None and asked != stored:
                raise UsageError(
                    f"--{key} {asked} disagrees with the archive's {key} = {stored} in {args.archive}"
                )
        if args.steps < start_step:
            raise UsageError(
                f"--steps {args.steps} is behind the archive's checkpoint at step "
                f"{start_step}; pass a total of at least {start_step}"
            )
        if args.steps == start_step:  # done already (the same resume again): report, touch nothing
            return _report_complete(args, caught)
        more = args.steps - start_step
        what = f"{archived['points']} points x {more} more steps"
        check_duration(args, what, archived["points"] * more, args.threads, args.device)
        sink, ensemble = ArchiveSink.resume(
            args.archive, threads=args.threads, device=args.device, how_to_continue=HOW_TO_CONTINUE
        )
    print_warnings(caught)
    from ..history import History

    # An archive written before histories existed: this session's rows only, not archived.
    history = sink.history or History(sink.threshold, sink.threshold_rule)
    first = ensemble.step
    start = time.perf_counter()

    def stopped() -> str:
        return (
            f"at step {ensemble.step} of {args.steps}; {args.archive} keeps the checkpoint at step "
            f"{sink.checkpoint_step}: run the same command again to continue"
        )

    with stopping(stopped):
        try:
            run_to(ensemble, args.steps, [ProgressBar(disable=args.quiet), history, sink], sink.chunk_steps)
        finally:
            sink.close()
    seconds = time.perf_counter() - start
    report = run_report(ensemble, seconds, args.steps - first, sink.threshold, sink.threshold_rule)
    report.update(history_report(history, sink.threshold_rule))
    report["archive"] = args.archive
    print_report(report, args.json)
    return 0
