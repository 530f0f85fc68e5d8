"""``python -m viz record run.h5 -o run.rrd``: replay an archive's snapshots as a rerun recording.

The archive (``warpratchet run ... --out run.h5 --snapshot-every K``) holds, every ``K`` steps,
``(x, p mod 1)``, the FTLE and ``A_n`` (Eq. An) of a fixed subsample, and one row of ensemble
series per chunk. The recording has one frame of the cloud per snapshot and the whole series
(mean ``A_n`` with its standard error, FTLE statistics, chaotic fraction, the theory's ``A`` of
Eqs. (Aa), (Ab) where it exists), in the layout of :mod:`warpratchet.recording`.
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path
from typing import Any

import numpy as np

from warpratchet.observables import lyapunov_threshold, rule_formula
from warpratchet.recording import SERIES_KEYS, PhaseSpaceRecording

from .command import command_name, run

__all__ = ["replay", "main"]


def replay(
    archive: Any,
    path: str | Path | None,
    *,
    spawn: bool = False,
    color_by: str = "ftle",
    trail: bool = False,
) -> PhaseSpaceRecording:
    """Write the snapshots and series of an open archive to a recording; returns it (closed).

    Parameters
    ----------
    archive : warpratchet.archive.Archive
        From :func:`warpratchet.archive.open_archive`: ``params``, ``settings``, ``series`` and
        ``snapshots`` (``steps (S,)``, ``x, p, ftle, finite_time_acceleration (S, M)``) are read.
    path : str or Path, optional
        ``.rrd`` file to create (must not exist).
    spawn, color_by, trail
        See :class:`warpratchet.recording.PhaseSpaceRecording`.
    """
    settings = archive.settings
    snaps = archive.snapshots
    series = archive.series
    threshold = settings.get("threshold")
    rule = settings.get("threshold_rule", "strict")  # the run's rule, when it gave no threshold
    info = {
        "archive": str(getattr(archive, "path", "")),
        "points": f"{settings.get('points')} ({settings.get('init')}, seed {settings.get('seed')})",
        "recorded points": f"{snaps.x.shape[1] if len(snaps) else 0} (the archive's snapshot subsample)",
        "chaos threshold": rule_formula(rule) if threshold is None else threshold,
    }
    title = f"replay of {Path(str(getattr(archive, 'path', 'archive'))).name}"
    with PhaseSpaceRecording(
        archive.params, path, spawn=spawn, color_by=color_by, trail=trail, title=title, info=info
    ) as rec:
        for s, step in enumerate(np.asarray(snaps.steps)):
            step = int(step)
            if step == 0:  # no FTLE or A_n before the first iteration
                rec.log_cloud(0, snaps.x[s], snaps.p[s])
                continue
            rec.log_cloud(
                step,
                snaps.x[s],
                snaps.p[s],
                ftle=snaps.ftle[s],
                acc=snaps.finite_time_acceleration[s],
                threshold=lyapunov_threshold(step, rule) if threshold is None else threshold,
            )
        if len(series["step"]):
            rec.send_series(series["step"], {key: series[key] for key in SERIES_KEYS})
    return rec


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    """The options of ``python -m viz record``."""
    parser = argparse.ArgumentParser(
        prog=command_name("record") if prog is None else prog, description=__doc__.splitlines()[0]
    )
    parser.add_argument("archive", help="HDF5 archive written by `warpratchet run --out FILE`")
    parser.add_argument("-o", "--output", default=None, help="the .rrd file to write (must not exist)")
    parser.add_argument("--spawn", action="store_true", help="also stream to a newly spawned viewer")
    parser.add_argument(
        "--color",
        choices=["ftle", "class"],
        default="ftle",
        help="colour points by FTLE (log scale) or by class: chaotic / L / R / normal island",
    )
    parser.add_argument(
        "--trail",
        action="store_true",
        help="the default view shows all frames up to the time cursor, not just the current one",
    )
    return parser


def _replay(args: argparse.Namespace, prog: str) -> int:
    if args.output is None and not args.spawn:
        raise ValueError("give -o FILE.rrd, --spawn, or both")
    from warpratchet.archive import open_archive

    with open_archive(args.archive) as archive:
        rec = replay(archive, args.output, spawn=args.spawn, color_by=args.color, trail=args.trail)
    if not rec.frames:
        print(
            f"{prog}: note: {args.archive} has no snapshots (run with --snapshot-every); "
            "the recording holds the series only",
            file=sys.stderr,
        )
    if args.output is not None:
        print(f"wrote {args.output}: {len(rec.frames)} frames")
    return 0


def main(argv: list[str] | None = None, prog: str | None = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for bad input, 130 after Ctrl-C)."""
    parser = build_parser(prog)
    replay_into = functools.partial(_replay, prog=parser.prog)
    return run(parser, argv, replay_into, interrupted="the recording holds the frames written so far")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
