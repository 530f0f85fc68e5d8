"""The ``warpratchet`` command.

One module per subcommand (:mod:`.theory`, :mod:`.run`, :mod:`.resume`, :mod:`.inspect`,
:mod:`.sweep`, :mod:`.sumrule`, :mod:`.orbits`, :mod:`.verify`, :mod:`.figures`), each with
``add(subparsers)`` declaring its flags and ``command(args)`` running it; :mod:`.common` holds what
they share (the one-line error, JSON output, flags built from :class:`~warpratchet.spec.RunSpec`),
:mod:`.sinks` the output options of ``run``. Bad input prints one line on stderr naming the value
and its range and exits with status 2, never a traceback (a flag refused while parsing: a short
usage line first, then ``warpratchet run: error: ...``; a ``ValueError`` from the API or an
unreadable file while a command runs: ``warpratchet: error: ...`` alone); a write the system refuses
(disk full, read-only, permissions: :class:`warpratchet.StorageError`) one line and status 1,
as does a launch the code refuses to vouch for (:class:`warpratchet.errors.KernelError`);
Ctrl-C prints one line (where it stopped, what was kept: :class:`.common.Interrupted`) and exits
with 130 (128 + SIGINT); SIGTERM, a scheduler's stop, the same line with ``terminated`` and 143
(128 + SIGTERM).

A new subcommand is a new module with ``add`` and ``command``, listed in :data:`SUBCOMMANDS`,
with its examples in :data:`EXAMPLES`.
"""

from __future__ import annotations

import argparse
import gc
import os
import re
import sys
from collections.abc import Sequence

from . import figures, inspect, orbits, resume, run, sumrule, sweep, theory, verify
from .common import (
    Interrupted,
    Parser,
    ProgressBar,
    UsageError,
    emit_json,
    nonnegative_int,
    positive_int,
)

__all__ = [
    "main",
    "console_main",
    "build_parser",
    "UsageError",
    "Interrupted",
    "ProgressBar",
    "emit_json",
    "positive_int",
    "nonnegative_int",
]

#: Subcommands in the order ``--help`` lists them: name -> module with ``add`` and ``command``.
SUBCOMMANDS = {
    "theory": theory,
    "run": run,
    "resume": resume,
    "inspect": inspect,
    "verify": verify,
    "sweep": sweep,
    "sumrule": sumrule,
    "orbits": orbits,
    "figures": figures,
}

DESCRIPTION = """\
Ensembles of the weak-chaos ratchet accelerator of Dana & Roitberg: the kicked rotor
p' = p + K f(x), x' = x + p' (mod 1) with the piecewise-linear force of strip widths b1, b2.
Computes the ratchet acceleration A with its standard error next to the paper's closed forms,
Lyapunov exponents, island censuses and parameter sweeps; archives runs (resumable bit for bit)
and records them for the rerun viewer."""

#: Examples shown at the end of each subcommand's ``--help`` (and the top-level one).
EXAMPLES = {
    "warpratchet": [
        "warpratchet theory --K 3 --b1 0.1 --b2 0.01",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --points 10000 --steps 120000",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --out run.h5 && warpratchet inspect run.h5",
        "warpratchet sweep --path maximal --b2 0.005:0.165:33 --out fig7.h5",
        "warpratchet COMMAND --help      (the options of one command)",
    ],
    "theory": ["warpratchet theory --K 3 --b1 0.1 --b2 0.01 --json"],
    "run": [
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --points 10000 --steps 120000",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --json --quiet",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --points 10000 --steps 120000 --transport",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --out run.h5 --snapshot-every 10000",
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --steps 20000 --rerun run.rrd   (then: rerun run.rrd)",
    ],
    "resume": ["warpratchet resume run.h5 --steps 2000000"],
    "inspect": ["warpratchet inspect run.h5", "warpratchet inspect run.h5 --json"],
    "verify": ["warpratchet verify run.h5", "warpratchet verify fig7.h5 --json"],
    "sweep": [
        "warpratchet sweep --path maximal --K 3 --b2 0.005:0.165:33 --out fig7.h5",
        "warpratchet sweep --grid b1=0.001:0.5:50,b2=0.001:0.5:50 --domain LR --out grid.h5",
        "warpratchet sweep --path k --Ks 2.5:3.5:11 --b1 0.1 --b2 0.01 --json",
    ],
    "sumrule": [
        "warpratchet sumrule --K 2.99 --b1 0.25 --b2 0.05 --points 100000 --steps 30000",
        "warpratchet sumrule --K 3 --b1 0.1 --b2 0.01 --grid 300 --indicator megno --json",
    ],
    "orbits": [
        "warpratchet orbits --K 3 --b1 0.1 --b2 0.01 --period 1 --json",
        "warpratchet orbits --K 2.99 --b1 0.25 --b2 0.05 --period 6",
        "warpratchet orbits --K 3 --b1 0.1 --b2 0.01 --period 10 --long   (minutes)",
    ],
}


