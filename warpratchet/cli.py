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

__all__ = ["main", "UsageError", "ProgressBar", "emit_json"]


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


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid integer value: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is outside the allowed range >= 1")
    return value


def _nonnegative_int(text: str) -> int:
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
            disable=self.disable,
            dynamic_ncols=True,
        )

    def after_chunk(self, ensemble, seconds: float) -> None:
        if self._bar is not None and not self.disable:
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
    p.add_argument("--points", type=_positive_int, default=10_000, help="ensemble size (default 10000)")
    p.add_argument("--steps", type=_positive_int, default=120_000, help="iterations (default 120000)")
    p.add_argument("--seed", type=_nonnegative_int, default=0, help="NumPy seed (default 0)")
    p.add_argument("--init", choices=["strip", "torus", "grid"], default="strip",
                   help="initial conditions: the strip B of Eq. (B) (default), the torus, or a grid")
    p.add_argument("--threads", type=_positive_int, default=None, help="CPU threads (default: one per core)")
    p.add_argument("--device", default="cpu", help="Warp device, e.g. cpu or cuda:0 (default cpu)")
    p.add_argument("--chunk-steps", type=_positive_int, default=None,
                   help="steps between observer calls (default: ~2.5e8 point-steps)")
    p.add_argument("--threshold", type=float, default=None,
                   help="FTLE above which a point counts as chaotic (default 10 (1 + ln n)/n)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


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
    print(f"K = {report['K']}, b1 = {report['b1']}, b2 = {report['b2']}: "
          f"{report['points']} points x {report['steps']} steps ({report['init']}, seed {report['seed']})")
    print(f"  A           = {report['A']:.6g} +- {report['A_stderr']:.2g}"
          + ("" if a_theory is None else f"   (theory {a_theory:.6g})"))
    print(f"  lyapunov    = {report['lyapunov']:.6g} (min {report['lyapunov_min']:.4g}) over "
          f"{report['chaotic_fraction']:.4f} of the points")
    if report["point_steps_per_second"]:
        print(f"  {report['seconds']:.2f} s, {report['point_steps_per_second'] / 1e6:.0f} M point-steps/s")


def _cmd_run(args) -> int:
    from .ensemble import Ensemble
    from .params import MapParams

    params = MapParams(args.K, args.b1, args.b2)
    ensemble = Ensemble.sample(params, args.points, args.init, args.seed, device=args.device,
                               threads=args.threads)
    observers = [ProgressBar(disable=args.quiet)]
    start = time.perf_counter()
    ensemble.run(args.steps, observers, chunk_steps=args.chunk_steps)
    seconds = time.perf_counter() - start
    print_report(run_report(ensemble, seconds, args.steps, args.threshold), args.json)
    return 0


# -- entry point ----------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="warpratchet", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_theory(sub)
    _add_run(sub)
    return parser


_COMMANDS = {
    "theory": _cmd_theory,
    "run": _cmd_run,
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
