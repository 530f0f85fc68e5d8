"""The output options of ``run``: an archive (``--out``, docs/archive.md) and a rerun recording.

Each sink's flags are checked up front, before any work, so a bad combination costs nothing:
``--snapshot-every`` without ``--out``, ``--rerun-every`` without ``--rerun``, a file that is not
an archive of this run. The archive's schedule options are the archive's, not the run's (they
change what is written, never a number): :func:`warpratchet.archive.schedule` checks them.

Resuming is one behaviour for ``run`` and ``sweep``: the same command again continues what an
interrupted one left. ``run --out FILE`` on an archive of the same run (map, ensemble, threshold
and schedule) resumes it from its checkpoint to ``--steps``; on anything else it refuses and
names the difference (``--force`` replaces the file).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from typing import Any

from ..limits import MAX_STEP
from ..spec import CHECKPOINT_SECONDS, RunSpec, check_checkpoint_seconds
from .common import UsageError, _typed, count_type


def _first_given(flags: list[tuple[str, Any]], needs: str) -> None:
    """UsageError naming the first flag given without the one it needs."""
    given = [flag for flag, value in flags if value]
    if given:
        raise UsageError(f"{given[0]} needs {needs}")


# -- archives -----------------------------------------------------------------------------------
def _count_flag(
    p: argparse.ArgumentParser,
    flag: str,
    low: int,
    default: int | None,
    help: str,
    metavar: str | None = None,
    high: int | None = None,
) -> None:
    """A count flag whose errors name it as a setting (``--snapshot-every`` -> ``snapshot_every``)."""
    kind = count_type(flag[2:].replace("-", "_"), low, high)
    p.add_argument(flag, type=kind, default=default, help=help, metavar=metavar)


def add_archive_flags(p: argparse.ArgumentParser) -> None:
    """The archive options of ``run`` (docs/archive.md)."""
    p.add_argument("--out", default=None, help="stream the run into this HDF5 archive (resumable)")
    p.add_argument("--force", action="store_true", help="with --out: replace an existing file")
    with_out = "with --out: steps between"
    _count_flag(
        p,
        "--snapshot-every",
        0,
        0,
        f"{with_out} x, p snapshots of a fixed subsample (default 0: none)",
        high=MAX_STEP,
    )
    _count_flag(
        p, "--snapshot-points", 1, None, "with --out: points in the snapshot subsample (default 1000)"
    )
    _count_flag(
        p, "--checkpoint-every", 1, None, f"{with_out} full checkpoints (default 8 chunks)", high=MAX_STEP
    )
    p.add_argument(
        "--checkpoint-seconds",
        type=_typed(float, check_checkpoint_seconds),
        default=None,
        metavar="SECONDS",
        help="with --out: also checkpoint so that at most this much work (wall clock) is unsaved "
        f"(default {CHECKPOINT_SECONDS:g})",
    )


def archive_plan(args: argparse.Namespace, spec: RunSpec) -> dict[str, Any] | None:
    """ArchiveSink keywords from the run flags (None without --out); checks them up front."""
    if args.out is None:
        _first_given(
            [
                ("--force", args.force),
                ("--snapshot-every", args.snapshot_every),
                ("--snapshot-points", args.snapshot_points),
                ("--checkpoint-every", args.checkpoint_every),
                ("--checkpoint-seconds", args.checkpoint_seconds is not None),
            ],
            "--out FILE",
        )
        return None
    check_schedule(args, spec)
    if os.path.lexists(args.out) and not args.force:
        return {"resume": _resumable(args, spec)}
    return {
        "force": args.force,
        "snapshot_every": args.snapshot_every,
        "snapshot_points": 1000 if args.snapshot_points is None else args.snapshot_points,
        "checkpoint_every": args.checkpoint_every,
        **({} if args.checkpoint_seconds is None else {"checkpoint_seconds": args.checkpoint_seconds}),
        "chunk_steps": spec.chunk_steps,
        "threshold": spec.threshold,
        "threshold_rule": spec.threshold_rule,
    }


def check_schedule(args: argparse.Namespace, spec: RunSpec) -> None:
    """UsageError (or ValueError) for archive schedule flags that do not go with ``spec``."""
    from ..archive import schedule

    schedule(spec.points, spec.chunk_steps, args.snapshot_every, args.checkpoint_every)  # ValueError if bad
    if args.snapshot_points is not None and args.snapshot_points > spec.points:
        raise UsageError(
            f"--snapshot-points {args.snapshot_points} is more than the run's {spec.points} points "
            f"(allowed range 1 <= snapshot_points <= {spec.points})"
        )


def _resumable(args: argparse.Namespace, spec: RunSpec) -> int:
    """The checkpoint step of ``--out`` if it is an archive of this same run; UsageError otherwise."""
    import h5py

    from ..archive import ArchiveError, open_archive

    replace = "choose another file or pass --force to replace it"
    if not os.path.isfile(args.out) or not h5py.is_hdf5(args.out):
        raise UsageError(f"{args.out} exists and is not a warpratchet archive; {replace}")
    try:
        with open_archive(args.out) as arc:
            stored = {**arc.settings, **arc.params.as_dict(), "transport": "transport" in arc.features}
            checkpoint = arc.checkpoint_step
    except ArchiveError as exc:
        raise UsageError(f"{exc}; {replace}") from None
    points = math.isqrt(spec.points) ** 2 if spec.init == "grid" else spec.points  # as run
    asked = {
        **spec.params.as_dict(derived=False),
        "init": spec.init,
        "points": points,
        "seed": spec.seed,
        "threshold": spec.threshold,
        "threshold_rule": spec.threshold_rule,
        "snapshot_every": args.snapshot_every,
        "transport": bool(getattr(args, "transport", False)),
    }
    given = {
        "snapshot_points": args.snapshot_points,
        "checkpoint_every": args.checkpoint_every,
        "checkpoint_seconds": args.checkpoint_seconds,
        "chunk_steps": spec.chunk_steps,
    }
    asked.update({k: v for k, v in given.items() if v is not None})
    for key, value in asked.items():
        if stored.get(key) != value:
            raise UsageError(
                f"{args.out} holds a different run ({key} is {stored.get(key)!r} in the file, "
                f"{value!r} requested); {replace}"
            )
    if checkpoint > spec.steps:
        raise UsageError(
            f"{args.out} is already at step {checkpoint}, beyond --steps {spec.steps}; "
            f"inspect it with: warpratchet inspect {args.out}"
        )
    return checkpoint


# -- recordings ---------------------------------------------------------------------------------
def add_rerun_flags(p: argparse.ArgumentParser) -> None:
    """The rerun recording options of ``run`` (README, "Watching the cloud")."""
    p.add_argument(
        "--rerun",
        metavar="PATH",
        default=None,
        help="write a rerun recording (.rrd, must not exist) of the phase-space cloud while running; "
        "frames are log-spaced in the step (dense early), within --rerun-max-mb and within 5%% of "
        "the run time",
    )
    p.add_argument(
        "--rerun-spawn",
        action="store_true",
        help="stream the recording to a newly spawned rerun viewer (needs a display; without one: "
        "a warning, and the run goes on)",
    )
    _count_flag(p, "--rerun-points", 1, None, "points drawn per frame, a fixed subsample (default 20000)")
    _count_flag(p, "--rerun-every", 1, None, "frames every STEPS steps instead of log-spaced frames", "STEPS")
    p.add_argument(
        "--rerun-max-mb",
        type=_positive_megabytes,
        default=None,
        metavar="MB",
        help="size budget of the recording: fewer points and frames to stay below it (default 10)",
    )
    p.add_argument(
        "--rerun-color",
        choices=["ftle", "class"],
        default=None,
        help="colour by FTLE (default, log scale) or by class: chaotic / L / R / normal island",
    )


def _positive_megabytes(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r}") from None
    if not (value > 0 and value < 1e6):
        raise argparse.ArgumentTypeError(f"rerun_max_mb = {value} is outside the allowed range 0 < MB < 1e6")
    return value


def rerun_sink(args: argparse.Namespace, spec: RunSpec):
    """The RecordingSink of ``run --rerun/--rerun-spawn`` (None without them); checks flags up front.

    ``--rerun-spawn`` without a display is a one-line warning on stderr, and the run goes on
    (recording to ``--rerun PATH`` if given).
    """
    given = [
        ("--rerun-points", args.rerun_points is not None),
        ("--rerun-every", args.rerun_every is not None),
        ("--rerun-max-mb", args.rerun_max_mb is not None),
        ("--rerun-color", args.rerun_color is not None),
    ]
    if args.rerun is None and not args.rerun_spawn:
        _first_given(given, "--rerun PATH or --rerun-spawn")
        return None
    from ..recording import DEFAULT_MAX_BYTES, DEFAULT_MAX_POINTS, RecordingSink, display_available

    spawn = args.rerun_spawn
    if spawn and not display_available():
        what = f"recording to {args.rerun} only" if args.rerun else "not recording"
        print(
            f"warpratchet: warning: --rerun-spawn needs a display (DISPLAY and WAYLAND_DISPLAY are not set); "
            f"{what}, the run goes on",
            file=sys.stderr,
        )
        if args.rerun is None:
            return None
        spawn = False
    try:
        return RecordingSink(
            args.rerun,
            spawn=spawn,
            max_points=args.rerun_points or DEFAULT_MAX_POINTS,
            every=args.rerun_every,
            max_bytes=int(args.rerun_max_mb * 1e6) if args.rerun_max_mb else DEFAULT_MAX_BYTES,
            color_by=args.rerun_color or "ftle",
            threshold=spec.threshold,
            threshold_rule=spec.threshold_rule,
        )
    except ImportError as exc:  # rerun-sdk is an optional extra
        raise UsageError(str(exc)) from None
