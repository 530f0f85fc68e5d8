"""``warpratchet run --scheduler ADDRESS [--shards N]``: one ensemble on a Dask cluster.

The run's ensemble is split into shards that run as Dask tasks on the cluster's workers
(:func:`warpratchet.cluster.run_sharded`); the report is ``run``'s, every number in it the one
the same command prints on one machine, plus ``shards`` and ``scheduler``.
"""

from __future__ import annotations

import argparse
import sys
import time

from ..spec import RunSpec
from .common import UsageError, count_type

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
    for flag, given in (("--out", args.out), ("--rerun", getattr(args, "rerun", None))):
        if given is not None:
            raise UsageError(
                f"{flag} does not go with --scheduler: a run on a cluster keeps its shards' archives "
                "in --workdir FOLDER (docs/cluster.md)"
            )
    return True


def command(args: argparse.Namespace, spec: RunSpec) -> int:
    """Run ``spec`` on the cluster at ``args.scheduler`` and print ``run``'s report."""
    from ..cluster import run_sharded
    from .run import history_report, print_report, run_report

    try:
        import distributed
    except ImportError:
        raise UsageError(
            "--scheduler needs dask.distributed: pip install 'warpratchet[distributed]'"
        ) from None
    if not args.quiet:
        print(f"warpratchet: connecting to the Dask scheduler at {args.scheduler}", file=sys.stderr)
    try:
        client = distributed.Client(args.scheduler, timeout="60s")
    except OSError as exc:
        raise UsageError(f"--scheduler {args.scheduler}: no Dask scheduler answers there ({exc})") from None
    with client:
        start = time.perf_counter()
        merged = run_sharded(spec, client, args.shards, transport=args.transport, workdir=args.workdir)
        seconds = time.perf_counter() - start
    report = run_report(merged, seconds, spec.steps, spec.threshold, spec.threshold_rule)
    if args.transport:
        report["transport"] = merged.report()
    report.update(history_report(merged.history, spec.threshold_rule))
    report["shards"] = merged.shards
    report["scheduler"] = args.scheduler
    if args.workdir is not None:
        report["workdir"] = args.workdir
    print_report(report, args.json)
    return 0
