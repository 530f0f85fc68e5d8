"""Ensembles of points of the map: state and the run loop (samplers in :mod:`warpratchet.sampling`).

An :class:`Ensemble` owns the per-point state on a Warp device and advances it with the kernel
of :mod:`warpratchet.kernels`. State per point (all float64 unless noted, 56 bytes in all)::

    x            position in [0, 1)
    q            fractional momentum in [0, 1)
    winding      int64, whole units of momentum gained since step 0
    p0           initial momentum (as given; only p0 mod 1 enters the dynamics)
    dx, dp       tangent vector under DM, started at (1, 0)
    log_stretch  log of the tangent norm removed by renormalisation

so ``p_n = floor(p0) + winding + q`` and ``A_n = (winding + q - frac(p0)) / n`` (Eq. An) keep
full precision however far the momentum runs. On the CPU the points are sharded over one
Python thread per core (a Warp CPU launch runs on one thread and releases the GIL); each point
is independent, so results are bitwise identical for any thread count.
"""

from __future__ import annotations

import functools
import operator
import os
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

import numpy as np
import warp as wp

from . import kernels
from .errors import (
    ParameterError,
    check_choice,
    check_count,
    check_optional,
    check_real,
    renamed_attribute,
    renamed_keyword,
)
from .kernels import INTERLEAVE, RENORM_CHECK_EVERY, RENORM_THRESHOLD
from .limits import MAX_POINTS, MAX_STEP, available_memory, check_kernel_range, check_memory, format_bytes
from .observables import (
    KEPT_BYTES,
    SUMMARY_BYTES_PER_POINT,
    SUMMARY_CHUNK,
    TREE_LEAF,
    Summary,
    _pieces,
    lyapunov_threshold,
    summarize,
    summarize_with_variance,
    summary_chunks,
)
from .params import MapParams
from .runloop import (
    Observer,
    check_observers,
    default_chunk_steps,
    default_threads,
    deferred_interrupts,
    open_sink,
    run_chunks,
)
from .sampling import _BUILD_CHUNK, grid_nodes, sample_grid, sample_strip, sample_torus, sampled_chunks
from .spec import MAX_CHUNK_STEPS, MAX_THREADS, SAMPLERS, check_setting
from .state import STATE_FIELDS, check_initial, check_state, initial_state

__all__ = [
    "STATE_FIELDS",
    "INTERLEAVE",
    "RENORM_CHECK_EVERY",
    "RENORM_THRESHOLD",
    "SAMPLERS",
    "Observer",
    "Ensemble",
    "sample_strip",
    "sample_torus",
    "sample_grid",
    "grid_nodes",
    "default_threads",
    "default_chunk_steps",
]

#: The state arrays the kernels take, in their argument order (p0 is not needed to advance).
_KERNEL_FIELDS = ("x", "q", "winding", "dx", "dp", "log_stretch")
#: Most bytes of state copies that a run keeps for the stops inside one chunk
#: (:meth:`Ensemble._advance_copying`; at most half the memory available).
COPY_BYTES = 64 << 20
#: Most pieces per thread, and fewest points per piece, of the points that
#: :meth:`Ensemble._advance_copying`'s threads take one after another.
PIECES_PER_THREAD = 4
PIECE_POINTS = 2048
# The initial-condition samplers (``SAMPLERS``, ``sample_*``, ``grid_nodes``) live in
# :mod:`warpratchet.sampling`; they are re-exported here, where callers have always found them.


