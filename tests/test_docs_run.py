"""README.md and docs/archive.md, orbits.md, transport.md run as written: every ```bash and
```python block, top to bottom, in one empty folder (the tutorial docs/api.md has its own test,
test_docs_api.py).

What a reader would do, with one documented shrinkage so that the suite stays fast
(:func:`shrink`): ``--points N`` becomes ``max(100, N // 100)`` and ``--steps N``
``max(15000, N // 50)`` (15000 is above the island census's minimum of 13824 steps; a resume to
twice the steps stays twice), the same for ``points=``/``steps=``/``.run(N`` in Python; a
``warpratchet run`` or ``sweep`` without them gets ``--points 100 --steps 15000``; a range
``START:STOP:COUNT`` (or ``np.linspace(START, STOP, COUNT)``) keeps at most 5 values;
``warpratchet figures`` gets ``--quick``, ``benchmarks/throughput.py`` ``--quick``.
``python -m viz`` is ``python -m warpratchet_viz`` outside the source folder, as the README
says, and ``python benchmarks/...`` runs the checkout's script.

A plain ``warpratchet ...`` or ``python -m warpratchet_viz ...`` command (no pipe, redirection or
quoting; no rerun recording, which closes at process exit) and each Python block (in fresh globals,
as ``python -c`` runs it) run in one Python process per doc (:data:`WORKER`, in the same folder),
with their own file descriptors 0-2: the exit status and output are the command's, without an
interpreter, Warp and its kernels started again for each (test_cli_core starts the script itself).
Everything else runs in its own process.

Left out, each for its stated reason (:data:`SKIPPED`): installs, the test suite itself, the
rerun viewer, a Dask cluster or batch system, and the two analyses that take minutes.
"""

from __future__ import annotations

import json
import os
import re
import select
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(bash|python)\n(.*?)^```$", re.DOTALL | re.MULTILINE)

#: Commands that a test cannot run (a pattern searched in a shell command, or in a Python block),
#: and why.
SKIPPED = {
    r"^pip install": "installs packages",
    r"^python -m pytest": "the test suite itself",
    r"^rerun ": "opens the rerun viewer",
    r"^dask (scheduler|worker)": "starts a Dask cluster",
    r" --scheduler ": "needs a Dask cluster",
    r"^from dask_jobqueue|\nfrom dask_jobqueue": "needs a batch system",
    r"^python scripts/": "analyses that take minutes",
}


def _scaled(name: str, value: int) -> int:
    return max(100, value // 100) if name == "points" else max(15000, value // 50)


def shrink(command: str) -> str:
    """A command (or Python block) with the shrinkage of the module docstring."""
    number = r"(\d[\d_]*)"
    command = re.sub(rf"--(points|steps) {number}", lambda m: f"--{m[1]} {_scaled(m[1], int(m[2]))}", command)
    command = re.sub(rf"\b(points|steps)={number}", lambda m: f"{m[1]}={_scaled(m[1], int(m[2]))}", command)
    command = re.sub(rf"\.run\({number}", lambda m: f".run({_scaled('steps', int(m[1]))}", command)
    # A subsample no larger than the shrunk ensemble (the run refuses more snapshot points than points).
    command = re.sub(
        rf"--snapshot-points {number}", lambda m: f"--snapshot-points {_scaled('points', int(m[1]))}", command
    )
    command = re.sub(r"(\d[\d.]*:\d[\d.]*:)(\d+)\b", lambda m: f"{m[1]}{min(int(m[2]), 5)}", command)
    command = re.sub(
        r"(np\.linspace\([^,]+,[^,]+, )(\d+)\)", lambda m: f"{m[1]}{min(int(m[2]), 5)})", command
    )
    if re.match(r"warpratchet (run|sweep) ", command):
        missing = [
            f"{flag} {value}"
            for flag, value in (("--points", 100), ("--steps", 15000))
            if flag not in command
        ]
        if missing:
            command = command.replace(" --", f" {' '.join(missing)} --", 1)
    if command.startswith("warpratchet figures"):
        command += " --quick"
    command = command.replace("python -m viz ", "python -m warpratchet_viz ")
    command = command.replace("python -m viz.", "python -m warpratchet_viz.")
    if command.startswith("python benchmarks/"):
        command = f"python {ROOT}/{command.removeprefix('python ')}"
        if "throughput.py" in command:
            command += " --quick"
    return command


def commands(text: str) -> list[tuple[str, str]]:
    """``(kind, code)`` of every block in order: each shell command on its own (continuations
    joined, comments and ``&&`` chains split), each Python block whole."""
    out = []
    for kind, block in FENCE.findall(text):
        if kind == "python":
            out.append(("python", block))
            continue
        for line in block.replace("\\\n", " ").splitlines():
            line = re.sub(r"(^|\s+)#.*$", "", line).strip()
            out.extend(("bash", part.strip()) for part in line.split(" && ") if part.strip())
    return out


#: A command that :data:`WORKER` runs: the shell would only split it into words (the rerun
#: recordings of ``--rerun``, ``scenes`` and ``record`` close at process exit).
IN_WORKER = re.compile(
    r"(warpratchet (?!.*--rerun)|python -m warpratchet_viz(\.report)? (?!scenes|record))[^|<>;&`$()'\"*?~\\]*"
)

