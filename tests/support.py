"""Helpers shared by the tests of archives, recordings, format fixtures and the CLI (not a test module).

Import with ``from support import ...`` (pytest puts ``tests/`` on ``sys.path``).
"""

from __future__ import annotations

import re
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

from warpratchet import Observer
from warpratchet.archive import Archive, ArchiveError
from warpratchet.ensemble import STATE_FIELDS
from warpratchet.history import BLOCK_FIELDS, HISTORY_FIELDS, History

#: The CLI flags of the map most tests use, MapParams(3.0, 0.1, 0.01) (domain LR, Eq. Aa).
MAP_FLAGS = ("--K", "3", "--b1", "0.1", "--b2", "0.01")
#: The archive's documented layout (its tables are checked against written files).
ARCHIVE_DOC = Path(__file__).resolve().parents[1] / "docs" / "archive.md"


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


def flip_bit(src, dst, offset: int, bit: int) -> None:
    """A copy of file ``src`` at ``dst`` with bit ``bit`` of byte ``offset`` flipped."""
    data = bytearray(open(src, "rb").read())
    data[offset] ^= 1 << bit
    open(dst, "wb").write(bytes(data))


def stored_chunks(path) -> list[tuple[str, int, int]]:
    """``(dataset, byte offset, size)`` of every stored chunk of every dataset in the HDF5 file at
    ``path``: the bytes a checksum covers."""
    chunks = []

    def add(name, obj):
        if isinstance(obj, h5py.Dataset):
            for i in range(obj.id.get_num_chunks()):
                info = obj.id.get_chunk_info(i)
                chunks.append((name, info.byte_offset, info.size))

    with h5py.File(path, "r") as f:
        f.visititems(add)
    return chunks