class Ensemble:
    """Points of the map (Eq. cpem) and their tangents, advanced together.

    Parameters
    ----------
    params : MapParams
        The map.
    x0, p0 : array_like, shape (n,)
        Initial positions (taken mod 1) and momenta.
    device : str, optional
        Warp device, e.g. ``"cpu"`` or ``"cuda:0"``; default ``"cpu"``.
    threads : int, optional
        CPU threads to shard over (default: one per core). Ignored on a GPU.
    init, seed : str, int, optional
        Provenance recorded in archives: the initial conditions' name (``"user"`` for arrays; a
        name of :data:`SAMPLERS` from :meth:`sample`) and their seed. ``sampler=`` is the former
        spelling of ``init=`` (a :class:`DeprecationWarning`).
    """

    sampler = renamed_attribute("Ensemble", "sampler", "init")

    @renamed_keyword("sampler", "init")
    def __init__(
        self,
        params: MapParams,
        x0: np.ndarray,
        p0: np.ndarray,
        *,
        device: str | None = None,
        threads: int | None = None,
        init: str = "user",
        seed: int | None = None,
        _chunks=None,
    ) -> None:
        # _chunks (internal, from sample): (n, iterable of (lo, x, p)) instead of x0 and p0.
        if _chunks is None:
            x0, p0 = check_initial(x0, p0)
            step = _BUILD_CHUNK
            _chunks = (
                x0.size,
                ((lo, x0[lo : lo + step], p0[lo : lo + step]) for lo in range(0, x0.size, step)),
            )
        points, chunks = _chunks
        self._setup(params, points, 0, device, threads, init, seed)
        for lo, x, p in chunks:
            self._fill(lo, x, p)

    def _fill(self, lo: int, x0: np.ndarray, p0: np.ndarray) -> None:
        """The initial state of points ``lo, lo + 1, ...`` from their positions and momenta."""
        for name, values in initial_state(x0, p0).items():
            self._put(name, lo, values, x0.size)

    def _put(self, name: str, lo: int, values, count: int) -> None:
        """Write ``values`` (``count`` of them, or one scalar for all) into ``name[lo : lo + count]``.

        Through a host array of ``count`` elements, on every device: callers pass chunks, so no
        full-size temporary is made.
        """
        dtype = np.int64 if name == "winding" else np.float64
        host = np.ascontiguousarray(np.broadcast_to(np.asarray(values, dtype=dtype), (count,)))
        source = wp.array(host, dtype=self._arrays[name].dtype, device="cpu", copy=False)
        wp.copy(self._arrays[name], source, dest_offset=lo, count=count)

    def _setup(self, params, points, step, device, threads, init, seed) -> None:
        """Everything but the state, which is allocated here (uninitialised) and filled by the caller.

        Every argument is checked before anything is allocated: the map against what the kernels
        carry, the points against :data:`~warpratchet.limits.MAX_POINTS` and this machine's memory.
        """
        params = check_kernel_range(params)
        points = check_count("points", points, 1, MAX_POINTS)
        if threads is None:
            threads = default_threads()
        self.threads = check_count("threads", threads, 1, MAX_THREADS)
        kernels.init_warp()
        self.params = params
        try:
            self.device = str(wp.get_device(device or "cpu"))
        except Exception:
            available = ", ".join(str(d) for d in wp.get_devices())
            raise ValueError(f"device = {device!r} is not available (Warp sees: {available})") from None
        self.check_fits(points, self.device)
        self.init = init
        self.seed = seed
        self.step = int(step)
        self._arrays = {
            name: wp.empty(points, dtype=wp.int64 if name == "winding" else wp.float64, device=self.device)
            for name in STATE_FIELDS
        }
        self.points = points
        self._summaries: dict[tuple, Summary] = {}  # (step, threshold, threshold_rule): summary at this step
        self._row_buffers: dict[str, np.ndarray] = {}  # the summaries' arrays, kept for the next row
        self._views: dict[str, np.ndarray] = {}  # array()'s zero-copy views on the CPU
        self._views_live = wp.get_device(self.device).is_cpu
        self._variance: tuple | None = None  # (step, variance of p_n - p_0) of the last summary
        self._recorded: dict[tuple[int, int], tuple] = {}  # shard (lo, hi): (what it uses, its launch)

    @classmethod
    def bytes_per_point(cls) -> int:
        """Bytes of device memory per point: the state (:data:`STATE_FIELDS`, 56 B) and the
        per-point arrays of the kernel variant (:attr:`_kernel`; e.g. 24 B for MEGNO and the FLI)."""
        state = 8 * len(STATE_FIELDS)  # float64 and int64
        extra = cls._kernel.variant.arrays.vars.values()
        return state + sum(wp.types.type_size_in_bytes(v.type.dtype) for v in extra)

    @classmethod
    def check_fits(cls, points: int, device: str = "cpu") -> None:
        """ResourceError, before anything is allocated, if ``points`` do not fit this machine.

        On the CPU the state and one summary's working memory share the host's memory (the
        summary reduces :data:`~warpratchet.observables.SUMMARY_CHUNK` points at a time, each
        needing :data:`~warpratchet.observables.SUMMARY_BYTES_PER_POINT`); on a GPU the state
        must fit the device, and the host holds a copy to summarise.
        """
        kernels.init_warp()
        state = cls.bytes_per_point()
        what = f"points = {points}"
        summary = min(points, SUMMARY_CHUNK) * SUMMARY_BYTES_PER_POINT
        if wp.get_device(device).is_cpu:
            detail = f"{state} B of state per point and {format_bytes(summary)} to summarise it"
            check_memory(what, points * state + summary, detail)
            return
        free = getattr(wp.get_device(device), "free_memory", None)
        check_memory(what, points * state, f"{state} B per point on {device}", available=free or None)
        check_memory(f"{what} (host copy)", points * 8 * len(STATE_FIELDS) + summary)

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def sample(
        cls,
        params: MapParams,
        points: int,
        init: str = "strip",
        seed: int = 0,
        *,
        device: str | None = None,
        threads: int | None = None,
    ) -> Ensemble:
        """An ensemble from a named sampler (``"strip"``, ``"torus"`` or ``"grid"``).

        Seeded with ``numpy.random.default_rng(seed)``: the same arguments give the same points.
        """
        points = check_count("points", points, 1)
        seed = check_setting("seed", seed)  # an int64, as archives and sweep files store it
        check_choice("init", init, SAMPLERS)
        # Built chunk by chunk into the state (the same points as sample_strip, sample_torus and
        # sample_grid): no full-size temporaries, so 10^8 points need little more than their state.
        chunks = sampled_chunks(params, init, points, seed)
        return cls(params, None, None, device=device, threads=threads, init=init, seed=seed, _chunks=chunks)

    @classmethod
    @renamed_keyword("sampler", "init")
    def from_state(
        cls,
        params: MapParams,
        state: dict[str, np.ndarray],
        step: int,
        *,
        device: str | None = None,
        threads: int | None = None,
        init: str = "user",
        seed: int | None = None,
    ) -> Ensemble:
        """Rebuild an ensemble exactly from :meth:`state` output (checkpoints, exact restart)."""
        step = check_count("step", step, 0, MAX_STEP)
        if not isinstance(state, Mapping):
            raise ParameterError(f"state = {type(state).__name__} is not a dict of arrays (Ensemble.state())")
        missing = [name for name in STATE_FIELDS if name not in state]
        if missing:
            raise ValueError(f"state is missing fields {missing}")
        sizes = {np.shape(state[name]) for name in STATE_FIELDS}
        if len(sizes) != 1 or len(next(iter(sizes))) != 1:
            raise ValueError(f"state fields must be 1-D arrays of one length; got shapes {sizes}")
        check_state(state)
        obj = cls.__new__(cls)
        obj._setup(params, len(state["x"]), step, device, threads, init, seed)
        for name in STATE_FIELDS:
            values = np.asarray(state[name])
            for lo in range(0, obj.points, _BUILD_CHUNK):
                chunk = values[lo : lo + _BUILD_CHUNK]
                obj._put(name, lo, chunk, chunk.size)
        return obj

    # -- access -------------------------------------------------------------------------------
    def array(self, name: str) -> np.ndarray:
        """One state field as a NumPy array, shape ``(points,)``, read-only.

        On the CPU a zero-copy view of the live state (copy it before the next run); read-only,
        since only a run changes the state (:meth:`summary` keeps each step's; see :meth:`from_state`).
        """
        values = self._views.get(name)
        if values is None:
            values = self._arrays[name].numpy()
            values.flags.writeable = False
            if self._views_live:  # a view of the memory itself (not a copy off a GPU): kept
                self._views[name] = values
        return values

    def views(self) -> dict[str, np.ndarray]:
        """Every state field as :meth:`array` gives it (keys :data:`STATE_FIELDS`): zero-copy on the
        CPU, for reading the state where it lies; valid until the next run."""
        return {name: self.array(name) for name in STATE_FIELDS}

    def state(self) -> dict[str, np.ndarray]:
        """A copy of every state field (keys :data:`STATE_FIELDS`)."""
        return {name: np.array(self.array(name), copy=True) for name in STATE_FIELDS}

    def momentum(self) -> np.ndarray:
        """Absolute momentum ``p_n = floor(p0) + winding + q``, shape ``(points,)``."""
        return np.floor(self.array("p0")) + self.array("winding") + self.array("q")

    # -- dynamics -----------------------------------------------------------------------------
    #: Kernel that advances one shard. A subclass that carries extra per-point accumulators
    #: swaps it and lists the accumulators in :meth:`_extra_arrays` (see ``sumrule``).
    _kernel = kernels.advance_map

    def _extra_arrays(self) -> list[wp.array]:
        """Arrays passed to :attr:`_kernel` after the state arrays, shape ``(points,)`` each."""
        return []

    def _launch(self, lo: int, hi: int, step0: int, steps: int) -> None:
        arrays = [self._arrays[name] for name in _KERNEL_FIELDS]
        extra = self._extra_arrays()
        # The shard's launch, recorded once and replayed at each chunk (the arrays and the map do
        # not change between chunks); recorded again if the kernel or an array is another object.
        uses = (self._kernel, *arrays, *extra)
        kept = self._recorded.get((lo, hi))
        if kept is None or len(kept[0]) != len(uses) or not all(map(operator.is_, kept[0], uses)):
            shard = [a[lo:hi] for a in arrays], [a[lo:hi] for a in extra]
            kept = self._recorded[(lo, hi)] = uses, self._kernel.recorded(self.device, *shard, self.params)
        self._kernel.replay(kept[1], step0, steps)

    def _shards(self) -> list[tuple[int, int]]:
        """The points ``(lo, hi)`` of each CPU thread's launch: :attr:`threads` near-equal shards."""
        return [(part.start, part.stop) for part in _pieces(range(self.points), self.threads)]

    def _advance(self, steps: int, pool: ThreadPoolExecutor | None) -> None:
        self._summaries = {}  # the state moves on
        self._variance = None
        # One launch advances at most MAX_LAUNCH_STEPS (its loop counter is 32-bit): a longer
        # chunk is split, so that no step is dropped.
        while steps > 0:
            todo = min(steps, kernels.MAX_LAUNCH_STEPS)
            if pool is None:
                self._launch(0, self.points, self.step, todo)
                wp.synchronize_device(self.device)
            else:
                # This thread takes the first shard itself (a Warp CPU launch releases the GIL)
                # rather than wait for the pool's threads to wake.
                first, *rest = self._shards()
                futures = [pool.submit(self._launch, lo, hi, self.step, todo) for lo, hi in rest]
                try:
                    self._launch(*first, self.step, todo)
                finally:
                    wait(futures)  # a failed shard's error waits until no shard writes the arrays
                for future in futures:
                    future.result()
            self.step += todo
            steps -= todo

    def _copies_that_fit(self) -> int:
        """How many stops :meth:`_advance_copying` may carry the shards through at once: the copies
        of the state that fit in :data:`COPY_BYTES` (and half the memory available); 0 for an
        ensemble whose shards carry more than the state (a kernel variant's arrays, its own launch)."""
        # the shards' launches bypass _advance: an ensemble with its own (or its own _launch: a
        # kernel variant's, a probe's) keeps its stops
        own = (getattr(self._advance, "__func__", None), getattr(self._launch, "__func__", None))
        if own != (Ensemble._advance, Ensemble._launch) or self._extra_arrays():
            return 0
        spare = available_memory()
        budget = COPY_BYTES if spare is None else min(COPY_BYTES, spare // 2)
        return budget // (8 * len(_KERNEL_FIELDS) * self.points)

    def _copying_pieces(self) -> list[tuple[int, int]]:
        """The points ``(lo, hi)`` of the pieces :meth:`_advance_copying`'s threads take one after
        another: up to :data:`PIECES_PER_THREAD` per thread, of at least :data:`PIECE_POINTS` points,
        cut at whole blocks of lanes."""
        count = max(self.threads, min(PIECES_PER_THREAD * self.threads, self.points // PIECE_POINTS))
        block = 2 * INTERLEAVE  # a launch's last block of lanes is a whole block's work
        cuts = [min(self.points, round(self.points * j / count / block) * block) for j in range(count + 1)]
        cuts[-1] = self.points
        return [(lo, hi) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True) if hi > lo]

    def _advance_copying(
        self,
        stops: Sequence[int],
        end: int,
        pool: ThreadPoolExecutor,
        at_copy: Callable[[int, Ensemble, float], None],
    ) -> None:
        """Advance to global step ``end`` on ``pool``'s threads through ``stops`` (increasing, before
        ``end``) without a meeting at any of them, copying the state at each; meanwhile, on this
        thread, ``at_copy(k, copy, at)`` for each stop in order as soon as every point's state has
        been copied at ``stops[k]`` (``copy``: the ensemble at that step, read-only; ``at``:
        ``time.perf_counter()`` then).

        The points are cut into pieces (:meth:`_copying_pieces`), and the work into one task per
        piece and stretch between two stops, taken by the threads in order: every piece's stretch to
        the first stop, then to the second, and so on, a piece's stretch only after its previous one.
        So a run's threads meet once, at ``end``, instead of at every stop, a thread that the
        observers' work slows down takes fewer tasks than the others, and the observers of the stops
        work while the threads go on: the copies are the state's bits, so whatever they compute is
        what they would have computed at a stop. A thread's error is raised once every thread has
        stopped, with ``step`` unchanged; an error of ``at_copy`` once every point is at ``end``,
        with ``step = end``.
        """
        self._summaries = {}  # the state moves on
        self._variance = None
        views = self.views()
        copies = self._copy_buffers(len(stops))
        pieces = self._copying_pieces()
        targets = [*stops, end]
        tasks = len(targets) * len(pieces)
        done = [0] * len(pieces)  # stretches each piece has gone through
        copied = [0] * len(stops)  # pieces copied at each stop
        taken = [0]  # tasks taken
        failed = []
        # One lock, two conditions: the threads wait for a piece's previous stretch, this thread
        # for a stop's whole copy, and each is woken only for what it waits for (a thread woken
        # for nothing takes a core from the launches).
        lock = threading.Lock()
        piece_done = threading.Condition(lock)
        stop_copied = threading.Condition(lock)

        def work() -> None:
            try:
                while True:
                    with lock:
                        task = taken[0]
                        taken[0] += 1
                        if task >= tasks:
                            return
                        k, i = divmod(task, len(pieces))
                        piece_done.wait_for(lambda i=i, k=k: failed or done[i] == k)
                        if failed:
                            return
                    lo, hi = pieces[i]
                    step = self.step if k == 0 else targets[k - 1]
                    while step < targets[k]:  # a launch's loop counter is 32-bit (MAX_LAUNCH_STEPS)
                        todo = min(targets[k] - step, kernels.MAX_LAUNCH_STEPS)
                        self._launch(lo, hi, step, todo)
                        step += todo
                    if k < len(stops):
                        for name, copy in copies[k].items():
                            copy[lo:hi] = views[name][lo:hi]
                    with lock:
                        done[i] = k + 1
                        piece_done.notify_all()
                        if k < len(stops):
                            copied[k] += 1
                            if copied[k] == len(pieces):
                                stop_copied.notify()
            except BaseException:
                with lock:
                    failed.append(True)
                    piece_done.notify_all()
                    stop_copied.notify()
                raise

        futures = [pool.submit(work) for _ in range(min(self.threads, len(pieces)))]
        error = None
        try:
            for k, stop in enumerate(stops):
                with lock:
                    stop_copied.wait_for(lambda k=k: failed or copied[k] == len(pieces))
                if failed:
                    break
                at_copy(k, self._state_copy(stop, copies[k], views["p0"]), time.perf_counter())
        except BaseException as exc:  # noqa: BLE001 - raised once no thread writes the arrays
            error = exc
        wait(futures)
        for future in futures:
            future.result()
        self.step = end
        if error is not None:
            raise error

    def _copy_buffers(self, count: int) -> list[dict[str, np.ndarray]]:
        """``count`` sets of arrays for copies of the state (less ``p0``, which a run never
        changes), kept from one chunk of a run to the next (fresh pages cost more than the copy)."""
        kept = self.__dict__.setdefault("_copies", [])
        while len(kept) < count:
            kept.append(
                {
                    name: np.empty(self.points, dtype=np.int64 if name == "winding" else np.float64)
                    for name in _KERNEL_FIELDS
                }
            )
        return kept[:count]

    def _state_copy(self, step: int, arrays: Mapping[str, np.ndarray], p0: np.ndarray) -> Ensemble:
        """This ensemble as it was at ``step``, from copies of its state: a :class:`_StateCopy`."""
        copy = _StateCopy.__new__(_StateCopy)
        copy.__dict__.update(self.__dict__)
        views = {"p0": p0}
        for name, values in arrays.items():
            views[name] = values.view()
            views[name].flags.writeable = False
        copy.step = step
        copy._views, copy._views_live = views, True
        copy._summaries, copy._variance = {}, None
        copy._run_pool, copy.threads = None, 1  # its summary on the observer's thread: the run's are busy
        return copy

    #: Why the state cannot be trusted (set when an error stopped a chunk partway), else None.
    undefined: str | None = None
    _run_pool: ThreadPoolExecutor | None = None
    _running = False  # inside run(): summaries keep what the next row reuses (_keep_bytes)

    @property
    def run_pool(self) -> ThreadPoolExecutor | None:
        """The threads of the run in progress (CPU, more than one thread), else None.

        Its launches are done whenever an observer is called, so an observer may run its
        per-point work on them (the history rows and the transport spread do); it must not shut
        them down: the run does, after the observers' ``end``. A copy of the state that a run hands
        an observer while its threads go on (:mod:`warpratchet.runloop`) has none."""
        return self._run_pool

    def run(
        self,
        steps: int,
        observers: Sequence[Observer] | Iterable[Observer] = (),
        chunk_steps: int | None = None,
        *,
        progress: bool = False,
        archive: str | os.PathLike | None = None,
    ) -> Ensemble:
        """Advance every point by ``steps`` iterations, in chunks, calling observers after each.

        Safe to interrupt: Ctrl-C (SIGINT) or SIGTERM stops the run at the end of the chunk in
        flight, with ``step`` matching the arrays, every observer's ``end`` called and the archive
        checkpointed at that step and closed, then raises ``KeyboardInterrupt`` (SIGTERM:
        :class:`~warpratchet.errors.Terminated`, exit status 143); ``run(rest, archive=same)``
        continues from there (:mod:`warpratchet.runloop`).

        Parameters
        ----------
        steps : int
            Iterations to add (``>= 0``).
        observers : sequence of Observer
            Called with :meth:`Observer.after_chunk` after every chunk.
        chunk_steps : int, optional
            Steps per chunk (default :func:`default_chunk_steps`, or the archive's); chunks end at
            global steps that are multiples of it, and at the end of the run. The result does not
            depend on it.
        progress : bool
            Draw a progress bar (``tqdm.auto``: a widget in Jupyter, text elsewhere).
        archive : str or PathLike, optional
            Stream the run into this HDF5 archive (:mod:`warpratchet.archive`) with its own
            chunking and the run's history (:class:`~warpratchet.history.History`, group
            ``/history``): a new file, or one this ensemble was archived to before and is still at
            the checkpoint of (then the run is appended). Closed when the run ends.

        Raises
        ------
        ValueError
            Bad ``steps``/``chunk_steps``, an archive that holds another run, or an ensemble whose
            state is undefined after an error (:attr:`undefined`).
        """
        if self.undefined is not None:
            raise ValueError(f"this ensemble cannot be run: {self.undefined}; rebuild it")
        steps = check_count("steps", steps, 0, MAX_STEP - self.step)
        observers = check_observers(observers)
        sink = None
        if archive is not None:
            sink = open_sink("archive", self, archive, chunk_steps)
            if sink.history is not None:
                observers.append(sink.history)  # its rows end chunks at their steps
            observers.append(sink)
            chunk_steps = sink.chunk_steps
        if progress:
            from .progress import ProgressBar

            observers.insert(0, ProgressBar(notebook=True))
        if chunk_steps is None:
            chunk_steps = default_chunk_steps(self.points)
        # Launches split longer chunks, but a chunk is also the unit of progress, checkpoints and
        # Ctrl-C: one of more than 2^31 steps is never what a user meant.
        chunk_steps = check_count("chunk_steps", chunk_steps, 1, MAX_CHUNK_STEPS)
        try:
            # Compile (or load from cache) before any thread launches.
            self._kernel.load(self.device, table=self.params.table)
            use_pool = wp.get_device(self.device).is_cpu and self.threads > 1 and self.points > 1
            pool = ThreadPoolExecutor(self.threads, thread_name_prefix="warpratchet") if use_pool else None
            self._run_pool = pool  # the observers' per-point work runs on it too (run_pool)
            self._running = True
            run_chunks(self, self.step + steps, observers, chunk_steps, pool)
        finally:
            self._run_pool = None
            self._running = False
            self._let_go_of_kept()  # a run's memory, not the ensemble's
            self.__dict__.pop("_copies", None)
            if sink is not None:
                with deferred_interrupts():  # a second Ctrl-C does not cut the archive's close
                    sink.close()
        return self

    def known_ftle(self, step: int) -> np.ndarray | None:
        """Every point's FTLE at ``step`` if the ensemble computed it already at its current step
        (for another observable), else None: :meth:`summary` takes it instead of computing it again.
        A plain ensemble never has it (:class:`~warpratchet.transport.TransportEnsemble` does)."""
        return None

    def known_variance(self, step: int) -> float | None:
        """The variance (ddof 1) of every point's ``p_n - p_0`` at ``step`` if :meth:`summary` computed
        it at the current step (in the same passes), else None: a history row takes it instead of
        computing it again."""
        values = self._variance
        return values[1] if values is not None and values[0] == step == self.step else None

    def _summary_on_threads(
        self, threshold: float | None, threshold_rule: str, ftle: np.ndarray | None
    ) -> Summary | None:
        """:func:`~warpratchet.observables.summarize_with_variance` of the current state on this
        ensemble's threads (the variance kept for :meth:`known_variance`), or None to leave the
        summary to ``summarize``: a value not finite.

        During :meth:`run` the threads are the run's own, idle between its launches; outside a
        run a pool lives for this summary only. On a GPU the state is copied to the host once and
        summarised there on the host's threads."""
        if self.step < 1:
            return None
        if threshold is None:
            threshold = lyapunov_threshold(self.step, threshold_rule)
        views = self.views()
        args = (views, self.step, threshold, ftle)
        # the per-point pass and the sums in kernels, NumPy's bits (the FTLE in the pass where its
        # functions are NumPy's here, else NumPy's own just before it: kernels.RowPass)
        options: dict[str, Any] = {"buffers": self._row_buffers, "keep_bytes": self._keep_bytes()}
        few = self.points < 4 * TREE_LEAF  # a few leaves: not worth the threads, nor the launches
        if not few:
            options["leaf_pass"] = functools.partial(kernels.RowPass, buffers=self._row_buffers)
            options["leaf_sums"] = kernels.leaf_sums
        # kernels take equal shares in equal times: one piece per thread (fewer gathered parts
        # to join); NumPy's passes balance better in smaller pieces
        batches = self.threads if "leaf_pass" in options else 4 * self.threads
        if self.threads < 2 or few:
            done = summarize_with_variance(*args, **options)
        elif self.run_pool is not None:
            done = summarize_with_variance(*args, pool=self.run_pool, batches=batches, **options)
        else:
            with ThreadPoolExecutor(self.threads, thread_name_prefix="warpratchet-rows") as pool:
                done = summarize_with_variance(*args, pool=pool, batches=batches, **options)
        if not self._running:
            self._let_go_of_kept()  # no next row to reuse them
        if done is None:
            self._row_buffers.clear()  # summarize needs the memory (SUMMARY_BYTES_PER_POINT)
            return None
        self._variance = (self.step, done[1])
        return done[0]

    def _keep_bytes(self) -> int:
        """Bytes of its chunks' values a summary may keep for its second pass instead of making
        them again (``summarize_with_variance``'s ``keep_bytes``; in :attr:`_row_buffers`, from one
        row of a run to the next): :data:`~warpratchet.observables.KEPT_BYTES` with more than one
        chunk, where half the memory available now and what they hold already holds that; else 0,
        and what they hold is let go."""
        spare = available_memory() if len(summary_chunks(self.points)) > 1 else None
        held = sum(values.nbytes for name, values in self._row_buffers.items() if name.startswith("kept"))
        if spare is not None and KEPT_BYTES <= (spare + held) // 2:
            return KEPT_BYTES
        self._let_go_of_kept()
        return 0

    def _let_go_of_kept(self) -> None:
        """Drop the chunks' values that summaries kept (:meth:`_keep_bytes`)."""
        for name in [name for name in self._row_buffers if name.startswith("kept")]:
            del self._row_buffers[name]

    @renamed_keyword("rule", "threshold_rule")
    def summary(
        self, threshold: float | None = None, threshold_rule: str = "strict", *, warn: bool = True
    ) -> Summary:
        """:func:`~warpratchet.observables.summarize` of the current state: A, FTLE, chaotic fraction.

        ``threshold`` (or, when it is None, ``threshold_rule``) as ``summarize`` takes them. Computed once per
        step and threshold: the history's row, the archive's series row and the run's report at
        the same step share it (bitwise the same Summary).

        Warns with :class:`~warpratchet.observables.UnreliableWarning` when the run is too short,
        or has too few chaotic points, to estimate A (``Summary.reliable`` is False; ``reason``
        says why); ``warn=False`` leaves that to the caller (sinks, which report it themselves).
        """
        if self.undefined is not None:
            raise ValueError(f"this ensemble has no summary: {self.undefined}")
        threshold = check_optional(check_real, "threshold", threshold, 0.0)
        key = (self.step, threshold, threshold_rule if threshold is None else None)
        result = self._summaries.get(key)
        if result is None:
            ftle = self.known_ftle(self.step)
            result = self._summary_on_threads(threshold, threshold_rule, ftle)
            if result is None:
                result = summarize(self.views(), self.step, threshold, threshold_rule, ftle)
            self._summaries[key] = result
        if warn:
            result.warn()
        return result

    def __repr__(self) -> str:
        p = self.params
        force = f"b1={p.b1!r}, b2={p.b2!r}" if p.is_paper else f"table={p.table!r}"
        return (
            f"Ensemble(K={p.K!r}, {force}, points={self.points}, step={self.step}, "
            f"device={self.device!r}, threads={self.threads})"
        )


class _StateCopy(Ensemble):
    """An ensemble as it was at a stop of a run that has gone on (:meth:`Ensemble._advance_copying`):
    its state is read-only copies, so it gives the summaries and views of that step and cannot be
    run."""

    def run(self, *args: Any, **kwargs: Any) -> Ensemble:
        raise ValueError(f"this is a copy of the state at step {self.step} during a run; it cannot be run")

    def _advance(self, steps: int, pool: ThreadPoolExecutor | None) -> None:
        raise ValueError(f"this is a copy of the state at step {self.step} during a run; it cannot be run")