#: Runs each JSON line on stdin: a list of words, ``warpratchet ARGS`` as
#: ``warpratchet.cli.main(ARGS)`` (what the installed script calls) and ``python -m MODULE ARGS`` as
#: :func:`runpy.run_module`; a string, a Python block as ``python -c`` runs it (``__main__``, fresh
#: globals). Its stdin empty and its stdout and stderr (file descriptors 1, 2: Python's and any
#: library's) in temporary files. Answers with a JSON line ``{"returncode", "stdout", "stderr"}``
#: on the stdout it started with.
WORKER = r"""
import json, os, runpy, sys, tempfile, traceback
from warpratchet.cli import main


def command(words):
    if isinstance(words, str):
        sys.argv = ["-c"]
        exec(compile(words, "<string>", "exec"), {"__name__": "__main__", "__builtins__": __builtins__})
        return 0
    if words[0] == "warpratchet":
        return main(words[1:])
    sys.argv = words[2:]
    runpy.run_module(words[2], run_name="__main__", alter_sys=True)
    return 0

requests, replies = os.fdopen(os.dup(0)), os.fdopen(os.dup(1), "w")
os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
for line in requests:
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        sys.stdout.flush(), sys.stderr.flush()
        os.dup2(out.fileno(), 1), os.dup2(err.fileno(), 2)
        try:
            returncode = command(json.loads(line))
        except SystemExit as exc:
            returncode = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
        except BaseException:
            traceback.print_exc()
            returncode = 1
        sys.stdout.flush(), sys.stderr.flush()
        out.seek(0), err.seek(0)
        answer = {"returncode": returncode, "stdout": out.read(), "stderr": err.read()}
    replies.write(json.dumps(answer) + "\n")
    replies.flush()
"""


class Worker:
    """One :data:`WORKER` process in ``cwd``; :meth:`run` is :func:`subprocess.run` of a command.
    A context manager: it leaves with the process ended (killed if the block raised)."""

    def __init__(self, cwd: Path, env: dict):
        argv = [sys.executable, "-c", WORKER]
        self.proc = subprocess.Popen(
            argv, cwd=cwd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )

    def __enter__(self) -> Worker:
        return self

    def __exit__(self, kind, *_) -> None:
        if kind is not None:
            self.proc.kill()
        self.proc.stdin.close()
        returncode = self.proc.wait(timeout=900)
        self.proc.stdout.close()
        assert kind is not None or returncode == 0, f"the worker process exited {returncode}"

    def run(self, command: str, timeout: float = 900, python: bool = False) -> subprocess.CompletedProcess:
        """The shell command ``command``, or with ``python`` the Python block ``command``."""
        self.proc.stdin.write(json.dumps(command if python else shlex.split(command)) + "\n")
        self.proc.stdin.flush()
        if not select.select([self.proc.stdout], [], [], timeout)[0]:
            raise subprocess.TimeoutExpired(command, timeout)
        line = self.proc.stdout.readline()
        assert line, f"the worker process ended (exit {self.proc.wait()}) running: {command}"
        answer = json.loads(line)
        return subprocess.CompletedProcess(command, answer["returncode"], answer["stdout"], answer["stderr"])


