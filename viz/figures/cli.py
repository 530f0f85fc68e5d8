"""``python -m viz figures``: which figures to draw, where, and how much numerics they get."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from ..command import command_name, run
from .acceleration import fig7, fig8, fig9
from .canvas import Context, pyplot
from .phase import fig1, fig2, fig4
from .plane import fig3, fig5, fig6
from .regions import fig10, fig11, fig12
from .sweeps import settings_for

__all__ = ["FIGURES", "main"]

#: Figure name -> function drawing it.
FIGURES: dict[str, Callable[[Context], None]] = {
    "fig1": fig1,
    "fig2": fig2,
    "fig3": fig3,
    "fig4": fig4,
    "fig5": fig5,
    "fig6": fig6,
    "fig7": fig7,
    "fig8": fig8,
    "fig9": fig9,
    "fig10": fig10,
    "fig11": fig11,
    "fig12": fig12,
}


def _build_parser(prog: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Regenerate the paper's figures (PNG and PDF) from warpratchet's own computations.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        f"  {prog} --all --out figures/                 (the paper's settings; README gives the time)\n"
        f"  {prog} --only fig7,fig8 --out figures/ --formats png\n"
        f"  {prog} --all --quick --out quick/           (small ensembles, what the tests run)",
    )
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--all", action="store_true", help="every figure, fig1 ... fig12")
    which.add_argument("--only", metavar="LIST", help="comma-separated figure names, e.g. fig7,fig8")
    parser.add_argument("--out", required=True, type=Path, help="output directory")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="small ensembles and few sweep points instead of the "
        "paper's settings (10^4 orbits x 120000 steps)",
    )
    parser.add_argument("--sweeps", type=Path, help="sweep files to reuse or create (default: OUT/sweeps)")
    parser.add_argument("--formats", default="png,pdf", help="comma-separated, from png,pdf (default both)")
    parser.add_argument("--dpi", type=int, default=150, help="PNG resolution (default 150)")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS", help="run sweeps on a Dask cluster, e.g. tcp://host:8786"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace figure files that already exist")
    parser.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    return parser


def _selected(args: argparse.Namespace) -> list[str]:
    if args.all:
        return list(FIGURES)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    bad = [n for n in names if n not in FIGURES]
    if bad or not names:
        raise ValueError(
            f"--only {args.only!r}: unknown figure {', '.join(bad) or '(none)'}; "
            f"allowed: {', '.join(FIGURES)}"
        )
    return names


def _draw(args: argparse.Namespace) -> int:
    names = _selected(args)
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    if not formats or any(f not in ("png", "pdf") for f in formats):
        raise ValueError(f"--formats {args.formats!r}: allowed formats are png, pdf")
    if not 20 <= args.dpi <= 1200:
        raise ValueError(f"--dpi {args.dpi}: outside the allowed range 20-1200")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {args.out}: exists and is not a directory")
    if args.sweeps is not None and args.sweeps.exists() and not args.sweeps.is_dir():
        raise ValueError(f"--sweeps {args.sweeps}: exists and is not a directory")
    existing = [args.out / f"{n}.{f}" for n in names for f in formats if (args.out / f"{n}.{f}").exists()]
    if existing and not args.overwrite:
        raise ValueError(
            f"{existing[0]} already exists ({len(existing)} figure files would be replaced); "
            "pass --overwrite or choose another --out"
        )
    plt = pyplot()
    args.out.mkdir(parents=True, exist_ok=True)
    ctx = Context(
        plt=plt,
        settings=settings_for(args.quick),
        out=args.out,
        sweeps=args.sweeps if args.sweeps is not None else args.out / "sweeps",
        formats=formats,
        dpi=args.dpi,
        progress=not args.quiet,
        client=args.scheduler,
    )
    for name in names:
        start = time.perf_counter()
        FIGURES[name](ctx)
        if not args.quiet:
            print(f"{name}: {time.perf_counter() - start:.1f} s", file=sys.stderr)
    if not args.quiet:
        print("\n".join(str(p) for p in ctx.written))
    return 0


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Draw the figures named on the command line; returns the exit status.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after the command name (default ``sys.argv[1:]``).
    prog : str, optional
        The command as the user types it, for help and messages (default ``python -m viz
        figures``; the ``warpratchet figures`` subcommand passes its own).

    Returns
    -------
    int
        0 on success, 2 on bad input (one line on stderr), 130 after Ctrl-C (finished sweep
        points stay in their files and the next run reuses them).
    """
    parser = _build_parser(command_name("figures") if prog is None else prog)
    kept = "finished sweep points are kept in the sweep files and reused by the next run"
    return run(parser, argv, _draw, interrupted=kept)
