"""The ``warpratchet`` command.

One module per subcommand (:mod:`.theory`, :mod:`.run`, :mod:`.resume`, :mod:`.inspect`,
:mod:`.sweep`, :mod:`.sumrule`), each with ``add(subparsers)`` declaring its flags and
``command(args)`` running it; :mod:`.common` holds what they share (the one-line error, JSON
output, flags built from :class:`~warpratchet.spec.RunSpec`), :mod:`.sinks` the output options of
``run``. Bad input (argparse errors, ``ValueError`` from the API, unreadable files) prints one
line on stderr and exits with status 2, never a traceback; a write the system refuses (disk
full, read-only, permissions: :class:`warpratchet._files.StorageError`) one line and status 1;
Ctrl-C exits with 130 (a subcommand may say what was kept: ``KeyboardInterrupt(message)``).

A new subcommand is a new module with ``add`` and ``command``, listed in :data:`SUBCOMMANDS`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from . import inspect, resume, run, sumrule, sweep, theory, verify
from .common import Parser, ProgressBar, UsageError, emit_json, nonnegative_int, positive_int

__all__ = [
    "main",
    "build_parser",
    "UsageError",
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
}


def build_parser() -> Parser:
    """The ``warpratchet`` argument parser with every subcommand."""
    parser = Parser(prog="warpratchet", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in SUBCOMMANDS.values():
        module.add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input, 130 on Ctrl-C)."""
    from .._files import StorageError

    try:
        args = build_parser().parse_args(argv)
        return SUBCOMMANDS[args.command].command(args)
    except StorageError as exc:  # not the user's input: the disk or the folder refused a write
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 1
    except (UsageError, ValueError, OSError) as exc:
        print(f"warpratchet: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print("warpratchet: interrupted" + (f"; {exc}" if str(exc) else ""), file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
