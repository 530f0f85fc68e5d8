"""``advance_map_transport``: :data:`~warpratchet.kernels.advance_map` plus return times and flights.

The orbit and tangent are bitwise those of ``advance_map`` (the same step loop); a hook after
every step counts, per point, two kinds of events into log2-binned histograms (bin ``k`` holds
lengths in ``[2^k, 2^(k+1))``, :data:`BINS` bins), exact int64 counts:

* **return times to B** (Eq. B): the gaps between consecutive global steps ``n`` at which ``x_n``
  lies in B. ``last_visit`` is the global step of the point's last visit (-1: none yet; the
  caller sets 0 for a point that starts in B, so its first gap counts from step 0); a visit at
  step ``n`` records the gap ``n - last_visit``.
* **flights**: maximal runs of consecutive steps whose whole-unit momentum gain (the step fact
  ``gain``) is the same nonzero integer ``v``. ``flight_gain`` is the gain of the run in progress
  (0: a run of steps that gained nothing, never recorded), ``flight_start`` the global step of
  its first step; a step whose gain differs ends the run (length ``n - flight_start``, into the
  histogram of the sign of ``v``) and starts a new one.

Two implementations, one count: the portable hooks (plain Warp, a lane at a time; what CUDA
runs) and the CPU hooks of :mod:`._transport_cpu` (codes per step, decoded in blocks as byte
vectors), which ``tests/analyses/test_transport.py`` checks against each other and against the NumPy twin
:mod:`warpratchet.transport._twin`.

The three per-point values are the carry state: runs still open at the end of a launch continue
in the next one, so chunking, thread count and resuming (the carry is checkpointed with the
state) never change a count. A portable thread counts into its own histogram and adds it to the
launch's histogram array at the end (an atomic add: one array for all CUDA threads); the CPU
hooks add to the launch's array directly (one array per CPU launch); integer sums do not depend
on the order.
"""

import numpy as np
import warp as wp

from ..errors import KernelError
from ._advance import AdvanceKernel, Variant
from ._runtime import CPU_ISA
from ._step import (
    INTERLEAVE,
    Coefficients,
    Lanes,
    cpu_steps_source,
    depth_first_steps_source,
    load_lanes,
    store_lane_vector,
)
from ._transport_cpu import (
    BINS,
    CLAIM_CPU,
    CONFLICT_WORD,
    DECODE_CPU,
    FINISH_CPU,
    RECORD_CPU,
    ROWS,
    SCRATCH_BYTES,
    record_avx512,
)

__all__ = ["BINS", "HISTOGRAMS", "CARRY_FIELDS", "advance_map_transport", "TRANSPORT"]

#: The histograms, in the order of the kernel's histogram array (``3 * BINS`` int64).
HISTOGRAMS = ("return_times", "flights_plus", "flights_minus")
#: Per-point carry state (int64 arrays), in the kernel's argument order.
CARRY_FIELDS = ("last_visit", "flight_gain", "flight_start")

_LaneInts = wp.types.vector(length=INTERLEAVE, dtype=wp.int64)
_Counts = wp.types.vector(length=3 * BINS, dtype=wp.int64)


@wp.struct
class _Arrays:
    last_visit: wp.array(dtype=wp.int64)
    flight_gain: wp.array(dtype=wp.int64)
    flight_start: wp.array(dtype=wp.int64)
    counts: wp.array(dtype=wp.int64)  # shape (3 * BINS,): this launch's histograms, added to
    scratch: wp.array(dtype=wp.uint8)  # (SCRATCH_BYTES,): the CPU hooks' buffer (.transport_cpu)


@wp.struct
class _Accumulators:
    """The portable hooks' per-thread state (what CUDA runs)."""

    last_visit: _LaneInts
    flight_gain: _LaneInts
    flight_start: _LaneInts
    lanes: int  # lanes 0 .. lanes-1 are real points (the rest repeat point n - 1)
    counts: _Counts  # this thread's histograms


@wp.struct
class _CpuAccumulators:
    """The CPU hooks' per-thread state: a few scalars. Their buffer and byte trackers live in the
    launch's ``scratch`` array, not here: Warp zero-initialises a thread's struct, and a 4.6 KB
    buffer inside it makes every launch pay for that (:mod:`._transport_cpu`)."""

    arrays: _Arrays  # carry (read by the first decode, written by the store), counts, scratch
    first: int
    spacing: int
    lanes: int  # lanes 0 .. lanes-1 are real points
    rows: int  # rows of the buffer in use
    base: wp.int64  # global step before buffer row 0
    ready: int  # 1 once the trackers hold the carry
    strip_flip: wp.uint32  # xored with the buffer's strip masks: all ones where they hold the lanes outside
    tallies: wp.types.vector(length=9, dtype=wp.int64)