def flip_sample(path, every: int) -> list[int]:
    """The offsets a suite's flip census tries in the file at ``path``: every ``every``-th byte of
    the file, and one byte of each checksummed dataset (of its first stored chunk, see
    :func:`stored_chunks`: the first, middle or last byte, in turn), however ``every`` falls."""
    first = {}
    for name, start, size in stored_chunks(path):
        first.setdefault(name, (start, size))
    picked = {start + (0, size // 2, size - 1)[i % 3] for i, (start, size) in enumerate(first.values())}
    return sorted(set(range(0, Path(path).stat().st_size, every)) | picked)


def archive_contents(path) -> tuple[dict, list[str]]:
    """What a reader returns from the archive at ``path`` (raises ArchiveError), and the warnings
    it gave."""
    import warnings

    from warpratchet.archive import ArchiveWarning, open_archive

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ArchiveWarning)
        with open_archive(path) as arc:
            got = {
                "series": arc.series,
                "snapshots": arc.snapshots,
                "initial": arc.initial,
                "checkpoint": arc.checkpoint(),
                "meta": (arc.params, arc.settings, arc.versions, arc.created),
            }
    return got, [str(w.message) for w in caught]


def same_contents(a: dict, b: dict) -> bool:
    """Two :func:`archive_contents` equal bit for bit."""
    series = all(np.array_equal(a["series"][k], b["series"][k], equal_nan=True) for k in a["series"])
    snaps = all(
        np.array_equal(getattr(a["snapshots"], k), getattr(b["snapshots"], k))
        for k in ("steps", "indices", "x", "p", "ftle", "finite_time_acceleration")
    )
    return (
        series
        and snaps
        and same_state(a["initial"], b["initial"])
        and same_state(a["checkpoint"][0], b["checkpoint"][0])
        and a["checkpoint"][1] == b["checkpoint"][1]
        and a["meta"] == b["meta"]
    )


def archive_flip_census(path, offsets: list[int], workdir, reference: Callable[[int], dict]) -> dict:
    """Single-bit flips of the archive at ``path``, one per offset (bit ``i % 8`` of the i-th),
    each in a copy under ``workdir``: what ``verify`` and a reader make of each.

    Returns the census ``tried / detected / harmless / recovered / silent`` and the lists
    ``missed`` (offsets in stored data that verify did not report) and ``wrong`` (offsets where a
    reader announced an older checkpoint that differs from ``reference(step)``, the state of an
    uninterrupted run at that step).
    """
    from functools import cache

    from warpratchet.archive import verify_archive

    reference = cache(reference)  # the few checkpoint steps recur over many flips
    want, _ = archive_contents(path)
    last = want["checkpoint"][1]
    chunks = [(start, size) for _, start, size in stored_chunks(path)]
    census = {
        "tried": 0,
        "detected": 0,
        "harmless": 0,
        "recovered": 0,
        "silent": 0,
        "missed": [],
        "wrong": [],
    }
    damaged = Path(workdir) / "flip.h5"
    for i, offset in enumerate(offsets):
        flip_bit(path, damaged, offset, i % 8)
        census["tried"] += 1
        try:
            problems, _ = verify_archive(damaged)
        except ArchiveError as exc:
            problems = [str(exc)]
        if problems:
            census["detected"] += 1
        elif any(start <= offset < start + length for start, length in chunks):
            census["missed"].append(offset)
        try:
            got, notes = archive_contents(damaged)
        except ArchiveError:
            continue
        if same_contents(got, want):
            census["harmless" if not problems else "recovered"] += 1 if not notes else 0
            continue
        state, step = got["checkpoint"]
        if notes and step < last:  # an older checkpoint, announced: it must be the true one
            if not same_state(state, reference(step)):
                census["wrong"].append(offset)
            census["recovered"] += 1
            continue
        census["silent"] += 1
    return census


def sweep_flip_census(path, offsets: list[int], workdir) -> dict:
    """Single-bit flips of the sweep file at ``path``, one per offset (bit ``i % 8`` of the i-th),
    each in a copy under ``workdir``: ``error`` (the reader refuses the file), ``same`` (it returns
    the same rows) and ``silent``, the offsets at which it returned other rows."""
    from warpratchet.errors import FileFormatError
    from warpratchet.sweep import read_sweep

    rows = read_sweep(path)
    outcomes = {"error": 0, "same": 0, "silent": []}
    damaged = Path(workdir) / "flip.h5"
    for i, offset in enumerate(offsets):
        flip_bit(path, damaged, offset, i % 8)
        try:
            got = read_sweep(damaged)
        except FileFormatError:
            outcomes["error"] += 1
            continue
        if got == rows:
            outcomes["same"] += 1
        else:
            outcomes["silent"].append(offset)
    return outcomes


def archive_rows(path) -> int:
    """The valid rows of the archive at ``path`` as a concurrent reader sees them (no lock taken);
    0 while it does not exist or cannot be read yet."""
    try:
        with Archive(path, locking=False) as arc:
            return arc.rows
    except (FileNotFoundError, ArchiveError, OSError):
        return 0


def benchmark(name: str, *args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    """``benchmarks/NAME ARGS`` in a fresh process, run to its end, output captured as text."""
    script = Path(__file__).resolve().parents[1] / "benchmarks" / name
    return subprocess.run(
        [sys.executable, str(script), *args], capture_output=True, text=True, timeout=timeout
    )


def quick_benchmark(name: str, timeout: float = 900) -> dict:
    """``benchmarks/NAME --quick --json`` in a fresh process: it must exit 0; its JSON report."""
    import json

    proc = benchmark(name, "--quick", "--json", timeout=timeout)
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


def refused(capsys, argv: list[str]) -> str:
    """``warpratchet ARGV`` in this process must refuse: exit 2 and one error line on stderr (returned),
    after a short usage line if a flag was refused while parsing."""
    from warpratchet.cli import main

    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    return error_line(err) + "\n"


class Capture(Observer):
    """Copies of the state at the start of a run and after chunks, keyed by step.

    ``keep(step)`` chooses the chunk ends to copy (default: all); the reference states that
    checkpoints and resumed runs are compared with.
    """

    def __init__(self, keep: Callable[[int], bool] = lambda step: True) -> None:
        self.keep = keep
        self.states: dict[int, dict[str, np.ndarray]] = {}

    def begin(self, ensemble, target_step):
        self.states[ensemble.step] = ensemble.state()

    def after_chunk(self, ensemble, seconds):
        if self.keep(ensemble.step):
            self.states[ensemble.step] = ensemble.state()


def bits(value: object) -> object:
    """Exact identity of a value: a float by its bits, so NaN equals NaN and -0.0 is not 0.0; any
    other value with its type."""
    return struct.pack("<d", value) if isinstance(value, float) else (type(value), value)


def exact_rows(rows: list[dict], skip=()) -> list[dict]:
    """Rows (sweep rows: field -> value) in a form that compares bit for bit (:func:`bits`), without
    the fields in ``skip``."""
    return [{k: bits(v) for k, v in row.items() if k not in skip} for row in rows]


def same_state(a: dict, b: dict) -> bool:
    """Two ensemble states equal bit for bit in every field of ``STATE_FIELDS``."""
    return all(np.array_equal(a[k], b[k]) for k in STATE_FIELDS)


def same_history(a: History | dict, b: History | dict, prefix: bool = False) -> bool:
    """Two histories equal bit for bit (NaN equal to NaN).

    ``a`` and ``b`` are :class:`~warpratchet.history.History` objects, compared in their rows (every
    field of ``HISTORY_FIELDS``), block records (every field of ``BLOCK_FIELDS``) and block
    subsample, or dicts of rows (field -> sequence: ``History.as_dict()``, ``run --json``'s
    ``history``, whose JSON null is read as NaN), compared in their rows. With ``prefix``, ``a`` holds
    the first rows (and block records) of ``b`` rather than all of them.
    """

    def parts(h: History | dict) -> tuple:
        return (h.rows, h.block_rows, h.block_indices) if isinstance(h, History) else (h, None, None)

    def same(x: dict, y: dict, fields: tuple[str, ...]) -> bool:
        n, m = len(x[fields[0]]), len(y[fields[0]])
        if n > m or (n < m and not prefix):
            return False
        # float: JSON's null becomes NaN; the integer fields (steps, counts) stay exact below 2^53
        return all(
            np.array_equal(np.array(x[k], dtype=float), np.array(y[k][:n], dtype=float), equal_nan=True)
            for k in fields
        )

    (rows_a, blocks_a, idx_a), (rows_b, blocks_b, idx_b) = parts(a), parts(b)
    if not same(rows_a, rows_b, HISTORY_FIELDS):
        return False
    if blocks_a is None or blocks_b is None:
        return True
    return same(blocks_a, blocks_b, BLOCK_FIELDS) and np.array_equal(idx_a, idx_b)


# -- the documented archive layout (test_archive.py, test_transport_cli.py) -------------------------
def documented_names() -> set[str]:
    """The names docs/archive.md's tables list: ``/group/dataset`` and ``/path@attribute``."""
    names = set()
    for line in ARCHIVE_DOC.read_text().splitlines():
        m = re.match(r"\|\s*`(/[^`]*)`\s*\|", line)
        if m:
            names.add(m.group(1))
    return names


#: Attributes every dataset carries (units, description) or that mark HDF5 dimension scales:
#: documented once in prose, checked by test_archive.py's test_every_dataset_describes_itself.
DATASET_ATTRS = {"units", "long_name", "CLASS", "NAME", "REFERENCE_LIST", "DIMENSION_LIST"}


def written_names(path) -> set[str]:
    """The names an HDF5 file holds, as the docs write them (without :data:`DATASET_ATTRS`)."""
    names = set()
    with h5py.File(path, "r") as f:

        def add(name, obj):
            names.add(f"/{name}")
            skip = DATASET_ATTRS if isinstance(obj, h5py.Dataset) else set()
            names.update(f"/{name}@{key}" for key in obj.attrs if key not in skip)

        names.update(f"/@{key}" for key in f.attrs)
        f.visititems(add)
    return names


def documented_optional() -> set[str]:
    """Attributes the table documents as absent for a run-dependent default (RunSpec's rule)."""
    return {
        m.group(1)
        for line in ARCHIVE_DOC.read_text().splitlines()
        if (m := re.match(r"\|\s*`(/[^`]*@[^`]*)`\s*\|.*\babsent\b", line))
    }
