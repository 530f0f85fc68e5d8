"""``warpratchet run --scheduler ADDRESS [--shards N]``: one ensemble on a Dask cluster.

The run's ensemble is split into shards that run as Dask tasks on the cluster's workers
(:func:`warpratchet.cluster.run_sharded`); the report is ``run``'s, every number in it the one
the same command prints on one machine, plus ``shards`` and ``scheduler``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from ..spec import RunSpec
from .common import UsageError, count_type
from .sinks import _first_given, check_schedule

__all__ = ["add_cluster_flags", "check_cluster_flags", "command"]


def add_cluster_flags(parser: argparse.ArgumentParser) -> None:
    """``--scheduler`` and ``--shards`` of ``run``."""
    group = parser.add_argument_group("one ensemble on a Dask cluster (docs/cluster.md)")
    group.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the ensemble as shards on the workers of this Dask scheduler (e.g. tcp://host:8786); "
        "the numbers are those of the same run on one machine (--threads: each shard's)",
    )
    group.add_argument(
        "--shards",
        type=count_type("shards", 1),
        help="shards of the ensemble, 1 to --points (default: one per worker); with --scheduler",
    )
    group.add_argument(
        "--workdir",
        metavar="FOLDER",
        help="a folder every worker sees: each shard keeps an archive of its points and its records "
        "there, a shard whose worker dies goes on from its checkpoint, and the same command again "
        "continues (or reports) the run; with --scheduler",
    )


def check_cluster_flags(args: argparse.Namespace) -> bool:
    """Whether the run goes to a cluster; UsageError for flags that do not go with it."""
    if args.scheduler is None:
        for flag, given in (("--shards", args.shards), ("--workdir", args.workdir)):
            if given is not None:
                raise UsageError(f"{flag} needs --scheduler ADDRESS (the Dask cluster to run on)")
        return False
    for flag in ("--rerun", "--rerun-spawn"):
        if getattr(args, flag[2:].replace("-", "_"), None):
            raise UsageError(
                f"{flag} does not go with --scheduler: its frames are drawn from the whole ensemble in "
                "one process; take snapshots (--out FILE --snapshot-every STEPS) and replay them with "
                "python -m viz record FILE (docs/cluster.md)"
            )
    if args.out is None:
        _first_given(
            [("--force", args.force), ("--snapshot-every", args.snapshot_every),
             ("--snapshot-points", args.snapshot_points)],
            "--out FILE",
        )  # fmt: skip
    return True


#: The settings an archive of the same run must share with the command (not threads, device or
#: chunk_steps: the numbers do not depend on them).
_SAME_RUN = ("K", "b1", "b2", "init", "points", "seed", "steps", "threshold", "threshold_rule")


def _same_run(out: str, spec: RunSpec) -> None:
    """UsageError unless ``out`` is an archive of this run (the same command again)."""
    from ..archive import ArchiveError, VirtualSourceError, open_archive

    why = f"{out} exists and is not an archive of this run; choose another file"
    try:
        with open_archive(out) as arc:
            stored = arc.spec
    except VirtualSourceError as exc:  # this run's archive, perhaps, but its shards are not all there
        raise UsageError(str(exc)) from None
    except ArchiveError:
        raise UsageError(why) from None
    if stored is None or any(getattr(stored, k) != getattr(spec, k) for k in _SAME_RUN):
        raise UsageError(why)


def command(args: argparse.Namespace, spec: RunSpec) -> int:
    """Run ``spec`` on the cluster at ``args.scheduler`` and print ``run``'s report."""
    from ..cluster import run_sharded
    from .report import history_report, print_report, run_report

    try:
        import distributed
    except ImportError:
        raise UsageError(
            "--scheduler needs dask.distributed: pip install 'warpratchet[distributed]'"
        ) from None
    from ..cluster import shards_folder

    out, workdir = args.out, args.workdir
    if out is not None:
        check_schedule(args, spec)
    if out is not None and os.path.lexists(out) and not args.force:
        _same_run(out, spec)
        workdir = shards_folder(out)  # where this run's shards are: the folder the file reads
        _say(args, f"{out} holds this run already: its report, merged again from the shards in {workdir}")
        write = None
    else:
        write = out
    _say(args, f"connecting to the Dask scheduler at {args.scheduler}")
    try:
        client = distributed.Client(args.scheduler, timeout="60s")
    except OSError as exc:
        raise UsageError(f"--scheduler {args.scheduler}: no Dask scheduler answers there ({exc})") from None
    with client:
        start = time.perf_counter()
        merged = run_sharded(
            spec, client, args.shards, transport=args.transport, out=write,
            workdir=workdir,  # None: run_sharded knows the default
            checkpoint_every=args.checkpoint_every, progress=not args.quiet, force=args.force,
            snapshot_every=args.snapshot_every, snapshot_points=args.snapshot_points or 1000,
        )  # fmt: skip
        seconds = time.perf_counter() - start
    report = run_report(merged, seconds, spec.steps, spec.threshold, spec.threshold_rule)
    if args.transport:
        report["transport"] = merged.report()
    report.update(history_report(merged.history, spec.threshold_rule))
    report["shards"] = merged.shards
    report["scheduler"] = args.scheduler
    if write is not None:
        workdir = shards_folder(out)
    if workdir is not None:
        report["workdir"] = workdir
    if out is not None:
        report["archive"] = out
    print_report(report, args.json)
    if not args.json:
        print(
            f"  {merged.shards} shards on the cluster at {args.scheduler}"
            + (f", archive {out}" if out else "")
        )
    return 0


def _say(args: argparse.Namespace, message: str) -> None:
    """One line on stderr about what the command does (not with --quiet)."""
    if not args.quiet:
        print(f"warpratchet: {message}", file=sys.stderr)