@wp.func
def _lanes(first: int, spacing: int, n: int):
    lanes = int(0)  # noqa: UP018 - Warp: a variable changed in a loop needs a constructor
    for k in range(wp.static(INTERLEAVE)):
        if first + k * spacing < n:
            lanes = k + 1  # real lanes are a prefix: first + k * spacing grows with k
    return lanes


@wp.func
def _load(arrays: _Arrays, first: int, spacing: int, n: int):
    acc = _Accumulators()
    acc.last_visit = load_lanes(arrays.last_visit, _LaneInts(), first, spacing, n)
    acc.flight_gain = load_lanes(arrays.flight_gain, _LaneInts(), first, spacing, n)
    acc.flight_start = load_lanes(arrays.flight_start, _LaneInts(), first, spacing, n)
    acc.lanes = _lanes(first, spacing, n)
    return acc


@wp.func
def _store(arrays: _Arrays, acc: _Accumulators, first: int, spacing: int, n: int):
    store_lane_vector(arrays.last_visit, acc.last_visit, first, spacing, n)
    store_lane_vector(arrays.flight_gain, acc.flight_gain, first, spacing, n)
    store_lane_vector(arrays.flight_start, acc.flight_start, first, spacing, n)
    for b in range(3 * BINS):
        if acc.counts[b] != wp.int64(0):
            wp.atomic_add(arrays.counts, b, acc.counts[b])


@wp.func_native(CLAIM_CPU)
def _claim_cpu(acc: wp.ref[_CpuAccumulators]): ...


@wp.func
def _load_cpu(arrays: _Arrays, first: int, spacing: int, n: int):
    acc = _CpuAccumulators()
    acc.arrays = arrays
    acc.first = first
    acc.spacing = spacing
    acc.lanes = _lanes(first, spacing, n)
    _claim_cpu(acc)  # the scratch's guard: this thread's tag, once, before the step loop
    return acc


@wp.func_native(DECODE_CPU)
def _decode_cpu(acc: wp.ref[_CpuAccumulators]): ...


_RECORDING_STEPS: dict[str, wp.Function] = {}


def _recording_steps(force) -> wp.Function:
    """The CPU body's steps of ``force`` with the recording inside (:data:`._transport_cpu.RECORD_CPU`
    on the AVX2 path, :func:`._transport_cpu.record_avx512`, register by register, on the AVX-512
    path): each step's row written from the lanes in registers (a thread's lanes and its 8-step
    runs between checks stay in registers, as in ``advance_map``)."""
    tag = "paper" if force.family == "paper" else force.key
    if tag not in _RECORDING_STEPS:

        def recording_steps(
            acc: wp.ref[_CpuAccumulators],
            s: wp.ref[Lanes],
            p: Coefficients,
            count: wp.int32,
            global_step: wp.int64,
        ): ...

        recording_steps.__qualname__ = f"_recording_steps_{tag}"
        if CPU_ISA == "avx2":
            before, each, after = RECORD_CPU
            source = cpu_steps_source(force, each=each, before=before, after=after)
        else:
            before, each, after_each, after = record_avx512(force)
            source = depth_first_steps_source(
                force, each=each, after_each=after_each, before=before, after=after
            )
        _RECORDING_STEPS[tag] = wp.func_native(source)(recording_steps)
    return _RECORDING_STEPS[tag]


@wp.func
def _after_check_cpu(acc: wp.ref[_CpuAccumulators], s: wp.ref[Lanes], check: wp.int64):
    if acc.rows > wp.static(ROWS - 8):  # the next 8 steps would not fit
        _decode_cpu(acc)


@wp.func_native(FINISH_CPU)
def _finish_cpu(acc: wp.ref[_CpuAccumulators]): ...


@wp.func
def _store_cpu(arrays: _Arrays, acc: wp.ref[_CpuAccumulators], first: int, spacing: int, n: int):
    _decode_cpu(acc)  # the rows since the last check
    _finish_cpu(acc)


