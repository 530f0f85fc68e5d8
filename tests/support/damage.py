"""Damaged copies of files: one flipped bit at a time, and what the readers make of each."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import h5py

from warpratchet.archive import ArchiveError

from .archives import archive_contents, same_contents
from .runs import same_state


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
