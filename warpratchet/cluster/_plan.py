"""The cut of a sharded run: its shards' bounds, and the memory a shard and the merge need.

:func:`shard_bounds` cuts the ensemble by global point index into consecutive shards, as equal
as can be. :func:`shard_bytes` is what a shard holds on its worker (its state, its records, the
records of a block of points that shards share, for the merge, and its snapshots) and
:func:`check_merge` what the merge's client holds (a few numbers per row and per block of
points, nothing per point); both are checked before any work, a shard against the smallest
worker (:func:`_check_workers`).
"""

from __future__ import annotations

import math
from typing import Any

from .. import observables as _obs
from .._cluster_archive import snapshot_steps
from ..archive._format import SNAPSHOT_FIELDS
from ..errors import ResourceError, check_count
from ..history import history_steps
from ..limits import format_bytes
from ..observables import SUMMARY_BYTES_PER_POINT
from ..spec import RunSpec


def shard_bounds(points: int, shards: int) -> list[tuple[int, int]]:
    """``(lo, hi)`` of each of ``shards`` shards of ``points`` points: consecutive, as equal as can be."""
    points = check_count("points", points, 1)
    shards = check_count("shards", shards, 1, points)
    bounds = [points * k // shards for k in range(shards + 1)]
    return list(zip(bounds[:-1], bounds[1:], strict=True))


def _ensemble_size(spec: RunSpec) -> int:
    """Points the ensemble of ``spec`` has: a grid rounds down to a square."""
    return math.isqrt(spec.points) ** 2 if spec.init == "grid" else spec.points


def _kind(transport: bool):
    if transport:
        from ..transport import TransportEnsemble

        return TransportEnsemble
    from ..ensemble import Ensemble

    return Ensemble


def shard_bytes(
    spec: RunSpec,
    points: int,
    transport: bool = False,
    on_disk: bool = False,
    snapshots: tuple[int, int] = (0, 0),
) -> int:
    """Memory a shard of ``points`` points needs on its worker: the state (and transport's
    carry), one summary's working memory, and its records: 16 B per point per history row, or
    with ``on_disk`` (records in a workdir) one row of them; and for the merge, a block of points
    that shards share, whose records at every row one task holds (twice: the pieces and the row
    they make). With ``snapshots`` (``(snapshot_every, snapshot_points)``), the snapshots of at
    most ``min(points, snapshot_points)`` of its points, which it keeps to the end."""
    every = len(history_steps(0, spec.steps))
    rows = 1 if on_disk else every
    state = _kind(transport).bytes_per_point()
    shared = 2 * min(_ensemble_size(spec), _obs.SUMMARY_CHUNK) * 16 * every
    snapped = (
        len(snapshot_steps(spec.steps, snapshots[0])) * len(SNAPSHOT_FIELDS) * 8 * min(points, snapshots[1])
    )
    return (
        points * (state + 16 * rows)
        + min(points, _obs.SUMMARY_CHUNK) * SUMMARY_BYTES_PER_POINT
        + shared
        + snapped
    )


def _worker_memory(client: Any) -> dict[str, int]:
    """Each worker's memory: Dask's ``memory_limit``, or where it has none, what its machine has
    available (asked of the worker; 0 where unknown)."""
    from ..limits import available_memory

    limits = {}
    unlimited = []
    for address, info in client.scheduler_info()["workers"].items():
        limit = int(info.get("memory_limit") or 0)
        limits[address] = limit
        if not limit:
            unlimited.append(address)
    if unlimited:
        for address, free in client.run(available_memory, workers=unlimited).items():
            limits[address] = int(free or 0)
    return limits


#: What the merge's client holds per history row and per block of points: the two passes' partial
#: sums as Python numbers in dicts, generously.
MERGE_BYTES_PER_BLOCK = 1024


def check_merge(points: int, transport: bool = False, rows: int = 64) -> None:
    """ResourceError, before any work, if this machine cannot hold the merge: the two passes'
    partial sums of every :data:`~warpratchet.observables.SUMMARY_CHUNK` block of points at each
    of ``rows`` rows (:data:`MERGE_BYTES_PER_BLOCK`), and with ``transport`` the spread's column
    sums; nothing per point."""
    from ..limits import check_memory
    from ..transport._fits import GROUPS

    blocks = -(-max(points, 1) // _obs.SUMMARY_CHUNK)  # len(summary_chunks(points)), counted
    needed = rows * (blocks * MERGE_BYTES_PER_BLOCK + (3 * GROUPS * 8 if transport else 0))
    check_memory(f"points = {points} (the merge of a sharded run)", needed,
                 f"{MERGE_BYTES_PER_BLOCK} B per row for each of {blocks} blocks of points")  # fmt: skip


def _check_workers(
    client: Any,
    spec: RunSpec,
    bounds: list[tuple[int, int]],
    transport: bool,
    on_disk: bool,
    snapshots: tuple[int, int] = (0, 0),
) -> None:
    """ResourceError, before any work, if the largest shard does not fit the smallest worker."""
    limits = _worker_memory(client)
    if not limits:
        raise ResourceError("the Dask cluster has no workers; start some (docs/cluster.md)")
    largest = max(hi - lo for lo, hi in bounds)
    needed = shard_bytes(spec, largest, transport, on_disk, snapshots)
    address, smallest = min(limits.items(), key=lambda item: item[1])
    if smallest and needed > smallest:
        rows = 1 if on_disk else len(history_steps(0, spec.steps))
        raise ResourceError(
            f"shards = {len(bounds)}: a shard of {largest} points needs {format_bytes(needed)} "
            f"({_kind(transport).bytes_per_point()} B of state and {16 * rows} B of records per point), "
            f"worker {address} has a memory limit of {format_bytes(smallest)}; use more shards "
            f"(at least {math.ceil(len(bounds) * needed / smallest)}) or workers with more memory"
        )
