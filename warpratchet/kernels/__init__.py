"""Every Warp kernel of warpratchet.

The map (Eq. cpem) and its tangent ``DM`` are advanced *inside* one kernel for ``steps``
iterations, so that a launch does real work: on the CPU a Warp launch runs on one thread, and
the ensemble layer shards points over one Python thread per core.

* :mod:`._step`: the step body, written once per backend: the arithmetic, the lanes, the CPU body
  (whole lane vectors, C++ with clang vector extensions) and the portable body (plain Warp, what
  CUDA runs);
* :mod:`._advance`: the step loop, written once, and kernel variants built on it (hooks after each
  step and after each renormalisation check; a plain run pays nothing for them);
* :mod:`._map`, :mod:`._indicators`, :mod:`._transport`: ``advance_map``, ``advance_map_indicators``
  (MEGNO, FLI; its accumulators :data:`INDICATOR_FIELDS`) and ``advance_map_transport`` (return
  times and flights);
* :mod:`._logarithm`: ``fdlog``, the indicators' logarithm, the same bits on every body;
* :mod:`._libm`: the C library's ``hypot`` and ``log`` as NumPy calls them, for kernels that must
  give NumPy's bits (the history rows' FTLE), and the gate that says whether they do here;
* :mod:`._rows`: a history row's per-point pass (``RowPass``), NumPy's pairwise sums
  (``leaf_sums``) and the FTLE alone (``lyapunov_into``), the bits of
  :func:`warpratchet.observables.summarize_with_variance`'s NumPy path;
* :mod:`._runtime`: Warp start-up and the compiler options.

The CPU body is built for one vector instruction set (:data:`._runtime.CPU_ISA`: AVX-512 where the
CPU has it, else AVX2; ``WARPRATCHET_CPU_ISA`` chooses): :data:`INTERLEAVE` = 32 lanes (four 8-wide
vectors per field) on the AVX-512 path, 16 (four 4-wide vectors) on the AVX2 path, the counts
that keep a step's lane vectors in the register file. Both paths give the same bits, and no FMA
contraction anywhere (``-ffp-contract=off``, ``fuse_fp=False``): NumPy rounds ``a*b + c`` twice.
A kernel without per-step work runs the steps between two renormalisation checks in one call of
the body, its lanes in registers throughout; one call advances two threads' worth of lanes, one
vector register after another, on both paths. ``advance_map_indicators`` takes its logarithm with
:func:`._logarithm.fdlog` (the same bits on every body and in NumPy) on whole lane vectors; the
renormalisation's ``log`` (once per ~660 steps for a chaotic point) is the C library's, lane by
lane, for the lanes that need it. The measurements behind these choices, and what each kernel
reaches against the hand-vectorised C of its instruction set, are in ``benchmarks/README.md``.
"""

from ._advance import MAX_LAUNCH_STEPS, AdvanceKernel, Variant, advance_kernel, launch_dim
from ._indicators import INDICATOR_FIELDS, advance_map_indicators
from ._map import advance_map
from ._rows import SUM_TERMS, RowPass, leaf_sums, lyapunov_into, row_pass_available
from ._runtime import CPU_ISA, init_warp
from ._step import INTERLEAVE, RENORM_CHECK_EVERY, RENORM_THRESHOLD, Lanes
from ._transport import advance_map_transport

__all__ = [
    "advance_map",
    "advance_map_indicators",
    "advance_map_transport",
    "RowPass",
    "leaf_sums",
    "lyapunov_into",
    "row_pass_available",
    "SUM_TERMS",
    "INDICATOR_FIELDS",
    "RENORM_THRESHOLD",
    "RENORM_CHECK_EVERY",
    "INTERLEAVE",
    "CPU_ISA",
    "MAX_LAUNCH_STEPS",
    "AdvanceKernel",
    "Variant",
    "Lanes",
    "advance_kernel",
    "init_warp",
    "launch_dim",
]
