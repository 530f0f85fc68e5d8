"""One ensemble split across the workers of a Dask cluster, with the single machine's numbers.

:func:`run_sharded` splits the ensemble of a :class:`~warpratchet.spec.RunSpec` by global point
index into shards (:func:`shard_bounds`), runs each as a Dask task (:func:`run_shard`, on the
worker's own threads) and merges what they record into a :class:`ShardedRun`: the summary, the
history rows and block gains, and with ``transport`` the return-time and flight counts and the
spread of the momentum. Every one of these numbers is bit for bit what the same run gives on one
machine, for any number of shards:

* **Initial conditions by global index.** A shard samples points ``lo <= i < hi`` of the one
  ensemble (:func:`warpratchet.sampling.sampled_chunks` with ``lo``, ``hi``): the same doubles,
  and each point's orbit and tangent are independent of the others (as they are of the thread
  count).
* **Partial sums in the single machine's order.** Each shard records two doubles per point at
  the run's common steps (:class:`ShardRecord`) and keeps them on its worker (or in its
  workdir); the merge reduces them there in the single machine's order: the summary and the
  history's variances block by block (:mod:`._passes`), the spread of the momentum column by
  column (:mod:`._spread`). Counts (return times, flights, runs still open) are int64 sums and
  merge by addition; block gains are per point of a fixed subsample and merge by concatenation.
* **No lockstep.** Shards never wait for each other: each runs to the end and keeps its
  records; the merge starts when all are in.

Cost: a record is 16 bytes per point per row (about 40 rows at n = 120000), on the shard's
worker (with a workdir, storage every worker and the client share: a file per row, and a shard's
memory is its state and one row). The client receives a few numbers per row and per block of
2^20 points (:data:`MERGE_BYTES_PER_BLOCK`) and the spread's column sums: nothing per point.
A block shared by two shards moves its points' records (16 B a point per row) between workers.
``benchmarks/cluster_scaling.py`` measures the merge's time.

The package's public names are those below (``__all__``); the implementation is private, one
idea per module:

* :mod:`._plan`: the cut into shards (:func:`shard_bounds`) and the memory a shard
  (:func:`shard_bytes`) and the merge (:func:`check_merge`) need, checked before any work;
* :mod:`._shard`: one shard, what a Dask task does (:func:`run_shard`), and its records
  (:class:`ShardRecord`);
* :mod:`._passes`: the merge's two rounds of tasks over the records, block by block: the
  summary and the history's variances;
* :mod:`._spread`: the merge of the spread of the momentum, column sums carried from shard to
  shard;
* :mod:`._merge`: :class:`ShardedRun`, the merged result, the client's side of the merge;
* :mod:`._workdir`: a workdir's ``run.json`` and the run's own folder beside ``out``;
* :mod:`._run`: :func:`run_sharded`, the shards submitted, gathered, merged and written.

Each imports only modules above it in this list. The archive of a merged run
(:func:`shard_paths`, :func:`shards_folder`, :func:`snapshot_file`) is
:mod:`warpratchet._cluster_archive`.
"""

from .._cluster_archive import shard_paths, shards_folder, snapshot_file
from ._merge import ShardedRun
from ._plan import MERGE_BYTES_PER_BLOCK, check_merge, shard_bounds, shard_bytes
from ._run import run_sharded
from ._shard import ShardRecord, run_shard

__all__ = [
    "check_merge",
    "MERGE_BYTES_PER_BLOCK",
    "ShardRecord",
    "ShardedRun",
    "shard_bounds",
    "shard_bytes",
    "shard_paths",
    "shards_folder",
    "snapshot_file",
    "run_shard",
    "run_sharded",
]