@wp.func
def _bin(length: wp.int64):
    """``floor(log2(length))`` for ``length >= 1``."""
    b = int(0)  # noqa: UP018 - as above
    v = length
    for shift in range(5, -1, -1):  # 32, 16, 8, 4, 2, 1
        width = 1 << shift
        if (v >> wp.int64(width)) != wp.int64(0):
            v = v >> wp.int64(width)
            b += width
    return b


@wp.func
def _after_step(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], global_step: wp.int64):
    for k in range(wp.static(INTERLEAVE)):
        if k < acc.lanes:
            if s.in_strip[k] != wp.float64(0.0):
                last = acc.last_visit[k]
                if last >= wp.int64(0):
                    b = _bin(global_step - last)
                    acc.counts[b] = acc.counts[b] + wp.int64(1)
                acc.last_visit[k] = global_step
            gain = wp.int64(s.gain[k])
            v = acc.flight_gain[k]
            if gain != v:
                if v != wp.int64(0):
                    b = _bin(global_step - acc.flight_start[k]) + wp.where(v > wp.int64(0), BINS, 2 * BINS)
                    acc.counts[b] = acc.counts[b] + wp.int64(1)
                acc.flight_gain[k] = gain
                acc.flight_start[k] = global_step


@wp.func
def _nothing(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], check: wp.int64):
    pass


TRANSPORT = Variant(
    "map_transport",
    _Arrays,
    _Accumulators,
    _load,
    _store,
    _after_step,
    _nothing,
    cpu_after_check=_after_check_cpu,
    cpu_store=_store_cpu,
    cpu_load=_load_cpu,
    # One step per call spills the lanes around the hook; the run of steps between two checks in
    # one call keeps them in registers (AVX2: coded rows; AVX-512: register by register).
    cpu_steps=_recording_steps,
)


class _TransportKernel(AdvanceKernel):
    """:class:`AdvanceKernel` whose :meth:`launch` adds the launch's scratch array itself."""

    def launch(
        self, device, state, extra, step0, steps, params, body=None, block_rows: int = 8, scratch=None
    ) -> None:
        """:meth:`AdvanceKernel.launch` with ``extra`` = the carry arrays and the launch's histogram
        array (:data:`CARRY_FIELDS`, then ``(3 * BINS,)`` int64, added to). ``block_rows``: the CPU
        hooks' largest block of rows decoded at once: 8, or 1 (row by row, the path of an AVX-512
        CPU without GFNI; the same counts, both paths checked by ``tests/analyses/test_transport.py``).
        ``scratch``: the CPU hooks' scratch array (default: one of this launch's own; a test gives
        two concurrent launches one scratch to check that the guard sees it).

        Raises
        ------
        KernelError
            (a ``RuntimeError``) Two CPU threads used the scratch at once (the guard of
            :mod:`._transport_cpu`): this launch's counts and carry are wrong, so they are
            refused, not returned.
        """
        if block_rows not in (1, 8):
            raise ValueError(f"block_rows = {block_rows} is not one of the allowed values 1, 8")
        cpu = wp.get_device(device).is_cpu
        # One scratch per launch: Warp runs a CPU launch's threads one after the other (its own
        # CPU atomics are plain adds for that reason), so they share it; concurrent launches
        # (CPU shards) each get their own. The portable hooks never touch it.
        # A scratch one byte longer asks the CPU hooks for the row loop alone (.transport_cpu); the
        # arrays struct holds arrays only (Ensemble sizes its per-point memory from it).
        if scratch is None:
            scratch = wp.zeros(SCRATCH_BYTES + (block_rows == 1) if cpu else 0, dtype=wp.uint8, device=device)
        super().launch(device, state, [*extra, scratch], step0, steps, params, body)
        if cpu:
            conflict = scratch.numpy()[8 * CONFLICT_WORD : 8 * CONFLICT_WORD + 8].view(np.int64)[0]
            if conflict != 0:
                raise KernelError(
                    "two CPU threads of a transport launch used its scratch at once (does Warp "
                    f"{wp.__version__} run a CPU launch's threads concurrently?): its return-time "
                    "and flight counts would be wrong, so the launch is refused"
                )


#: ``advance_map`` plus the return-time and flight histograms (module docstring); its own Warp
#: modules, compiled only when a transport run needs them.
advance_map_transport = _TransportKernel(TRANSPORT, module_suffix=".transport")
