"""What every ``python -m viz`` command shares: its name, bad input and Ctrl-C.

Bad input gives one line ``<prog>: error: <message>`` on stderr and exit status 2 (argparse's
own usage errors print the usage line first, as argparse does everywhere); Ctrl-C gives one line
``<prog>: interrupted ...`` and exit status 130, the shell's code for SIGINT. Never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

__all__ = ["PACKAGE", "INTERRUPTED", "command_name", "run"]

#: The name this package is imported under: ``viz`` from a checkout, ``warpratchet_viz`` when
#: installed (pyproject.toml maps the folder viz/ to that name).
PACKAGE = __name__.rpartition(".")[0]

#: Exit status after Ctrl-C: 128 + SIGINT.
INTERRUPTED = 130


def command_name(command: str) -> str:
    """How the user typed a command, e.g. ``"python -m viz figures"``."""
    return f"python -m {PACKAGE} {command}"


def run(
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None,
    body: Callable[[argparse.Namespace], int],
    interrupted: str = "",
) -> int:
    """Parse ``argv`` with ``parser`` and run ``body`` on the result; returns the exit status.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's options; its ``prog`` (the command as the user typed it) prefixes every message.
    argv : sequence of str, optional
        The arguments after the command name (default ``sys.argv[1:]``).
    body : callable
        Does the work and returns the exit status; raises ``ValueError``, ``OSError`` or
        ``ImportError`` (a missing optional dependency) for bad input or an unusable file.
    interrupted : str
        What is kept after Ctrl-C and how to go on, appended to the ``interrupted`` line.
    """
    try:
        return body(parser.parse_args(list(sys.argv[1:] if argv is None else argv)))
    except SystemExit as exc:  # argparse after --help (0) or a usage error (2): already printed
        # Returned, not raised, so that ``main(argv)`` of every command returns its status.
        return exc.code if isinstance(exc.code, int) else 2
    except (ValueError, OSError, ImportError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted{'; ' + interrupted if interrupted else ''}", file=sys.stderr)
        return INTERRUPTED