def _skipped(code: str) -> str | None:
    return next((why for pattern, why in SKIPPED.items() if re.search(pattern, code)), None)


@pytest.mark.slow
@pytest.mark.parametrize("doc", ["README.md", "docs/archive.md", "docs/orbits.md", "docs/transport.md"])
def test_the_doc_runs_in_one_empty_folder(doc, tmp_path):
    pytest.importorskip("matplotlib", reason="the README's figures need the figures extra")
    pytest.importorskip("xarray", reason="the archive docs use the xarray extra")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    ran, skipped = 0, []
    with Worker(tmp_path, env) as worker:
        for kind, code in commands((ROOT / doc).read_text()):
            why = _skipped(code)
            if why is not None:
                skipped.append(why)
                continue
            code = shrink(code)
            if kind == "python" or IN_WORKER.fullmatch(code):
                proc = worker.run(code, python=kind == "python")
            else:
                argv = ["bash", "-euo", "pipefail", "-c", code]
                proc = subprocess.run(
                    argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900
                )
            assert proc.returncode == 0, f"{doc}: {code}\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
            assert kind == "bash" or proc.stdout.strip(), f"{doc}: a Python block prints nothing:\n{code}"
            ran += 1
    assert ran >= (25 if doc == "README.md" else 3), (ran, skipped)


def test_shrink_is_what_the_docstring_says():
    assert shrink("warpratchet run --K 3 --b1 0.1 --b2 0.01 --points 100000 --steps 1000000 --out a.h5") == (
        "warpratchet run --K 3 --b1 0.1 --b2 0.01 --points 1000 --steps 20000 --out a.h5"
    )
    assert shrink("warpratchet run --K 3 --b1 0.1 --b2 0.01 --rerun run.rrd") == (
        "warpratchet run --points 100 --steps 15000 --K 3 --b1 0.1 --b2 0.01 --rerun run.rrd"
    )
    assert shrink("c = census(p, steps=30_000, points=100_000)") == "c = census(p, steps=15000, points=1000)"
    assert shrink("warpratchet sweep --path maximal --K 3 --b2 0.005:0.165:33 --points 10000").endswith(
        "--b2 0.005:0.165:5 --points 100"
    )
    assert shrink("pts = maximal_path(np.linspace(0.005, 0.165, 33), K=3.0)").endswith("0.165, 5), K=3.0)")
    assert (
        shrink("python -m viz history drift.h5 -o h.png")
        == "python -m warpratchet_viz history drift.h5 -o h.png"
    )


#: A duration in prose: "about 2 s", "4-6 minutes", "well under one".
DURATION = re.compile(
    r"(?:~|about |\b)\d+(?:[.,-]\d+)*\s*(?:s|ms|min|minutes|seconds|hours?)\b"
    r"|\ba minute\b|under (?:a minute|one)\b"
)


def test_readme_timings_name_their_machine():
    """A time in the README is a measurement on one machine: it says which, close by (the rerun
    viewer's playback time excepted, which is the viewer's, not a measurement)."""
    text = (ROOT / "README.md").read_text()
    bare = [
        text[max(0, m.start() - 40) : m.end() + 40]
        for m in DURATION.finditer(text)
        if "machine" not in text[max(0, m.start() - 100) : m.end() + 100]
        and "press play" not in text[m.start() - 40 : m.start()]
    ]
    assert bare == []


def test_license_is_the_mit_license_pyproject_names():
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
    assert 'license = "MIT"' in (ROOT / "pyproject.toml").read_text()
