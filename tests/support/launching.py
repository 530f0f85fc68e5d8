"""The command line in a fresh process or in this one, the benchmarks, and their refusals."""

from __future__ import annotations

import contextlib
import os
import runpy
import subprocess
import sys
import tempfile
import traceback
import warnings
from pathlib import Path

#: The CLI flags of the map most tests use, MapParams(3.0, 0.1, 0.01) (domain LR, Eq. Aa).
MAP_FLAGS = ("--K", "3", "--b1", "0.1", "--b2", "0.01")


def run_argv(*flags: str) -> list[str]:
    """``warpratchet run`` of the map :data:`MAP_FLAGS` with more ``flags``, as an argv list."""
    return ["run", *MAP_FLAGS, *flags]


def cli(
    *args: str, timeout: float = 900, module: str = "warpratchet.cli", **options
) -> subprocess.CompletedProcess:
    """``warpratchet ARGS`` in a fresh process (``python -m warpratchet.cli``; another command line
    with ``module``, e.g. ``viz``), run to its end, output captured as text; ``options`` (``env``,
    ``cwd``) go to :func:`subprocess.run`."""
    return subprocess.run(
        [sys.executable, "-m", module, *args], capture_output=True, text=True, timeout=timeout, **options
    )


def launch(*args: str, module: str = "warpratchet.cli", text: bool = True, **options) -> subprocess.Popen:
    """``warpratchet ARGS`` started in a fresh process (as :func:`cli`) and left running, its stdout
    and stderr piped (as text unless ``text`` is false): for tests that interrupt, kill or read it."""
    return subprocess.Popen(
        [sys.executable, "-m", module, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=text,
        **options,
    )


@contextlib.contextmanager
def _warnings_on_stderr(stderr: list[str]):
    """Warnings nobody catches inside the block go, formatted, to ``stderr`` (appended after the
    block), filtered as a fresh interpreter does (``DeprecationWarning`` and its kin hidden),
    instead of to pytest's summary."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
            warnings.simplefilter("ignore", category)
        yield
    stderr.extend(warnings.formatwarning(w.message, w.category, w.filename, w.lineno) for w in caught)


def benchmark(name: str, *args: str) -> subprocess.CompletedProcess:
    """``python benchmarks/NAME ARGS`` in this process: run as that command runs it (``__main__``,
    ``sys.argv``, its folder first on ``sys.path``), with file descriptors 1 and 2 (Python's and any
    library's output) in temporary files; an uncaught exception prints its traceback and gives
    status 1. The :class:`subprocess.CompletedProcess` of the command, without a fresh interpreter
    that imports Warp, NumPy and Dask again for each benchmark."""
    script = Path(__file__).resolve().parents[2] / "benchmarks" / name
    argv, path = sys.argv, list(sys.path)
    extra: list[str] = []
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        sys.stdout.flush(), sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        os.dup2(out.fileno(), 1), os.dup2(err.fileno(), 2)
        sys.argv, sys.path[:0] = [str(script), *args], [str(script.parent)]
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _warnings_on_stderr(extra):
                try:
                    runpy.run_path(str(script), run_name="__main__")
                    code = 0
                except SystemExit as exc:
                    if isinstance(exc.code, str):
                        print(exc.code, file=sys.stderr)
                    code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
                except Exception:
                    traceback.print_exc()
                    code = 1
        finally:
            out.flush(), err.flush()
            os.dup2(saved[0], 1), os.dup2(saved[1], 2)
            os.close(saved[0]), os.close(saved[1])
            sys.argv, sys.path[:] = argv, path
        out.seek(0), err.seek(0)
        return subprocess.CompletedProcess(
            ["python", str(script), *args], code, out.read(), err.read() + "".join(extra)
        )


def quick_benchmark(name: str, *args: str) -> dict:
    """``benchmarks/NAME --quick --json ARGS`` (:func:`benchmark`): it must exit 0; its JSON report."""
    import json

    proc = benchmark(name, "--quick", "--json", *args)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def assert_one_line_error(proc: subprocess.CompletedProcess) -> None:
    """Bad input: exit 2, one line ``warpratchet: error: ...`` on stderr, no traceback."""
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warpratchet: error:"), proc.stderr


#: Longest usage line before an error line (the CLI shortens a longer one to ``usage: PROG [options]
#: (PROG --help lists them)``).
USAGE_WIDTH = 100


def error_line(stderr: str) -> str:
    """The one error line of a refusal, ``PROG: error: ...``: alone, or after one short usage line
    of the same ``PROG`` (a flag refused while parsing, argparse's convention); anything else fails."""
    lines = stderr.strip().splitlines()
    assert len(lines) in (1, 2) and ": error: " in lines[-1], stderr
    if len(lines) == 2:
        prog, usage = lines[1].split(": error: ")[0], lines[0]
        assert usage.startswith(f"usage: {prog} ") and "error:" not in usage, stderr
        assert len(usage) <= USAGE_WIDTH, stderr
    return lines[-1]


def in_process(capture, *args: str, main=None) -> subprocess.CompletedProcess:
    """``warpratchet ARGS`` through :func:`warpratchet.cli.main` in this process (what the installed
    script calls; another command line's ``main(argv)`` with ``main``, e.g. ``viz``'s): the
    :class:`subprocess.CompletedProcess` that :func:`cli` would give, for a test that needs only a
    command's exit status and output, not a fresh interpreter, a signal or a kill.

    ``capture`` is pytest's ``capfd`` (file descriptors 1 and 2, so also what HDF5 or Warp write
    there) or ``capsys``. A warning nobody catches ends on stderr, formatted and filtered as a fresh
    interpreter does (``DeprecationWarning`` and its kin hidden), instead of in pytest's summary."""
    if main is None:
        from warpratchet.cli import main

    capture.readouterr()  # what came before is not this command's
    extra: list[str] = []
    with _warnings_on_stderr(extra):
        code = main(list(args))
    out, err = capture.readouterr()
    err += "".join(extra)
    return subprocess.CompletedProcess([main.__module__, *args], code, out, err)


def refused(capsys, argv: list[str]) -> str:
    """``warpratchet ARGV`` in this process must refuse: exit 2 and one error line on stderr (returned),
    after a short usage line if a flag was refused while parsing."""
    from warpratchet.cli import main

    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    return error_line(err) + "\n"
