"""The chunked run loop behind :meth:`Ensemble.run <warpratchet.ensemble.Ensemble.run>`.

One idea: advance an ensemble to a target step in chunks, tell the observers after each, and
stop only *between* chunks. Three guarantees follow from that:

* **Consistent on Ctrl-C and SIGTERM.** A Warp launch cannot be cancelled, and a chunk runs as
  several launches (one per CPU thread): stopping halfway would leave some points a chunk ahead
  of the step counter (``ens.step`` 0, the arrays at step 20000, every later ``A_n`` divided by
  the wrong ``n``). So while the loop runs, SIGINT and SIGTERM are *deferred*: the handler notes
  the signal, the chunk in flight finishes, every observer sees the step where the run stops
  (``after_chunk``: an archive writes its row there, then checkpoints in ``end``), every
  observer's ``end`` runs, and then the signal is delivered: SIGINT to the original handler
  (Python's raises :class:`KeyboardInterrupt`), SIGTERM to its handler or, for the default
  action (death), as :class:`~warpratchet.errors.Terminated` (exit status 143). A signal that
  comes while the observers write (a second Ctrl-C during the checkpoint) is noted, not acted
  on. The ensemble's ``step`` always matches its arrays. Deferral needs the main thread and a
  Python handler or the default action; otherwise signals are left alone.
* **Observers always end.** ``end`` is called on every observer whose ``begin`` ran, whatever
  happened (an exception, an interrupt), even if another observer's ``end`` raises; the first
  error is re-raised after all of them.
* **An error inside a chunk is never silent.** If advancing raises (a failed launch), the
  in-flight launches are waited for and the ensemble is marked undefined: its points may sit at
  different steps, so :meth:`Ensemble.run` and :meth:`Ensemble.summary` refuse it afterwards.

Stops. An observer may define ``next_stop(step) -> int | None``: the next step after ``step``
at which it wants to see the ensemble (a recording's log-spaced frames). The loop then ends a
chunk there too; only the observers that asked for that step are called there, so an archive
still gets exactly one row per regular chunk (results never depend on chunking anyway), except
at the step where the run stops, which every observer sees. The
``seconds`` passed to ``after_chunk`` are the kernel seconds since *that* observer was last
called.

Stops without a meeting. On more than one CPU thread every stop is a barrier: the next launch
waits for the slowest shard, and the threads sleep while the observers work (what that costs a
small ensemble run long: benchmarks/README.md, "stop_cost.py"). Where every observer that asks
for stops takes copies (``Observer.takes_state_copies``: a
:class:`~warpratchet.history.History` does), the threads instead carry pieces of the ensemble
through the chunk's stops without waiting for each other, copying each piece's state at each, and
the observers get, at their stops, a read-only copy of the ensemble at that step
(``Ensemble._advance_copying``), while the threads go on: the threads meet once a chunk, and the
one whose core the observers share takes fewer pieces. The copies are the state's bits, so every
number is the one a stop would give. At most :data:`~warpratchet.ensemble.COPY_BYTES` of copies
are held; past that the chunk ends at the next stop as above.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from .errors import ParameterError, Terminated

__all__ = [
    "Observer",
    "check_observers",
    "deferred_interrupts",
    "run_chunks",
    "register_sink",
    "open_sink",
    "default_threads",
    "default_chunk_steps",
]


def default_threads() -> int:
    """One thread per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_chunk_steps(points: int, point_steps: int = 1_000_000_000) -> int:
    """Steps per chunk of a run: about ``point_steps`` point-steps (by default 1e9), between 16
    and 10^5 steps.

    A chunk end is a launch boundary: every point's state is stored and loaded once more, and
    every observer is called. The observers that must see a given step ask for it themselves
    (``next_stop``: a history's rows, a recording's frames), so a run's own chunk ends only move
    its progress bar and let Ctrl-C stop it: they can be few, so that they cost little beside the
    kernel (what a chunk and a stop take on a CPU: benchmarks/README.md). An archive writes a row
    at each of its chunk ends and asks for shorter chunks (:func:`warpratchet.archive.schedule`).
    """
    return int(min(100_000, max(16, point_steps // max(points, 1))))


class Observer:
    """Receives the ensemble after each chunk of :meth:`Ensemble.run <warpratchet.ensemble.Ensemble.run>`.

    Subclass and override what you need; archives, recordings and progress bars are observers.
    An observer may also define ``next_stop(step) -> int | None``, the next step after ``step``
    at which it wants ``after_chunk`` called (see the module docstring).
    """

    #: True for an observer whose ``next_stop`` depends on the step alone and whose ``after_chunk``
    #: at those stops only reads the ensemble (its state, views, summaries): the run may then hand
    #: it, there, a read-only copy of the ensemble at that step while its threads go on (see the
    #: module docstring).
    takes_state_copies = False

    def begin(self, ensemble: Any, target_step: int) -> None:
        """Called once before the first chunk; the run will stop at ``target_step``."""

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        """Called after each chunk; ``seconds``: kernel wall time since this observer was last called."""

    def end(self, ensemble: Any) -> None:
        """Called once after the last chunk (also when the run is interrupted or fails)."""


def check_observers(observers: Any) -> list[Any]:
    """``observers`` as a list, each with callable ``begin``, ``after_chunk`` and ``end``.

    Checked before the run starts, so that a wrong entry (``None``, a function) is one clear
    :class:`~warpratchet.errors.ParameterError` rather than an ``AttributeError`` halfway.
    """
    if isinstance(observers, (str, bytes)) or not hasattr(observers, "__iter__"):
        raise ParameterError(f"observers = {observers!r} is not a sequence of Observers")
    listed = list(observers)
    for i, obs in enumerate(listed):
        missing = [name for name in ("begin", "after_chunk", "end") if not callable(getattr(obs, name, None))]
        if missing:
            raise ParameterError(
                f"observers[{i}] = {obs!r} is not an Observer (it has no {', '.join(missing)}; "
                "subclass warpratchet.Observer)"
            )
    return listed


#: The signals a run defers: Ctrl-C, and the stop a scheduler (SLURM, PBS, Kubernetes) sends
#: before it kills a job.
DEFERRED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _Deferred:
    """SIGINT or SIGTERM noted while a run is between two safe points."""

    def __init__(self) -> None:
        self.pending: tuple[int, Any] | None = None
        self.previous: dict[int, Any] = {}

    def handler(self, signum: int, frame: Any) -> None:
        # The first signal is delivered; a SIGTERM after a Ctrl-C still ends the process.
        if self.pending is None or signum == signal.SIGTERM:
            self.pending = (signum, frame)

    def deliver(self) -> None:
        """Act on the noted signal as its handler before the run would have."""
        signum, frame = self.pending
        previous = self.previous[signum]
        if callable(previous):
            previous(signum, frame)  # Python's SIGINT handler raises KeyboardInterrupt
        else:  # SIGTERM's default action: end the process, but by unwinding (files close)
            raise Terminated()


def _deferrable(signum: int, handler: Any) -> bool:
    """Whether a run may defer ``signum`` whose handler is ``handler``: a Python handler, or
    SIGTERM's default action; never an ignored signal or a handler installed outside Python."""
    return callable(handler) or (signum == signal.SIGTERM and handler == signal.SIG_DFL)


@contextlib.contextmanager
def deferred_interrupts() -> Iterator[_Deferred]:
    """Defer SIGINT and SIGTERM for the duration of the block; deliver the signal on exit.

    Yields an object whose ``pending`` is set once a signal arrived. Outside the main thread, or
    for a signal that is ignored or has no Python handler (SIGTERM: or its default action),
    nothing is changed. Blocks nest: an inner block delivers to the outer one's handler, which
    notes the signal again.
    """
    deferred = _Deferred()
    if threading.current_thread() is threading.main_thread():
        for signum in DEFERRED_SIGNALS:
            previous = signal.getsignal(signum)
            if _deferrable(signum, previous):
                deferred.previous[signum] = previous
                signal.signal(signum, deferred.handler)
    try:
        yield deferred
    finally:
        for signum, previous in deferred.previous.items():
            signal.signal(signum, previous)
        if deferred.pending is not None:
            deferred.deliver()


def _end_all(ensemble: Any, observers: Sequence[Any]) -> None:
    """``end`` on every observer; the first exception is raised once all have run."""
    error: BaseException | None = None
    for obs in observers:
        try:
            obs.end(ensemble)
        except BaseException as exc:  # noqa: BLE001 - every sink must get its end, then re-raise
            error = error or exc
    if error is not None:
        raise error


def _next_stops(stoppers: Sequence[Any], step: int) -> list[int | None]:
    stops = []
    for obs in stoppers:
        stop = obs.next_stop(step)
        stops.append(None if stop is None or stop <= step else int(stop))
    return stops


def _plan(stoppers: Sequence[Any], step: int, chunk_end: int, most: int) -> list[tuple[int, list[Any]]]:
    """The first ``most`` stops after ``step`` and before ``chunk_end`` that the ``stoppers`` ask
    for, in order, each with the observers that asked for it."""
    plan: list[tuple[int, list[Any]]] = []
    while len(plan) < most:
        stops = _next_stops(stoppers, step)
        stop = min([chunk_end] + [s for s in stops if s is not None])
        if stop == chunk_end:
            break
        plan.append((stop, [obs for obs, s in zip(stoppers, stops, strict=True) if s == stop]))
        step = stop
    return plan


def _copies(ensemble: Any, stoppers: Sequence[Any], pool: Any) -> int:
    """How many stops in a row the run's threads may go through without meeting, their observers
    given copies of the state there (``Ensemble._advance_copying``): on more than one CPU thread,
    where every observer that stops the run takes copies (:class:`Observer`), as many as the
    ensemble's copies hold; else none."""
    if pool is None or not stoppers or not all(getattr(obs, "takes_state_copies", False) for obs in stoppers):
        return 0
    return getattr(ensemble, "_copies_that_fit", lambda: 0)()


def run_chunks(
    ensemble: Any,
    target: int,
    observers: Sequence[Any],
    chunk_steps: int,
    pool: ThreadPoolExecutor | None,
) -> None:
    """Advance ``ensemble`` to ``target`` in chunks ending at global multiples of ``chunk_steps``.

    Parameters
    ----------
    ensemble : Ensemble
        Advanced with its ``_advance(steps, pool)``.
    target : int
        Global step to reach.
    observers : sequence of Observer
        ``begin``, ``after_chunk`` after every chunk (and at the stops they ask for), ``end``.
    chunk_steps : int
        Steps per regular chunk.
    pool : ThreadPoolExecutor or None
        CPU shards' threads (shut down here, after the observers' ``end``, which may still
        compute a summary on them).
    """
    stoppers = [obs for obs in observers if callable(getattr(obs, "next_stop", None))]
    unseen = {id(obs): 0.0 for obs in observers}  # kernel seconds since each was last called
    mark = 0.0  # when the kernel seconds were last counted into unseen

    def tell(called: Sequence[Any], state: Any, at: float) -> None:
        """``after_chunk(state, ...)`` on ``called``, the kernel seconds counted up to ``at``."""
        nonlocal mark
        for key in unseen:
            unseen[key] += at - mark
        mark = at
        for obs in called:
            elapsed, unseen[id(obs)] = unseen[id(obs)], 0.0
            obs.after_chunk(state, elapsed)

    began: list[Any] = []
    with deferred_interrupts() as interrupt:
        try:
            for obs in observers:
                began.append(obs)
                obs.begin(ensemble, target)
            while ensemble.step < target and interrupt.pending is None:
                step = ensemble.step
                # Chunk ends sit at global multiples of chunk_steps, so a run resumed from any
                # step reports (and archives) at the same steps as an uninterrupted one.
                chunk_end = min(step + chunk_steps - step % chunk_steps, target)
                copies = _copies(ensemble, stoppers, pool)
                plan = _plan(stoppers, step, chunk_end, copies + 1)
                copied = plan[:copies]
                stop, askers = plan[copies] if copies < len(plan) else (chunk_end, None)
                mark = time.perf_counter()  # the observers' time between chunks is not the kernel's

                def at_copy(k: int, copy: Any, at: float, copied: list = copied) -> None:
                    tell(copied[k][1], copy, at)

                try:
                    if copied:
                        ensemble._advance_copying([s for s, _ in copied], stop, pool, at_copy)
                    else:
                        ensemble._advance(stop - step, pool)
                except BaseException as exc:
                    # _advance returns or raises only after every shard has stopped writing.
                    if ensemble.step == step:
                        ensemble.undefined = (
                            f"an error stopped a chunk from step {step} to {stop} partway "
                            f"({type(exc).__name__}: {exc}); points may be at different steps"
                        )
                    raise
                called = list(observers) if askers is None else askers
                tell(called, ensemble, time.perf_counter())
                if interrupt.pending is not None:
                    # The run stops here: the observers that did not ask for this step see it
                    # too (an archive's row, so that its checkpoint can stand here).
                    seen = {id(obs) for obs in called}
                    tell([obs for obs in observers if id(obs) not in seen], ensemble, mark)
        finally:
            try:
                _end_all(ensemble, began)
            finally:
                if pool is not None:
                    pool.shutdown(wait=True)


#: Sinks that :meth:`Ensemble.run <warpratchet.ensemble.Ensemble.run>` opens by keyword
#: (``archive=path``): keyword -> ``factory(ensemble, target, chunk_steps)``. The packages that
#: provide them sit above the run loop, so they register here and the loop never imports them.
_SINKS: dict[str, Callable[[Any, Any, int | None], Any]] = {}


def register_sink(keyword: str, factory: Callable[[Any, Any, int | None], Any]) -> None:
    """Let ``Ensemble.run(keyword=target)`` open its sink with ``factory(ensemble, target, chunk_steps)``."""
    _SINKS[keyword] = factory


def open_sink(keyword: str, ensemble: Any, target: Any, chunk_steps: int | None) -> Any:
    """The sink that ``Ensemble.run(keyword=target)`` asks for, from its registered factory."""
    factory = _SINKS.get(keyword)
    if factory is None:
        raise ValueError(f"{keyword}= has no sink registered; import warpratchet first")
    return factory(ensemble, target, chunk_steps)
