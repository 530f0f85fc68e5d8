"""Every Warp kernel of warpratchet.

The map (Eq. cpem) and its tangent ``DM`` are advanced *inside* one kernel for ``steps``
iterations, so that a launch does real work: on the CPU a Warp launch runs on one thread, and
the ensemble layer shards points over one Python thread per core.

* :mod:`.step`: the step body (arithmetic, lanes, the CPU and the portable implementation);
* :mod:`.advance`: the step loop, written once, and kernel variants built on it;
* :mod:`.map`, :mod:`.indicators`: ``advance_map`` and ``advance_map_indicators``;
* :mod:`.runtime`: Warp start-up and compiler options.

Chosen options (measured on the 2-core AMD EPYC with AVX-512, 10^6 points x 1000 steps, ratios
to the hand-vectorised C of ``benchmarks/c/`` from the same run; see ``benchmarks/README.md``):

* the CPU step body works on whole lane vectors (clang vector extensions in a
  ``wp.func_native``), :data:`INTERLEAVE` = 32 lanes per Warp thread, i.e. four 8-wide
  AVX-512 vectors per state field, whose independent dependency chains hide each other's
  latencies. The scalar Warp body with 8 lanes ran at 0.28 of the C program; the vector body
  at 8 lanes (one dependency chain) at ~0.3, 16 lanes ~0.6, 32 lanes ~0.8, 64 lanes ~0.6
  (register spills);
* ``cpu_compiler_flags`` = ``-march=native -ffp-contract=off`` plus Warp's raised inline
  thresholds (:mod:`.runtime`); ``fuse_fp=False``.
"""

from .advance import MAX_LAUNCH_STEPS, AdvanceKernel, Variant, advance_kernel, launch_dim
from .indicators import advance_map_indicators
from .map import advance_map
from .runtime import init_warp
from .step import INTERLEAVE, RENORM_CHECK_EVERY, RENORM_THRESHOLD, Lanes

__all__ = [
    "advance_map",
    "advance_map_indicators",
    "RENORM_THRESHOLD",
    "RENORM_CHECK_EVERY",
    "INTERLEAVE",
    "MAX_LAUNCH_STEPS",
    "AdvanceKernel",
    "Variant",
    "Lanes",
    "advance_kernel",
    "init_warp",
    "launch_dim",
]
