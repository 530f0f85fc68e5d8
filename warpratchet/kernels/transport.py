"""``advance_map_transport``: :data:`~warpratchet.kernels.advance_map` plus return times and flights.

The orbit and tangent are bitwise those of ``advance_map`` (the same step loop); a hook after
every step counts, per point, two kinds of events into log2-binned histograms (bin ``k`` holds
lengths in ``[2^k, 2^(k+1))``, :data:`BINS` bins), exact int64 counts (issue 16):

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
runs) and the CPU hooks of :mod:`.transport_cpu` (codes per step, decoded in blocks as byte
vectors), which ``tests/test_transport.py`` checks against each other and against the NumPy twin
:mod:`warpratchet.transport.twin`.

The three per-point values are the carry state: runs still open at the end of a launch continue
in the next one, so chunking, thread count and resuming (the carry is checkpointed with the
state) never change a count. Each Warp thread counts into its own histogram and adds it to the
launch's histogram array at the end (an atomic add: one array per CPU launch, or one for all
CUDA threads); integer sums do not depend on the order.
"""

import warp as wp

from .advance import Variant, advance_kernel
from .step import INTERLEAVE, Lanes, load_lanes, store_lane_vector
from .transport_cpu import BINS, DECODE_CPU, FINISH_CPU, STEP_CPU

__all__ = ["BINS", "HISTOGRAMS", "CARRY_FIELDS", "advance_map_transport", "TRANSPORT"]

#: The histograms, in the order of the kernel's histogram array (``3 * BINS`` int64).
HISTOGRAMS = ("return_times", "flights_plus", "flights_minus")
#: Per-point carry state (int64 arrays), in the kernel's argument order.
CARRY_FIELDS = ("last_visit", "flight_gain", "flight_start")

_LaneInts = wp.types.vector(length=INTERLEAVE, dtype=wp.int64)
_LaneBytes = wp.types.vector(length=INTERLEAVE, dtype=wp.uint8)
_Counts = wp.types.vector(length=3 * BINS, dtype=wp.int64)
#: Steps buffered by the CPU hooks between two decodes (at a renormalisation check, every 8 steps,
#: once fewer than 8 rows are free): a decode spills the step's registers, so it is kept rare.
_ROWS = 128


@wp.struct
class _Arrays:
    last_visit: wp.array(dtype=wp.int64)
    flight_gain: wp.array(dtype=wp.int64)
    flight_start: wp.array(dtype=wp.int64)
    counts: wp.array(dtype=wp.int64)  # shape (3 * BINS,): this launch's histograms, added to


@wp.struct
class _Accumulators:
    last_visit: _LaneInts
    flight_gain: _LaneInts
    flight_start: _LaneInts
    lanes: int  # lanes 0 .. lanes-1 are real points (the rest repeat point n - 1)
    counts: _Counts  # this thread's histograms
    # The CPU hooks' own state (.transport_cpu): buffered codes and byte trackers.
    buffer: wp.types.vector(length=_ROWS * INTERLEAVE, dtype=wp.uint8)
    strip: wp.types.vector(length=_ROWS, dtype=wp.uint32)  # in_strip per buffered row, bit k = lane k
    rows: int  # rows of the buffer in use
    base: wp.int64  # global step before buffer row 0
    ready: int  # 1 once the trackers hold the carry
    valid: _LaneBytes
    visited: _LaneBytes
    age: _LaneBytes
    fcode: _LaneBytes
    flen: _LaneBytes
    age_extra: _LaneInts
    flen_extra: _LaneInts
    tallies: wp.types.vector(length=9, dtype=wp.int64)


@wp.func
def _load(arrays: _Arrays, first: int, spacing: int, n: int):
    acc = _Accumulators()
    acc.last_visit = load_lanes(arrays.last_visit, _LaneInts(), first, spacing, n)
    acc.flight_gain = load_lanes(arrays.flight_gain, _LaneInts(), first, spacing, n)
    acc.flight_start = load_lanes(arrays.flight_start, _LaneInts(), first, spacing, n)
    lanes = int(0)  # noqa: UP018 - Warp: a variable changed in a loop needs a constructor
    for k in range(wp.static(INTERLEAVE)):
        if first + k * spacing < n:
            lanes = k + 1  # real lanes are a prefix: first + k * spacing grows with k
    acc.lanes = lanes
    return acc


@wp.func
def _store(arrays: _Arrays, acc: _Accumulators, first: int, spacing: int, n: int):
    store_lane_vector(arrays.last_visit, acc.last_visit, first, spacing, n)
    store_lane_vector(arrays.flight_gain, acc.flight_gain, first, spacing, n)
    store_lane_vector(arrays.flight_start, acc.flight_start, first, spacing, n)
    for b in range(3 * BINS):
        if acc.counts[b] != wp.int64(0):
            wp.atomic_add(arrays.counts, b, acc.counts[b])


@wp.func_native(DECODE_CPU)
def _decode_cpu(acc: wp.ref[_Accumulators]): ...


@wp.func_native(STEP_CPU)
def _after_step_cpu(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], global_step: wp.int64): ...


@wp.func
def _after_check_cpu(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], check: wp.int64):
    if acc.rows > wp.static(_ROWS - 8):  # the next 8 steps would not fit
        _decode_cpu(acc)


@wp.func_native(FINISH_CPU)
def _finish_cpu(acc: wp.ref[_Accumulators], arrays: _Arrays, first: int, spacing: int, n: int): ...


@wp.func
def _store_cpu(arrays: _Arrays, acc: wp.ref[_Accumulators], first: int, spacing: int, n: int):
    # by reference: a copy of the accumulators (6.7 KB with the buffer) per launch and thread is
    # measurable on short launches
    _decode_cpu(acc)  # the rows since the last check
    _finish_cpu(acc, arrays, first, spacing, n)


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
    cpu_after_step=_after_step_cpu,
    cpu_after_check=_after_check_cpu,
    cpu_store=_store_cpu,
)

#: ``advance_map`` plus the return-time and flight histograms (module docstring); its own Warp
#: modules, compiled only when a transport run needs them.
advance_map_transport = advance_kernel(TRANSPORT, module_suffix=".transport")
