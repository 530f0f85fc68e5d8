"""One ensemble sharded across a Dask cluster (warpratchet.cluster): the single machine's numbers.

The cluster is a LocalCluster of two worker processes on loopback, each with a memory limit below
what the whole ensemble's shard would need (the Nanny's own memory actions are switched off, so
the limit is the number the run checks against, not a reason to kill a worker).
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from support import bits, refused, run_argv, same_history

from warpratchet.cluster import ShardedRun, run_shard, run_sharded, shard_bounds, shard_bytes
from warpratchet.ensemble import Ensemble
from warpratchet.errors import ResourceError
from warpratchet.history import History
from warpratchet.runloop import Observer
from warpratchet.spec import RunSpec
from warpratchet.transport import TransportEnsemble

distributed = pytest.importorskip("distributed")

SPEC = RunSpec(K=3.0, b1=0.1, b2=0.01, points=2000, steps=3000, seed=3, threads=1, chunk_steps=500)
#: Below one shard of the whole ensemble, above a shard of half of it.
MEMORY_LIMIT = (shard_bytes(SPEC, SPEC.points // 2) + shard_bytes(SPEC, SPEC.points)) // 2


def exact(value):
    """A report's value in a form that compares bit for bit (floats by their bits, NaN included)."""
    if isinstance(value, dict):
        return {k: exact(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [exact(v) for v in value]
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    return bits(value)


def single_machine(transport: bool) -> tuple[dict, History, dict | None]:
    """The run on one machine, as ``warpratchet run`` makes it: summary, history, transport report."""
    kind = TransportEnsemble if transport else Ensemble
    ensemble = kind.sample(SPEC.params, SPEC.points, SPEC.init, SPEC.seed, threads=2)
    ensemble.threshold, ensemble.threshold_rule = SPEC.threshold, SPEC.threshold_rule
    history = History(SPEC.threshold, SPEC.threshold_rule)
    ensemble.run(SPEC.steps, [history], chunk_steps=SPEC.chunk_steps)
    summary = ensemble.summary(SPEC.threshold, SPEC.threshold_rule, warn=False).as_dict()
    return summary, history, ensemble.report() if transport else None


@pytest.fixture(scope="module")
def references():
    return {transport: single_machine(transport) for transport in (False, True)}


@pytest.fixture(scope="module")
def cluster():
    import dask

    quiet = {f"distributed.worker.memory.{k}": False for k in ("target", "spill", "pause", "terminate")}
    with (
        dask.config.set(quiet),
        distributed.LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, memory_limit=MEMORY_LIMIT,
            host="127.0.0.1", dashboard_address=None,
        ) as cluster,
    ):  # fmt: skip
        yield cluster


@pytest.fixture(scope="module")
def client(cluster):
    with distributed.Client(cluster) as client:
        yield client


def check_merged(merged: ShardedRun, reference: tuple, transport: bool) -> None:
    summary, history, report = reference
    assert exact(merged.summary(SPEC.threshold, SPEC.threshold_rule, warn=False).as_dict()) == exact(summary)
    # the keyword is Ensemble.summary's (the former spelling still works, and warns)
    assert merged.summary(threshold_rule=SPEC.threshold_rule, warn=False) is merged.summary(warn=False)
    with pytest.warns(DeprecationWarning, match="threshold_rule"):
        assert merged.summary(rule=SPEC.threshold_rule, warn=False) is merged.summary(warn=False)
    assert same_history(merged.history, history)
    assert exact(merged.history.as_dict()) == exact(history.as_dict())
    assert exact(merged.history.convergence().__dict__) == exact(history.convergence().__dict__)
    if transport:
        assert exact(merged.report()) == exact(report)


def test_the_memory_limit_is_below_the_whole_ensemble():
    assert shard_bytes(SPEC, SPEC.points) > MEMORY_LIMIT >= shard_bytes(SPEC, -(-SPEC.points // 2))


@pytest.mark.parametrize("transport", [False, True])
@pytest.mark.parametrize("shards", [2, 3, 7])
def test_sharded_run_equals_the_single_machine_bit_for_bit(client, references, shards, transport):
    merged = run_sharded(SPEC, client, shards, transport=transport)
    assert merged.shards == shards and merged.points == SPEC.points
    check_merged(merged, references[transport], transport)


@pytest.mark.parametrize("transport", [False, True])
def test_one_shard_equals_the_single_machine_bit_for_bit(references, transport):
    # one shard holds the whole ensemble: a worker of its own, in this process, without a limit
    with (
        distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as whole,
        distributed.Client(whole) as client,
    ):
        check_merged(run_sharded(SPEC, client, 1, transport=transport), references[transport], transport)


def test_a_shard_that_does_not_fit_a_worker_is_refused_with_the_numbers(client):
    with pytest.raises(
        ResourceError, match=r"shards = 1: a shard of 2000 points needs .* memory limit of"
    ) as err:
        run_sharded(SPEC, client, 1)
    assert "at least 2" in str(err.value)


@pytest.mark.parametrize(("threads", "gate"), [(1, "as found"), (3, "as found"), (3, "off")])
def test_a_shards_row_records_are_the_gain_and_lyapunovs_numerator_bit_for_bit(monkeypatch, threads, gate):
    """A shard's row records, made in pieces on the run's threads (the last piece short), are
    ``momentum_gain`` and ``log_stretch + log(hypot(dx, dp))`` as NumPy gives them over the whole
    arrays, non-finite tangents and -0.0 included: the stretch in the kernel where the libm gate
    allows it, else in NumPy."""
    from concurrent.futures import ThreadPoolExecutor

    from warpratchet.cluster import _shard
    from warpratchet.kernels import _rows
    from warpratchet.observables import momentum_gain

    monkeypatch.setattr(_shard, "RECORD_PIECE", 64)
    if gate == "off":
        monkeypatch.setattr(_rows, "_verdicts", {**_rows._verdicts, "libm": False})
    ens = Ensemble.sample(SPEC.params, 1001, "torus", seed=2, threads=1).run(40)
    views = ens.state()
    views["dx"][[3, 500]] = [np.inf, np.nan]
    views["dp"][999] = -0.0
    views["dx"][999] = 0.0  # a zero norm: log gives -inf
    gain, stretch = np.full((2, 1001), np.nan)
    with ThreadPoolExecutor(threads) as pool:
        _shard._row_records(views, gain, stretch, pool if threads > 1 else None, threads)
    with np.errstate(divide="ignore", invalid="ignore"):
        want = views["log_stretch"] + np.log(np.hypot(views["dx"], views["dp"]))
    assert [bits(float(v)) for v in gain] == [bits(float(v)) for v in momentum_gain(views)]
    assert [bits(float(v)) for v in stretch] == [bits(float(v)) for v in want]


@pytest.mark.parametrize("init", ["strip", "torus", "grid"])
def test_shards_draw_their_slice_of_the_ensembles_points(init):
    """A shard's records are the whole run's rows of its points (here without a cluster)."""
    spec = RunSpec(K=3.0, b1=0.1, b2=0.01, points=50, steps=40, seed=9, threads=1, init=init)
    n = 49 if init == "grid" else 50  # a grid rounds down to a square
    whole = run_shard(spec, 0, n)
    parts = [run_shard(spec, lo, hi) for lo, hi in shard_bounds(n, 3)]
    assert [(r.lo, r.hi) for r in parts] == shard_bounds(n, 3) and parts[-1].hi == n
    for name in ("gain", "stretch"):
        assert np.array_equal(np.concatenate([getattr(r, name) for r in parts], axis=1), getattr(whole, name))


class StopsAt(Observer):
    """Fails the run at its first regular chunk end at or after ``step``; notes where runs begin."""

    def __init__(self, step: int) -> None:
        self.step = step
        self.began: list[int] = []

    def begin(self, ensemble, target_step):
        self.began.append(ensemble.step)

    def after_chunk(self, ensemble, seconds):
        if ensemble.step >= self.step:
            raise RuntimeError(f"stopped at step {ensemble.step}")


@pytest.mark.parametrize("transport", [False, True])
def test_a_shard_continues_from_its_archive_bit_for_bit(tmp_path, transport):
    """A shard stopped after a checkpoint and run again equals one that ran through (no cluster)."""
    whole = run_shard(SPEC, 500, 1300, transport)
    with pytest.raises(RuntimeError, match="stopped at step 1500"):
        run_shard(SPEC, 500, 1300, transport, [StopsAt(1500)], tmp_path, 1, checkpoint_every=500)
    notes = StopsAt(SPEC.steps + 1)
    again = run_shard(SPEC, 500, 1300, transport, [notes], tmp_path, 1, checkpoint_every=500)
    assert notes.began == [1500]  # from the checkpoint, not from step 0
    assert again.gain is None and again.folder is not None  # its rows are on disk only
    for name in ("steps", "block_steps", "block_gain", "block_ftle", "counts", "open_counts"):
        assert exact(getattr(again, name)) == exact(getattr(whole, name)), name
    for k in range(len(whole.steps)):
        assert exact(list(again.row(k))) == exact(list(whole.row(k)))


class Fails(Observer):
    """Makes every shard fail after its first chunk."""

    def after_chunk(self, ensemble, seconds):
        raise ValueError(f"no luck at step {ensemble.step}")


def test_a_shard_that_fails_fails_the_run_with_its_reason(client):
    # Both shards fail; whichever the client sees first is named, with its own points.
    reason = r"shard (0 of 2 \(points 0\.\.999\)|1 of 2 \(points 1000\.\.1999\)) failed: ValueError: no luck"
    with pytest.raises(RuntimeError, match=reason):
        run_sharded(SPEC, client, 2, observers=[Fails()])


class HoldsOnce(Observer):
    """Holds the first shard that passes its checkpoint at step 1000 until the test has killed its
    worker; the retry notes the step it starts from.

    Events, not sleeps: the shard tells the test its process id and that it is mid-run, then
    waits for "go", which the test sets once the worker is dead (the retry, which sees "killed",
    runs through).
    """

    def __init__(self) -> None:
        self.held = False

    def begin(self, ensemble, target_step):
        if distributed.Event("i28-killed").is_set() and ensemble.step > 0:
            distributed.Variable("i28-resumed-at").set(ensemble.step)

    def after_chunk(self, ensemble, seconds):
        if self.held or ensemble.step < 1000:
            return
        self.held = True
        if distributed.Event("i28-killed").is_set():
            return
        if not distributed.Lock("i28-first").acquire(blocking=False):
            return  # another shard is the one held
        distributed.Variable("i28-pid").set(os.getpid())
        distributed.Event("i28-reached").set()
        distributed.Event("i28-go").wait(timeout=900)  # the test kills this worker before


def test_a_worker_killed_mid_run_is_retried_from_its_checkpoint_with_the_result_unchanged(
    client, references, tmp_path
):
    from concurrent.futures import ThreadPoolExecutor

    work = tmp_path / "shards"
    with ThreadPoolExecutor(1) as pool:
        future = pool.submit(
            run_sharded, SPEC, client, 2, observers=[HoldsOnce()], workdir=work, checkpoint_every=500
        )
        try:
            assert distributed.Event("i28-reached", client=client).wait(timeout=600)
            pid = distributed.Variable("i28-pid", client=client).get(timeout=60)
            os.kill(pid, signal.SIGKILL)
            distributed.Event("i28-killed", client=client).set()
        finally:
            distributed.Event("i28-go", client=client).set()
        merged = future.result(timeout=600)
    assert pid not in client.run(os.getpid).values()  # the held shard's worker did die
    assert distributed.Variable("i28-resumed-at", client=client).get(timeout=60) == 1000
    check_merged(merged, references[False], False)
    # the same call again finds every shard complete in its archive: nothing runs, same numbers
    check_merged(run_sharded(SPEC, client, 2, workdir=work), references[False], False)


# -- the command line ---------------------------------------------------------------------------------
def run_json(capsys, *flags: str) -> dict:
    import json

    from warpratchet.cli import main

    size = ["--points", str(SPEC.points), "--steps", str(SPEC.steps), "--seed", str(SPEC.seed)]
    code = main(run_argv(*size, "--threads", "1", "--json", "--quiet", *flags))
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("transport", [False, True])
def test_run_with_scheduler_prints_the_single_machine_numbers(capsys, cluster, tmp_path, transport):
    extra = ["--transport"] if transport else []
    here = run_json(capsys, *extra)
    work = str(tmp_path / "shards")
    there = run_json(
        capsys, "--scheduler", cluster.scheduler_address, "--shards", "3", "--workdir", work, *extra
    )
    assert there.pop("shards") == 3 and there.pop("scheduler") == cluster.scheduler_address
    assert there.pop("workdir") == work and sorted(os.listdir(work))[:2] == ["run.json", "shard-0000.h5"]
    # each shard's archive is an ordinary one: it verifies, and holds its points at the last step
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive

    assert verify_archive(os.path.join(work, "shard-0002.h5"))[0] == []
    with open_archive(os.path.join(work, "shard-0002.h5")) as arc:
        assert (arc.points, arc.checkpoint_step) == (SPEC.points - 2 * SPEC.points // 3, SPEC.steps)
    timing = ("seconds", "point_steps_per_second")
    assert {k: v for k, v in there.items() if k not in timing} == {
        k: v for k, v in here.items() if k not in timing
    }


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--shards", "2"], "--shards needs --scheduler ADDRESS"),
        (["--workdir", "w"], "--workdir needs --scheduler ADDRESS"),
        (["--scheduler", "tcp://127.0.0.1:1", "--snapshot-every", "5"], "--snapshot-every needs --out FILE"),
        (["--scheduler", "tcp://127.0.0.1:1", "--force"], "--force needs --out FILE"),
        (
            ["--scheduler", "tcp://127.0.0.1:1", "--rerun", "r.rrd"],
            "--rerun does not go with --scheduler: its",
        ),
        (
            ["--scheduler", "tcp://127.0.0.1:1", "--out", "o.h5", "--snapshot-points", "101"],
            "is more than the",
        ),
        (["--scheduler", "tcp://127.0.0.1:1", "--shards", "0"], "shards = 0 is outside the allowed range"),
    ],
)
def test_run_refuses_cluster_flags_it_cannot_honour(capsys, tmp_path, flags, message):
    assert message in refused(capsys, run_argv("--points", "100", "--steps", "10", *flags))


def test_a_workdir_of_another_run_is_refused(client, tmp_path):
    other = RunSpec(K=3.0, b1=0.1, b2=0.01, points=100, steps=50, seed=4, threads=1)
    run_sharded(other, client, 2, workdir=tmp_path)
    with pytest.raises(ValueError, match=r"holds the shards of another run \(it differs in seed\)"):
        run_sharded(RunSpec(**{**other.as_dict(), "seed": 5}), client, 2, workdir=tmp_path)


def test_the_benchmark_runs_and_its_runs_are_identical():
    from support import quick_benchmark

    report = quick_benchmark("cluster_scaling.py")
    assert report["identical"] and [r["workers"] for r in report["rows"]] == [None, 1, 2]
    assert [m["shards"] for m in report["merge"]] == [1, 4, 16, 64]  # --quick: up to 64 shards
    assert set(report["merge_projected_seconds"]) == {"100", "1000"}


# -- one archive of the whole run ------------------------------------------------------------------------
def test_out_is_one_archive_of_the_whole_run(client, references, tmp_path):
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive

    out = tmp_path / "run.h5"
    merged = run_sharded(SPEC, client, 3, out=out)
    summary, history, _ = references[False]
    with open_archive(out) as arc:
        assert (arc.points, arc.checkpoint_step, arc.target_step) == (SPEC.points, SPEC.steps, SPEC.steps)
        assert same_history(arc.history, history)
        series = arc.series
        assert list(series["step"]) == history.rows["step"]
        assert exact(float(series["A"][-1])) == exact(summary["A"])
        assert exact(float(series["A_stderr"][-1])) == exact(summary["A_stderr"])
        snapshots = arc.h5["snapshots"]  # none in a merged archive, named as in every new one
        assert len(arc.snapshots) == 0 and arc.h5.attrs["format_minor"] == 2
        assert "finite_time_acceleration" in snapshots and "A" not in snapshots
        state, step = arc.checkpoint()
        initial = arc.initial
        ds = arc.to_xarray()
    assert ds.sizes["step"] == len(history.rows["step"])
    # the per-point data are the shards' own, through virtual datasets, in global order
    whole = Ensemble.sample(SPEC.params, SPEC.points, SPEC.init, SPEC.seed, threads=2)
    assert all(np.array_equal(initial[k], v) for k, v in whole.state().items())
    whole.run(SPEC.steps)
    assert step == SPEC.steps and all(np.array_equal(state[k], v) for k, v in whole.state().items())
    assert verify_archive(out)[0] == []
    assert merged.points == SPEC.points
    from warpratchet.cli import main

    assert main(["inspect", str(out)]) == 0 and main(["verify", str(out)]) == 0
    with pytest.raises(ValueError, match="exists; choose a new path"):
        run_sharded(SPEC, client, 3, out=out)


def test_run_with_scheduler_and_out_the_same_command_again_reports_it(capsys, cluster, tmp_path, references):
    from warpratchet import open_archive

    out = str(tmp_path / "run.h5")
    flags = ("--scheduler", cluster.scheduler_address, "--shards", "2", "--out", out)
    first = run_json(capsys, *flags)
    assert first["archive"] == out and os.path.dirname(first["workdir"]) == out + ".shards"
    with open_archive(out) as arc:
        assert same_history(arc.history, references[False][1])
    stamp = os.stat(out).st_mtime_ns
    again = run_json(capsys, *flags)
    timing = ("seconds", "point_steps_per_second")
    assert {k: v for k, v in again.items() if k not in timing} == {
        k: v for k, v in first.items() if k not in timing
    }
    assert os.stat(out).st_mtime_ns == stamp  # reported, not rewritten
    other = run_argv("--points", "100", "--steps", "10", *flags)
    assert "exists and is not an archive of this run" in refused(capsys, other)


def test_a_merge_this_machine_cannot_hold_is_refused_with_the_numbers():
    from warpratchet.cluster import check_merge

    check_merge(SPEC.points, transport=True)  # a few hundred kB
    with pytest.raises(ResourceError, match=r"points = 10000000000000 \(the merge of a sharded run\) needs"):
        check_merge(10**13)


def test_run_with_scheduler_for_a_human(capsys, cluster):
    from warpratchet.cli import main

    address = cluster.scheduler_address
    assert main(run_argv("--points", "300", "--steps", "200", "--scheduler", address, "--shards", "3")) == 0
    out, err = capsys.readouterr()
    assert "300 points x 200 steps" in out and f"  3 shards on the cluster at {address}\n" in out
    assert f"connecting to the Dask scheduler at {address}" in err


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of 300 points for the summaries and variances (one machine's and the merge's alike):
    an ensemble of 2000 points has 7 of them, and shards cut inside some."""
    import warpratchet.observables

    monkeypatch.setattr(warpratchet.observables, "SUMMARY_CHUNK", 300)  # the history's chunks too


@pytest.mark.parametrize("transport", [False, True])
def test_a_merge_over_blocks_cut_by_the_shards_equals_the_single_machine(small_blocks, transport):
    """The merge's tasks run here, over records (no cluster: the blocks' size is this process's)."""
    reference = single_machine(transport)
    for shards in (1, 2, 3, 7):
        bounds = shard_bounds(SPEC.points, shards)
        assert shards == 1 or any(lo % 300 for lo, _ in bounds)  # a block shared by two shards
        merged = ShardedRun(SPEC, [run_shard(SPEC, lo, hi, transport) for lo, hi in bounds], transport)
        check_merged(merged, reference, transport)


def test_a_merge_of_shards_far_smaller_than_a_block_equals_the_single_machine(small_blocks):
    """1000 shards of 2 points, each block of 300 points cut by 150 of them: the records of one
    run of the whole ensemble, sliced (the merge's tasks see the numbers of 1000 shards' runs;
    the block subsample is all in the first shard), merged here, without a cluster."""
    from dataclasses import replace

    reference = single_machine(False)
    whole = run_shard(SPEC, 0, SPEC.points)
    records = [
        replace(whole, lo=lo, hi=hi, gain=whole.gain[:, lo:hi], stretch=whole.stretch[:, lo:hi])
        if lo == 0
        else replace(
            whole,
            lo=lo,
            hi=hi,
            gain=whole.gain[:, lo:hi],
            stretch=whole.stretch[:, lo:hi],
            block_gain=whole.block_gain[:, :0],
            block_ftle=whole.block_ftle[:, :0],
        )
        for lo, hi in shard_bounds(SPEC.points, 1000)
    ]
    check_merged(ShardedRun(SPEC, records, False), reference, False)


def test_the_merge_gathers_numbers_per_block_and_row_not_per_point():
    """What the merge's tasks hand to the client for 400 and 40000 points (one block) differs only
    by the width of its integer counts, and is below one row of 40000 points' records."""
    gathered = []
    for points in (400, 40000):
        spec = RunSpec(K=3.0, b1=0.1, b2=0.01, points=points, steps=300, seed=3, threads=1)
        records = [run_shard(spec, lo, hi, True) for lo, hi in shard_bounds(points, 3)]
        merged = ShardedRun(spec, records, True)
        gathered.append(merged.gathered_bytes)
    assert abs(gathered[1] - gathered[0]) < gathered[0] // 100 and gathered[1] < 16 * 40000


def test_out_of_a_transport_run_holds_the_merged_transport_group(client, tmp_path):
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive

    out = tmp_path / "run.h5"
    run_sharded(SPEC, client, 3, transport=True, out=out)
    whole = TransportEnsemble.sample(SPEC.params, SPEC.points, SPEC.init, SPEC.seed, threads=2)
    whole.threshold, whole.threshold_rule = SPEC.threshold, SPEC.threshold_rule
    whole.run(SPEC.steps, chunk_steps=SPEC.chunk_steps)
    expected = whole.transport_state()
    with open_archive(out) as arc:
        rows = arc.transport
        _, step, state = arc.checkpoint_with_transport()
        features = arc.features
    assert "transport" in features
    assert rows["step"][-1] == SPEC.steps and np.array_equal(rows["counts"][-1], expected.counts)
    assert step == SPEC.steps and np.array_equal(state.counts, expected.counts)
    assert all(np.array_equal(state.carry[k], v) for k, v in expected.carry.items())
    assert np.array_equal(state.spread_steps, expected.spread_steps)
    assert exact(state.spread) == exact(expected.spread)
    assert verify_archive(out)[0] == []


# -- snapshots and --force -----------------------------------------------------------------------------
SNAPSHOT_EVERY = 1500


def single_machine_archive(path, snapshot_points: int, transport: bool = False) -> None:
    """The single machine's archive of SPEC with snapshots, as ``warpratchet run --out`` writes it."""
    from warpratchet.archive import ArchiveSink

    kind = TransportEnsemble if transport else Ensemble
    ensemble = kind.sample(SPEC.params, SPEC.points, SPEC.init, SPEC.seed, threads=2)
    ensemble.threshold, ensemble.threshold_rule = SPEC.threshold, SPEC.threshold_rule
    sink = ArchiveSink(
        path, ensemble, snapshot_every=SNAPSHOT_EVERY, snapshot_points=snapshot_points,
        chunk_steps=SPEC.chunk_steps, threshold=SPEC.threshold, threshold_rule=SPEC.threshold_rule,
    )  # fmt: skip
    try:
        ensemble.run(SPEC.steps, [sink], chunk_steps=sink.chunk_steps)
    finally:
        sink.close()


def snapshot_datasets(path) -> dict:
    """Every dataset of ``/snapshots``: dtype, shape, dimension scales, units and long name, bits."""
    import h5py

    with h5py.File(path, "r") as f:
        g = f["snapshots"]
        return {
            name: (
                ds.dtype.str,
                ds.shape,
                [[scale.name for scale in dim.values()] for dim in ds.dims],
                {k: ds.attrs[k] for k in ("units", "long_name")},
                ds[()].tobytes(),
            )  # fmt: skip
            for name, ds in g.items()
        }


@pytest.mark.parametrize("shards, snapshot_points", [(1, 150), (2, 150), (3, 150), (7, 5)])
def test_out_exposes_the_single_machines_snapshots_bit_for_bit(cluster, tmp_path, shards, snapshot_points):
    """With 150 points every shard boundary cuts the subsample; with 7 shards and 5 points some
    shards hold none of it."""
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive
    from warpratchet.cli import main

    single, out = tmp_path / "single.h5", tmp_path / "run.h5"
    single_machine_archive(single, snapshot_points)
    if shards == 1:  # one shard holds the whole ensemble: a worker without the memory limit
        with (
            distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as whole,
            distributed.Client(whole) as client,
        ):
            run_sharded(
                SPEC, client, 1, out=out, snapshot_every=SNAPSHOT_EVERY, snapshot_points=snapshot_points
            )
    else:
        with distributed.Client(cluster) as client:
            run_sharded(
                SPEC, client, shards, out=out, snapshot_every=SNAPSHOT_EVERY, snapshot_points=snapshot_points
            )
    expected = snapshot_datasets(single)
    assert snapshot_datasets(out) == expected and len(expected) > 2
    with open_archive(single) as arc:
        reference, settings, xr = arc.snapshots, arc.settings, arc.to_xarray("snapshots")
    with open_archive(out) as arc:
        snapshots = arc.snapshots
        assert {k: arc.settings[k] for k in ("snapshot_every", "snapshot_points")} == {
            k: settings[k] for k in ("snapshot_every", "snapshot_points")
        }
        ds = arc.to_xarray("snapshots")
        from viz.record import replay

        assert replay(arc, tmp_path / "replay.rrd").frames == [1500, 3000]
    assert list(snapshots.steps) == [1500, 3000] and snapshots.indices.size == snapshot_points
    assert exact(snapshots.__dict__) == exact(reference.__dict__)
    assert ds.sizes == xr.sizes and all(exact(ds[k].values) == exact(xr[k].values) for k in xr.variables)
    assert verify_archive(out)[0] == []
    assert main(["inspect", str(out)]) == 0 and main(["verify", str(out)]) == 0


def test_force_replaces_out_only_when_the_new_run_is_complete(capsys, cluster, tmp_path, references):
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive

    out = tmp_path / "run.h5"
    other = RunSpec(K=3.0, b1=0.1, b2=0.01, points=300, steps=200, seed=4, threads=1)
    with distributed.Client(cluster) as client:
        run_sharded(other, client, 2, out=out)
        with pytest.raises(RuntimeError, match="failed: ValueError: no luck"):
            run_sharded(SPEC, client, 2, out=out, force=True, observers=[Fails()])
    with open_archive(out) as arc:  # the failed run left the file and its shards as they were
        assert (arc.points, arc.settings["seed"]) == (300, 4)
    assert verify_archive(out)[0] == []
    flags = ("--scheduler", cluster.scheduler_address, "--shards", "2", "--out", str(out))
    assert "exists and is not an archive of this run" in refused(capsys, run_argv(*flags))
    report = run_json(capsys, *flags, "--force", "--snapshot-every", "1500", "--snapshot-points", "10")
    assert report["archive"] == str(out)
    with open_archive(out) as arc:
        assert same_history(arc.history, references[False][1])
        assert list(arc.snapshots.steps) == [1500, 3000] and arc.checkpoint_step == SPEC.steps
    assert verify_archive(out)[0] == [] and sorted(os.listdir(tmp_path)) == ["run.h5", "run.h5.shards"]
    assert len(os.listdir(tmp_path / "run.h5.shards")) == 1  # the replaced run's shards are gone


def archive_content(path) -> tuple:
    """What an archive holds: its points and seed, its history's rows, its checkpoint's bits."""
    from warpratchet import open_archive

    with open_archive(path) as arc:
        state, step = arc.checkpoint()
        return arc.points, arc.settings["seed"], exact(arc.history.as_dict()), step, exact(state)


def publishes_then_fails(real):
    def publish(tmp, path, replace):
        real(tmp, path, replace=replace)
        raise KeyboardInterrupt("killed after the rename")

    return publish


def fails(*args, **kwargs):
    raise KeyboardInterrupt("killed here")


@pytest.mark.parametrize(
    "where, published",
    [
        ("warpratchet._cluster_archive._write_snapshots", False),  # writing the new file
        ("warpratchet._cluster_archive.sync_h5", False),  # making it durable
        ("warpratchet.archive._writer.publish", False),  # just before the rename
        ("warpratchet.archive._writer.publish", True),  # just after the rename
        ("warpratchet.cluster._run._remove_other_runs", True),  # removing the replaced run's shards
    ],
)
def test_force_killed_at_each_step_of_publishing_leaves_a_consistent_archive(
    monkeypatch, client, tmp_path, where, published
):
    """The file at ``out`` reads its own run's shards at every instant: the old run's until the
    rename, the new run's after; the same call again completes the replacement."""
    import warpratchet.archive._writer as writer
    from warpratchet.archive import verify_archive

    out = tmp_path / "run.h5"
    other = RunSpec(K=3.0, b1=0.1, b2=0.01, points=300, steps=200, seed=4, threads=1)
    run_sharded(other, client, 2, out=out)
    old = archive_content(out)
    new_run = dict(out=out, force=True, snapshot_every=SNAPSHOT_EVERY, snapshot_points=10)
    with monkeypatch.context() as patched:
        fault = publishes_then_fails(writer.publish) if published and where.endswith("publish") else fails
        patched.setattr(where, fault)
        with pytest.raises(KeyboardInterrupt):
            run_sharded(SPEC, client, 2, **new_run)
    assert verify_archive(out)[0] == []
    content = archive_content(out)
    assert (content == old) != published and content[:2] == (
        (SPEC.points, SPEC.seed) if published else (300, 4)
    )
    run_sharded(SPEC, client, 2, **new_run)  # the same call again
    assert verify_archive(out)[0] == [] and archive_content(out)[:2] == (SPEC.points, SPEC.seed)
    assert len(os.listdir(f"{out}.shards")) == 1


def test_a_shard_continued_from_its_archive_keeps_its_snapshots(tmp_path):
    """The snapshot at step 1500, taken before the stop, comes back from the shard's records."""
    import h5py

    from warpratchet.cluster import snapshot_file

    def snapshots(folder):
        with h5py.File(snapshot_file(folder), "r") as f:
            return {name: f[name][()].tobytes() for name in f}

    through = run_shard(SPEC, 500, 1300, False, [], tmp_path / "a", 1, 500, SNAPSHOT_EVERY, 150)
    with pytest.raises(RuntimeError, match="stopped at step 1500"):
        run_shard(SPEC, 500, 1300, False, [StopsAt(1500)], tmp_path / "b", 1, 500, SNAPSHOT_EVERY, 150)
    notes = StopsAt(SPEC.steps + 1)
    again = run_shard(SPEC, 500, 1300, False, [notes], tmp_path / "b", 1, 500, SNAPSHOT_EVERY, 150)
    assert notes.began == [1500]
    assert snapshots(again.folder) == snapshots(through.folder) and len(snapshots(through.folder)) > 2


def test_a_shards_memory_counts_the_snapshots_it_keeps():
    from warpratchet.archive._format import SNAPSHOT_FIELDS

    more = shard_bytes(SPEC, 700, snapshots=(SNAPSHOT_EVERY, 1000)) - shard_bytes(SPEC, 700)
    assert more == 2 * len(SNAPSHOT_FIELDS) * 8 * 700  # two snapshots of at most its 700 points


def test_a_missing_shard_file_is_refused_by_every_reader_and_flagged_by_verify(capsys, cluster, tmp_path):
    """HDF5 reads a virtual dataset whose source file is gone as fill values: every route that reads
    the merged archive names the missing file instead (``/initial``, the checkpoint, the snapshots)."""
    import glob

    from warpratchet import open_archive
    from warpratchet.archive import ArchiveError, verify_archive
    from warpratchet.cli import main

    out = str(tmp_path / "run.h5")
    flags = ("--scheduler", cluster.scheduler_address, "--shards", "2", "--out", out)
    snap = ("--snapshot-every", str(SNAPSHOT_EVERY), "--snapshot-points", "10")
    first = run_json(capsys, *flags, *snap)
    for pattern in ("shard-0001.h5", "shard-0001.records/snapshots.h5"):
        [moved] = glob.glob(os.path.join(out + ".shards", "**", pattern), recursive=True)
        os.rename(moved, tmp_path / "away.h5")
        name = os.path.basename(moved)
        with pytest.raises(ArchiveError, match=f"reads from .*{name}, which is missing"):
            open_archive(out)
        problems = verify_archive(out)[0]
        assert problems and all(f"{name}, which is missing" in p for p in problems)
        assert main(["verify", out]) == 1 and f"{name}, which is missing" in capsys.readouterr().out
        for argv in (["inspect", out], ["resume", out, "--steps", "4000"], run_argv(*flags, *snap)):
            assert f"{name}, which is missing" in refused(capsys, argv)
        os.rename(tmp_path / "away.h5", moved)
        assert verify_archive(out)[0] == [] and main(["inspect", out]) == 0
        capsys.readouterr()
        again = run_json(capsys, *flags, *snap)
        timing = ("seconds", "point_steps_per_second")
        assert {k: v for k, v in again.items() if k not in timing} == {
            k: v for k, v in first.items() if k not in timing
        }


def test_out_of_a_transport_run_with_snapshots_equals_the_single_machines(client, tmp_path):
    from warpratchet import open_archive
    from warpratchet.archive import verify_archive

    def transport(path) -> tuple:
        with open_archive(path) as arc:
            _, step, state = arc.checkpoint_with_transport()
            carry = {k: exact(v) for k, v in state.carry.items()}
            held = (exact(state.counts), carry, exact(state.spread_steps), exact(state.spread))
            return exact(arc.transport), step, held

    single, out = tmp_path / "single.h5", tmp_path / "run.h5"
    single_machine_archive(single, 150, transport=True)
    run_sharded(SPEC, client, 3, transport=True, out=out, snapshot_every=SNAPSHOT_EVERY, snapshot_points=150)
    expected = snapshot_datasets(single)
    assert snapshot_datasets(out) == expected and len(expected) > 2
    assert transport(out) == transport(single)
    assert verify_archive(out)[0] == []