def _epilog(name: str) -> str:
    return "examples:\n" + "\n".join(f"  {line}" for line in EXAMPLES[name])


def build_parser() -> Parser:
    """The ``warpratchet`` argument parser with every subcommand."""
    from .. import __version__

    parser = Parser(
        prog="warpratchet",
        description=DESCRIPTION,
        epilog=_epilog("warpratchet"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser, metavar="COMMAND")
    for name, module in SUBCOMMANDS.items():
        module.add(sub)
        p = sub.choices[name]
        # Each subcommand's help opens with its module's summary and ends with examples.
        if p.description is None:
            summary = module.__doc__.split("\n\n")[0].replace("\n", " ")
            # The docstring's "``warpratchet run``: ..." heading reads as plain text in a terminal.
            p.description = re.sub(r"^``[^`]*``:\s*", "", summary).replace("``", "")
        if name in EXAMPLES:
            p.epilog = _epilog(name)
            p.formatter_class = argparse.RawDescriptionHelpFormatter
    return parser


def _joined_lists(argv: list[str]) -> list[str]:
    """``--values -0.2,0.3`` as ``--values=-0.2,0.3``: argparse takes a list that starts with a
    minus sign for an option."""
    out = []
    for item in argv:
        if out and out[-1] in ("--knots", "--values") and item.startswith("-") and item[1:2].isdigit():
            out[-1] = f"{out[-1]}={item}"
        else:
            out.append(item)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input, 130 on Ctrl-C, 143 on SIGTERM)."""
    from .. import StorageError
    from ..errors import KernelError, Terminated

    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["figures"]:  # its options are warpratchet_viz's: passed through unparsed
            return figures.main(argv[1:])
        parser = build_parser()
        if not argv:  # no command: the overview, as --help prints it
            parser.print_help()
            return 0
        try:
            args = parser.parse_args(_joined_lists(argv))
        except SystemExit as exc:  # --help, --version (0); parse errors raise UsageError instead
            return exc.code if isinstance(exc.code, int) else 0
        return SUBCOMMANDS[args.command].command(args)
    except StorageError as exc:  # not the user's input: the disk or the folder refused a write
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 1
    except UsageError as exc:
        if exc.usage:
            print(exc.usage, file=sys.stderr)
        print(f"{exc.prog}: error: {exc}{exc.hint}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader of stdout left (``warpratchet orbits ... | head``): not an error, and nothing
        # more to say. Python's documented recipe: point stdout at devnull so the flush at exit
        # does not fail again; the status is the shell's for a writer ended by SIGPIPE.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE (13)
    except KernelError as exc:  # not the user's input: a launch the code cannot vouch for
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 1
    except (ValueError, OSError) as exc:
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 2
    except Terminated:  # SIGTERM during a run that stopped cleanly but said nothing more
        print("warpratchet: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt as exc:
        detail = str(exc) if isinstance(exc, Interrupted) else ""
        what = "terminated" if getattr(exc, "terminated", False) else "interrupted"
        print(f"warpratchet: {what}{' ' + detail if detail else ''}", file=sys.stderr)
        return getattr(exc, "status", 130)


#: Allocations between two collections of the cycle collector's youngest generation while the
#: command runs (Python's default: 700; 2,000 from Python 3.13).
YOUNG_GENERATION_THRESHOLD = 10_000


def console_main() -> int:
    """The ``warpratchet`` command as the process runs it (and ``python -m warpratchet``):
    :func:`main`, after which the process ends.

    A command's process makes ~10^5 objects that live to its end (Warp's import, most of them) and
    few after, so Python's cycle collector is set for that: while the command runs, its youngest
    generation is collected every :data:`YOUNG_GENERATION_THRESHOLD` allocations rather than
    Python's default, which spares the import most of its collections; and before the process ends every
    object is frozen out of it (``gc.freeze``), as the interpreter's teardown would otherwise
    collect over all of them at each stage of it. Together they are a large part of a short
    command's time (``benchmarks/README.md``, "command_time.py"). Nothing is lost by them: cycles
    are still collected during the run, the commands have closed their archives and recordings
    before the end, the atexit handlers still run, and objects that no cycle holds are still
    freed as their last reference goes. :func:`main` itself changes neither: a caller in the same
    process (a test, a notebook) goes on as it was.
    """
    gc.set_threshold(YOUNG_GENERATION_THRESHOLD, *gc.get_threshold()[1:])
    status = main()
    gc.freeze()
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(console_main())
