"""The ``warpratchet`` command.

Each subcommand has a ``_add_<name>`` function that declares its arguments and a ``_cmd_<name>``
function that runs it. Bad input (argparse errors, ``ValueError`` from the API, unreadable files)
prints one line on stderr and exits with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from typing import Any, NoReturn

__all__ = ["main", "UsageError", "ProgressBar", "emit_json", "positive_int", "nonnegative_int"]


class UsageError(Exception):
    """Bad input from the user: reported in one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + error
        raise UsageError(f"{self.prog}: {message}")


# -- shared helpers -------------------------------------------------------------------------------
def _clean(value: Any) -> Any:
    """JSON-safe: NaN and infinities become null, NumPy scalars become Python numbers."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def emit_json(obj: dict[str, Any]) -> None:
    """Print one JSON object on stdout (NaN as null)."""
    print(json.dumps(_clean(obj), allow_nan=False))


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (also used by the benchmarks' command lines)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid integer value: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is outside the allowed range >= 1")
    return value


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid integer value: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is outside the allowed range >= 0")
    return value


def _add_map_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--K", type=float, required=True, help="kick strength, 0 < K < 4")
    parser.add_argument("--b1", type=float, required=True, help="left strip width, b1 > 0")
    parser.add_argument("--b2", type=float, required=True, help="right strip width, b2 > 0, b1 + b2 < 1")


class ProgressBar:
    """An :class:`~warpratchet.ensemble.Observer` drawing a tqdm bar over steps on stderr."""

    def __init__(self, description: str = "steps", disable: bool = False) -> None:
        self.description = description
        self.disable = disable
        self._bar = None

    def begin(self, ensemble, target_step: int) -> None:
        from tqdm import tqdm

        self._first_step = ensemble.step
        self._bar = tqdm(
            total=target_step,
            initial=ensemble.step,
            desc=self.description,
            unit="step",
            unit_scale=True,
            file=sys.stderr,
            # None: tqdm draws only on a terminal, so logs and pipes stay clean.
            disable=True if self.disable else None,
            dynamic_ncols=True,
        )

    def after_chunk(self, ensemble, seconds: float) -> None:
        if self._bar is not None and not self._bar.disable:
            self._bar.update(ensemble.step - self._bar.n)
            elapsed = max(self._bar.format_dict["elapsed"], 1e-9)
            rate = ensemble.points * (ensemble.step - self._first_step) / elapsed
            self._bar.set_postfix_str(f"{rate / 1e6:.0f} M point-steps/s", refresh=False)

    def end(self, ensemble) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


# -- theory ---------------------------------------------------------------------------------------
def _add_theory(sub) -> None:
    p = sub.add_parser("theory", help="closed forms of the paper at (K, b1, b2)")
    _add_map_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _cmd_theory(args) -> int:
    from . import theory
    from .params import MapParams

    summary = theory.summary(MapParams(args.K, args.b1, args.b2))
    if args.json:
        emit_json(summary)
    else:
        for key, value in summary.items():
            print(f"{key:>7} = {'n/a' if value is None else value}")
    return 0


# -- run ------------------------------------------------------------------------------------------
def _add_run(sub) -> None:
    p = sub.add_parser("run", help="iterate an ensemble and report A and the Lyapunov exponent")
    _add_map_args(p)
    p.add_argument("--points", type=positive_int, default=10_000, help="ensemble size (default 10000)")
    p.add_argument("--steps", type=positive_int, default=120_000, help="iterations (default 120000)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="NumPy seed (default 0)")
    p.add_argument(
        "--init",
        choices=["strip", "torus", "grid"],
        default="strip",
        help="initial conditions: the strip B of Eq. (B) (default), the torus, or a grid",
    )
    p.add_argument("--threads", type=positive_int, default=None, help="CPU threads (default: one per core)")
    p.add_argument("--device", default="cpu", help="Warp device, e.g. cpu or cuda:0 (default cpu)")
    p.add_argument(
        "--chunk-steps",
        type=positive_int,
        default=None,
        help="steps between observer calls (default: ~2.5e8 point-steps)",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="FTLE above which a point counts as chaotic (default 10 (1 + ln n)/n)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_archive_args(p)
    _add_rerun_args(p)


def run_report(ensemble, seconds: float, steps_run: int, threshold: float | None) -> dict[str, Any]:
    """The JSON object of ``run`` and ``resume``: parameters, A, FTLE statistics, speed."""
    from . import theory
    from .observables import summarize

    s = summarize(ensemble.state(), ensemble.step, threshold)
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
        "A": s.A,
        "A_stderr": s.A_stderr,
        "A_theory": theory.summary(p)["A"],
        "lyapunov": s.lyapunov,
        "lyapunov_std": s.lyapunov_std,
        "lyapunov_min": s.lyapunov_min,
        "chaotic_fraction": s.chaotic_fraction,
        "chaotic_points": s.chaotic_points,
        "threshold": s.threshold,
        "seconds": seconds,
        "point_steps_per_second": ensemble.points * steps_run / seconds if seconds > 0 else None,
    }


def print_report(report: dict[str, Any], as_json: bool) -> None:
    if as_json:
        emit_json(report)
        return
    a_theory = report["A_theory"]
    print(
        f"K = {report['K']}, b1 = {report['b1']}, b2 = {report['b2']}: "
        f"{report['points']} points x {report['steps']} steps ({report['init']}, seed {report['seed']})"
    )
    print(
        f"  A           = {report['A']:.6g} +- {report['A_stderr']:.2g}"
        + ("" if a_theory is None else f"   (theory {a_theory:.6g})")
    )
    print(
        f"  lyapunov    = {report['lyapunov']:.6g} (min {report['lyapunov_min']:.4g}) over "
        f"{report['chaotic_fraction']:.4f} of the points"
    )
    if report["point_steps_per_second"]:
        print(f"  {report['seconds']:.2f} s, {report['point_steps_per_second'] / 1e6:.0f} M point-steps/s")


def _cmd_run(args) -> int:
    from .ensemble import Ensemble
    from .params import MapParams

    params = MapParams(args.K, args.b1, args.b2)
    archive_plan = _archive_plan(args)  # bad archive flags fail before any work
    recorder = _rerun_sink(args)  # so do bad recording flags
    ensemble = Ensemble.sample(
        params, args.points, args.init, args.seed, device=args.device, threads=args.threads
    )
    observers = [ProgressBar(disable=args.quiet)]
    chunk_steps = args.chunk_steps
    sink = None
    if archive_plan is not None:
        from .archive import ArchiveSink

        sink = ArchiveSink(args.out, ensemble, **archive_plan)
        observers.append(sink)
        chunk_steps = sink.chunk_steps
    if recorder is not None:
        observers.append(recorder)
        chunk_steps = chunk_steps or recorder.every  # frames at exact multiples of --rerun-every
    start = time.perf_counter()
    try:
        ensemble.run(args.steps, observers, chunk_steps=chunk_steps)
    finally:
        if sink is not None:
            sink.close()
    seconds = time.perf_counter() - start
    report = run_report(ensemble, seconds, args.steps, args.threshold)
    if sink is not None:
        report["archive"] = args.out
    if recorder is not None and args.rerun is not None:
        report["recording"] = args.rerun
    print_report(report, args.json)
    return 0


# -- sweep ----------------------------------------------------------------------------------------
#: What each kind of sweep reads besides --K: the flags it needs (any other is an error).
_SWEEP_NEEDS = {
    "maximal": ("b2",),
    "line": ("a", "b2"),
    "fixed-b1": ("b1", "b2"),
    "k": ("Ks", "b1", "b2"),
    "grid": (),
}


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="one ensemble per parameter point; rows to an HDF5 sweep file")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--path",
        choices=[name for name in _SWEEP_NEEDS if name != "grid"],
        help="maximal: Eq. (b2max) over --b2; line: b1 = b2/a (Eq. Ama) over --b2; "
        "fixed-b1: --b1 with --b2 varying (Fig. 9); k: --Ks at fixed --b1, --b2",
    )
    where.add_argument(
        "--grid",
        metavar="b1=START:STOP:COUNT,b2=START:STOP:COUNT",
        help="every (b1, b2) pair of two ranges (pairs with b1 + b2 >= 1 are skipped)",
    )
    p.add_argument(
        "--K", type=float, default=None, help="kick strength, 0 < K < 4 (default 3; not with --path k)"
    )
    p.add_argument("--Ks", metavar="START:STOP:COUNT", help="K range of --path k")
    p.add_argument("--b1", type=float, default=None, help="fixed b1 of --path fixed-b1 and --path k")
    p.add_argument(
        "--b2",
        metavar="START:STOP:COUNT",
        help="b2 range (a single value for --path k); ranges include both ends",
    )
    p.add_argument("--a", type=float, default=None, help="slope of --path line: b1 = b2 / a")
    p.add_argument(
        "--domain",
        metavar="NAMES",
        help="with --grid: keep points in these domains of Fig. 3, e.g. LR or LR,R",
    )
    p.add_argument(
        "--points", type=positive_int, default=10_000, help="ensemble size per point (default 10000)"
    )
    p.add_argument(
        "--steps", type=positive_int, default=120_000, help="iterations per point (default 120000)"
    )
    p.add_argument(
        "--seed",
        type=nonnegative_int,
        default=0,
        help="root seed; point i uses child i of numpy SeedSequence(seed) (default 0)",
    )
    p.add_argument(
        "--init",
        choices=["strip", "torus", "grid"],
        default="strip",
        help="initial conditions: the strip B of Eq. (B) (default), the torus, or a grid",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="FTLE above which a point counts as chaotic (default 10 (1 + ln n)/n)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="sweep file (HDF5); if it holds this same sweep, only missing points are run",
    )
    p.add_argument("--force", action="store_true", help="replace --out if it holds anything else")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on a Dask cluster, e.g. tcp://host:8786 (default: here, every core per point)",
    )
    p.add_argument(
        "--threads",
        type=positive_int,
        default=None,
        help="CPU threads per point (default: every core here; 1 per Dask worker thread)",
    )
    p.add_argument("--json", action="store_true", help='print {"rows": [...]} on stdout')
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _parse_range(flag: str, text: str) -> list[float]:
    """``START:STOP:COUNT`` (COUNT values, both ends included) or one number."""
    parts = text.split(":")
    try:
        if len(parts) == 1:
            start = stop = float(parts[0])
            count = 1
        elif len(parts) == 3:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        else:
            raise ValueError
    except ValueError:
        raise UsageError(
            f"{flag} {text!r} is not START:STOP:COUNT (both ends included) or a number"
        ) from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise UsageError(f"{flag} {text!r}: START and STOP must be finite numbers")
    if count < 1:
        raise UsageError(f"{flag} {text!r}: COUNT = {count} is outside the allowed range COUNT >= 1")
    if count == 1 and start != stop:
        raise UsageError(f"{flag} {text!r}: COUNT = 1 cannot include both ends of a range; use COUNT >= 2")
    import numpy as np

    return np.linspace(start, stop, count).tolist()


def _parse_value(flag: str, text: str) -> float:
    values = _parse_range(flag, text)
    if len(values) != 1:
        raise UsageError(f"{flag} {text!r}: this sweep needs a single value, not a range")
    return values[0]


def _parse_grid(text: str) -> dict[str, list[float]]:
    axes = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        if not sep or name.strip() not in ("b1", "b2") or name.strip() in axes:
            raise UsageError(f"--grid {text!r} is not b1=START:STOP:COUNT,b2=START:STOP:COUNT")
        axes[name.strip()] = _parse_range(f"--grid {name.strip()}", value.strip())
    if set(axes) != {"b1", "b2"}:
        raise UsageError(f"--grid {text!r} needs both b1=START:STOP:COUNT and b2=START:STOP:COUNT")
    return axes


def _sweep_points(args) -> list:
    from . import sweep

    kind = "grid" if args.grid is not None else args.path
    needs = _SWEEP_NEEDS[kind]
    what = "--grid" if kind == "grid" else f"--path {kind}"
    for name in ("Ks", "b1", "b2", "a", "domain", "K"):
        given = getattr(args, name) is not None
        used = name in needs or (name == "domain" and kind == "grid") or (name == "K" and kind != "k")
        if name in needs and not given:
            raise UsageError(f"{what} needs --{name}")
        if given and not used:
            raise UsageError(f"--{name} is not used by {what}")
    K = 3.0 if args.K is None else args.K
    if kind == "maximal":
        return sweep.maximal_path(_parse_range("--b2", args.b2), K=K)
    if kind == "line":
        return sweep.line_path(args.a, _parse_range("--b2", args.b2), K=K)
    if kind == "fixed-b1":
        return sweep.fixed_b1_path(args.b1, _parse_range("--b2", args.b2), K)
    if kind == "k":
        return sweep.k_path(_parse_range("--Ks", args.Ks), args.b1, _parse_value("--b2", args.b2))
    axes = _parse_grid(args.grid)
    domain = None if args.domain is None else [name.strip() for name in args.domain.split(",")]
    points = sweep.grid_points(axes["b1"], axes["b2"], K=K, domain=domain)
    if not points:
        raise UsageError(
            f"--grid {args.grid!r} has no point with b1 + b2 < 1"
            + ("" if domain is None else f" in domain {args.domain}")
        )
    return points


def _cmd_sweep(args) -> int:
    from . import sweep

    points = _sweep_points(args)
    spec = sweep.SweepSpec(
        points=args.points, steps=args.steps, init=args.init, seed=args.seed, threshold=args.threshold
    )
    computed = []
    try:
        rows = sweep.run_sweep(
            points,
            spec,
            out=args.out,
            client=args.scheduler,
            progress=not args.quiet,
            threads=args.threads,
            force=args.force,
            on_row=computed.append,
        )
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    if args.json:
        emit_json({"rows": rows})
        return 0
    print(
        f"{'K':>6} {'b1':>10} {'b2':>10} {'domain':>6} {'A':>11} {'+-':>8} {'A_theory':>11} "
        f"{'lyapunov':>9} {'chaotic':>7} {'seconds':>8}"
    )
    for r in rows:
        a_theory = "n/a" if math.isnan(r["A_theory"]) else f"{r['A_theory']:.5g}"
        print(
            f"{r['K']:>6.4g} {r['b1']:>10.4g} {r['b2']:>10.4g} {r['domain']:>6} {r['A']:>11.5g} "
            f"{r['A_stderr']:>8.2g} {a_theory:>11} {r['lyapunov']:>9.4g} {r['chaotic_fraction']:>7.4f} "
            f"{r['seconds']:>8.2f}"
        )
    source = f", {len(rows) - len(computed)} read from {args.out}" if args.out is not None else ""
    print(f"{len(rows)} points: {len(computed)} computed{source}")
    return 0


# -- archives (run --out, resume, inspect) --------------------------------------------------------
def _add_archive_args(p: argparse.ArgumentParser) -> None:
    """The archive options of ``run`` (docs/archive.md)."""
    p.add_argument("--out", default=None, help="stream the run into this HDF5 archive (resumable)")
    p.add_argument("--force", action="store_true", help="with --out: replace an existing file")
    p.add_argument(
        "--snapshot-every",
        type=nonnegative_int,
        default=0,
        help="with --out: steps between x, p snapshots of a fixed subsample (default 0: none)",
    )
    p.add_argument(
        "--snapshot-points",
        type=positive_int,
        default=None,
        help="with --out: points in the snapshot subsample (default 1000)",
    )
    p.add_argument(
        "--checkpoint-every",
        type=positive_int,
        default=None,
        help="with --out: steps between full checkpoints (default 8 chunks)",
    )


def _archive_plan(args) -> dict[str, Any] | None:
    """ArchiveSink keywords from the run flags (None without --out); checks them up front."""
    import os

    from .archive import schedule

    if args.out is None:
        given = [
            flag
            for flag, value in (
                ("--force", args.force),
                ("--snapshot-every", args.snapshot_every),
                ("--snapshot-points", args.snapshot_points),
                ("--checkpoint-every", args.checkpoint_every),
            )
            if value
        ]
        if given:
            raise UsageError(f"{given[0]} needs --out FILE")
        return None
    if os.path.lexists(args.out) and not args.force:
        raise UsageError(f"{args.out} exists; refusing to overwrite it (pass --force to replace it)")
    schedule(args.points, args.chunk_steps, args.snapshot_every, args.checkpoint_every)  # ValueError if bad
    return {
        "force": args.force,
        "snapshot_every": args.snapshot_every,
        "snapshot_points": 1000 if args.snapshot_points is None else args.snapshot_points,
        "checkpoint_every": args.checkpoint_every,
        "chunk_steps": args.chunk_steps,
        "threshold": args.threshold,
    }


def _add_resume(sub) -> None:
    p = sub.add_parser("resume", help="continue an archived run (run --out) to a total number of steps")
    p.add_argument("archive", help="HDF5 archive written by run --out")
    p.add_argument(
        "--steps",
        type=positive_int,
        required=True,
        help="total iterations to reach (beyond the archive's checkpoint)",
    )
    p.add_argument("--K", type=float, default=None, help="optional: must equal the archive's K")
    p.add_argument("--b1", type=float, default=None, help="optional: must equal the archive's b1")
    p.add_argument("--b2", type=float, default=None, help="optional: must equal the archive's b2")
    p.add_argument("--points", type=positive_int, default=None, help="optional: must equal the archive's")
    p.add_argument("--seed", type=nonnegative_int, default=None, help="optional: must equal the archive's")
    p.add_argument(
        "--init", choices=["strip", "torus", "grid"], default=None, help="optional: must equal the archive's"
    )
    p.add_argument("--threads", type=positive_int, default=None, help="CPU threads (default: one per core)")
    p.add_argument("--device", default="cpu", help="Warp device, e.g. cpu or cuda:0 (default cpu)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _print_archive_warnings(caught) -> None:
    for w in caught:
        print(f"warpratchet: warning: {w.message}", file=sys.stderr)


def _cmd_resume(args) -> int:
    import warnings

    from .archive import ArchiveSink, ArchiveWarning, open_archive, run_to

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(args.archive) as arc:
            archived = {
                **arc.params.as_dict(),
                "points": arc.points,
                "seed": arc.settings["seed"],
                "init": arc.settings["sampler"],
            }
            start_step = arc.checkpoint_step
        for key in ("K", "b1", "b2", "points", "seed", "init"):
            asked = getattr(args, key)
            if asked is not None and asked != archived[key]:
                raise UsageError(
                    f"--{key} {asked} disagrees with the archive's {key} = {archived[key]} in {args.archive}"
                )
        if args.steps <= start_step:
            raise UsageError(
                f"--steps {args.steps} is not beyond the archive's checkpoint at step "
                f"{start_step}; pass a total above {start_step}"
            )
        sink, ensemble = ArchiveSink.resume(args.archive, threads=args.threads, device=args.device)
    _print_archive_warnings(caught)
    first = ensemble.step
    start = time.perf_counter()
    try:
        run_to(ensemble, args.steps, [ProgressBar(disable=args.quiet), sink], sink.chunk_steps)
    finally:
        sink.close()
    seconds = time.perf_counter() - start
    report = run_report(ensemble, seconds, args.steps - first, sink.threshold)
    report["archive"] = args.archive
    print_report(report, args.json)
    return 0


def _add_inspect(sub) -> None:
    p = sub.add_parser("inspect", help="parameters, progress and latest summary of an archive")
    p.add_argument("archive", help="HDF5 archive written by run --out")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _cmd_inspect(args) -> int:
    import warnings

    from . import theory
    from .archive import ArchiveWarning, open_archive

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(args.archive) as arc:
            info = arc.info()
            info["A_theory"] = theory.summary(arc.params)["A"]
    _print_archive_warnings(caught)
    if args.json:
        emit_json(info)
        return 0
    p, s, v, last = info["params"], info["settings"], info["versions"], info["latest"]
    print(f"{info['path']}: {info['format']} v{info['format_version']}, created {info['created']}")
    print(
        f"  K = {p['K']}, b1 = {p['b1']}, b2 = {p['b2']}  (l1 = {p['l1']:.6g}, l2 = {p['l2']:.6g}, "
        f"c = {p['c']:.6g})"
    )
    snaps = (
        f"snapshots of {s['snapshot_points']} points every {s['snapshot_every']} steps"
        if s["snapshot_every"]
        else "no snapshots"
    )
    print(
        f"  {s['points']} points ({s['sampler']}, seed {s['seed']}), chunks of {s['chunk_steps']} steps, "
        f"checkpoint every {s['checkpoint_every']}, {snaps}"
    )
    print(
        f"  progress: checkpoint at step {info['checkpoint_step']}, {info['rows']} series rows, "
        f"{info['snapshots']} snapshots"
    )
    if last is None:
        print("  latest: no chunk recorded yet")
    else:
        a_theory = "" if info["A_theory"] is None else f"   (theory {info['A_theory']:.6g})"
        print(
            f"  latest (step {last['step']}): A = {last['A']:.6g} +- {last['A_stderr']:.2g}{a_theory}, "
            f"lyapunov = {last['lyapunov']:.6g} over {last['chaotic_fraction']:.4f} of the points"
        )
    print("  written by " + ", ".join(f"{k} {val}" for k, val in v.items()))
    return 0


# -- sumrule --------------------------------------------------------------------------------------
def _add_sumrule(sub) -> None:
    p = sub.add_parser("sumrule", help="island census of the torus and the sum rule, Eq. (sum), for any K")
    _add_map_args(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--points",
        type=positive_int,
        default=None,
        help="random points uniform on the torus (default 100000)",
    )
    where.add_argument(
        "--grid",
        type=positive_int,
        default=None,
        help="a G x G lattice off the kinks instead of random points",
    )
    p.add_argument(
        "--steps",
        type=positive_int,
        default=30_000,
        help="iterations per point (default 30000; at least 8 m_max^3)",
    )
    p.add_argument(
        "--m-max",
        type=positive_int,
        default=12,
        help="largest period m of an island's nu = w/m (default 12)",
    )
    p.add_argument(
        "--classifier",
        choices=["ftle", "megno", "fli"],
        default="ftle",
        help="chaos indicator (default ftle)",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="indicator value above which a point is chaotic (default: per indicator)",
    )
    p.add_argument("--seed", type=nonnegative_int, default=0, help="NumPy seed for --points (default 0)")
    p.add_argument("--threads", type=positive_int, default=None, help="CPU threads (default: one per core)")
    p.add_argument("--device", default="cpu", help="Warp device, e.g. cpu or cuda:0 (default cpu)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _cmd_sumrule(args) -> int:
    from .params import MapParams
    from .sumrule import census

    params = MapParams(args.K, args.b1, args.b2)
    points = 100_000 if args.points is None and args.grid is None else args.points
    result = census(
        params,
        args.steps,
        points=points,
        grid=args.grid,
        seed=args.seed,
        m_max=args.m_max,
        classifier=args.classifier,
        threshold=args.threshold,
        threads=args.threads,
        device=args.device,
        observers=[ProgressBar(disable=args.quiet)],
    )
    out = result.as_dict()
    if args.json:
        emit_json(out)
        return 0
    err = "+-" if result.error_kind == "stderr" else "bound"
    print(
        f"K = {result.K}, b1 = {result.b1}, b2 = {result.b2}: {result.points} points ({result.sampling}) "
        f"x {result.steps} steps, classifier {result.classifier}"
    )
    print(f"  {'nu':>8} {'w':>4} {'m':>3} {'area':>10}  {err:>9}  chaotic")
    print(f"  {'C':>8} {'':>4} {'':>3} {result.S_C:10.6f}  {result.S_C_stderr:9.2g}")
    for item in result.islands:
        print(
            f"  {item.nu:8.4f} {item.w:4d} {item.m:3d} {item.area:10.6f}  {item.area_stderr:9.2g}  "
            f"{item.chaotic_fraction:.3f}"
        )
    if result.unidentified_area:
        print(
            f"  {'?':>8} {'':>4} {'':>3} {result.unidentified_area:10.6f}  "
            f"{result.unidentified_area_stderr:9.2g}  (regular, no nu with m <= {result.m_max})"
        )
    for key in ("A_sumrule", "A_direct", "A_force", "torus_mean_A"):
        spread = out.get(f"{key}_stderr")
        label = err if key == "A_sumrule" else "+-"  # means over points always carry a standard error
        print(f"  {key:<12} = {out[key]:.6g}" + ("" if spread is None else f" {label} {spread:.2g}"))
    if result.theory is not None:
        t = result.theory
        print(
            "  theory (K = 3): "
            + ", ".join(
                f"{k} = {'n/a' if t[k] is None else f'{t[k]:.6g}'}" for k in ("S_C", "S_L", "S_R", "A")
            )
        )
    print(f"  {result.seconds:.1f} s")
    return 0


# -- recordings (run --rerun) --------------------------------------------------------------------
def _add_rerun_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--rerun",
        metavar="PATH",
        default=None,
        help="write a rerun recording (.rrd, must not exist) of the phase-space cloud while running",
    )
    p.add_argument(
        "--rerun-spawn",
        action="store_true",
        help="stream the recording to a newly spawned rerun viewer (needs a display)",
    )
    p.add_argument(
        "--rerun-points",
        type=positive_int,
        default=None,
        help="points drawn per frame, a fixed subsample (default 100000)",
    )
    p.add_argument(
        "--rerun-every",
        type=positive_int,
        default=None,
        help="steps between frames (default: recording costs < 5%% of the run, at most 100 frames)",
    )
    p.add_argument(
        "--rerun-color",
        choices=["ftle", "class"],
        default=None,
        help="colour by FTLE (default, log scale) or by class: chaotic / L / R / normal island",
    )


def _rerun_sink(args):
    """The RecordingSink of ``run --rerun/--rerun-spawn`` (None without them); checks flags up front."""
    if args.rerun is None and not args.rerun_spawn:
        given = [
            flag
            for flag, value in (
                ("--rerun-points", args.rerun_points),
                ("--rerun-every", args.rerun_every),
                ("--rerun-color", args.rerun_color),
            )
            if value is not None
        ]
        if given:
            raise UsageError(f"{given[0]} needs --rerun PATH or --rerun-spawn")
        return None
    from .recording import DEFAULT_MAX_POINTS, RecordingSink, frame_every

    max_points = args.rerun_points or DEFAULT_MAX_POINTS
    try:
        return RecordingSink(
            args.rerun,
            spawn=args.rerun_spawn,
            max_points=max_points,
            every=args.rerun_every or frame_every(args.points, args.steps, max_points),
            color_by=args.rerun_color or "ftle",
            threshold=args.threshold,
        )
    except ImportError as exc:  # rerun-sdk is an optional extra
        raise UsageError(str(exc)) from None


# -- entry point ----------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="warpratchet", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_theory(sub)
    _add_run(sub)
    _add_resume(sub)
    _add_inspect(sub)
    _add_sweep(sub)
    _add_sumrule(sub)
    return parser


_COMMANDS = {
    "theory": _cmd_theory,
    "run": _cmd_run,
    "resume": _cmd_resume,
    "inspect": _cmd_inspect,
    "sweep": _cmd_sweep,
    "sumrule": _cmd_sumrule,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    try:
        args = build_parser().parse_args(argv)
        return _COMMANDS[args.command](args)
    except UsageError as exc:
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as exc:
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("warpratchet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
