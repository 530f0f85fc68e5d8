"""``python -m viz <command> ...``: the ``main`` of viz.figures, scenes, record, report or history."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from .command import PACKAGE, run

#: Command -> what it does; each is the module of that name with a ``main(argv)``.
COMMANDS = {
    "figures": "regenerate the paper's figures (PNG and PDF)",
    "scenes": "record the paper's phase-space scenes (Figs. 1, 2, 4) as .rrd",
    "record": "replay an archive's snapshots into a rerun .rrd",
    "report": "write docs/validation.md from the sweep files of the figures",
    "history": "plot a run's history (A_n and sigma_n against n) from its archive",
    "transport": "return-time and flight distributions of a --transport run; periodic orbits on the torus",
}


def _parser(prog: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        usage=f"{prog} [-h] COMMAND ...",
        description="Pictures built on the warpratchet API: the paper's figures, rerun recordings "
        "and the validation report.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="commands:\n"
        + "\n".join(f"  {name:9s} {text}" for name, text in COMMANDS.items())
        + f"\n\n'{prog} COMMAND --help' describes a command's options, e.g.\n"
        f"  {prog} figures --all --quick --out figures/",
    )
    # Optional only so that a missing COMMAND gets its own message (see dispatch in main).
    parser.add_argument(
        "command", nargs="?", choices=list(COMMANDS), metavar="COMMAND", help=", ".join(COMMANDS)
    )
    parser.add_argument(
        "arguments", nargs=argparse.REMAINDER, metavar="...", help="the command's own options"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns its exit status (0 after ``--help``, 2 on bad input, 130 after Ctrl-C)."""
    parser = _parser(f"python -m {PACKAGE}")

    def dispatch(args: argparse.Namespace) -> int:
        if args.command is None:
            parser.error(f"a COMMAND is required, one of {', '.join(COMMANDS)}")
        # Imported on demand: figures need matplotlib, scenes and record rerun.
        return importlib.import_module(f".{args.command}", __package__).main(args.arguments)

    return run(parser, argv, dispatch)


if __name__ == "__main__":
    sys.exit(main())
