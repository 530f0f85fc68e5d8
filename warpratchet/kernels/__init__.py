"""Every Warp kernel of warpratchet.

The map (Eq. cpem) and its tangent ``DM`` are advanced *inside* one kernel for ``steps``
iterations, so that a launch does real work: on the CPU a Warp launch runs on one thread, and
the ensemble layer shards points over one Python thread per core.

* :mod:`.step`: the step body, written once per backend: the arithmetic, the lanes, the CPU body
  (whole lane vectors, C++ with clang vector extensions) and the portable body (plain Warp, what
  CUDA runs);
* :mod:`.advance`: the step loop, written once, and kernel variants built on it (hooks after each
  step and after each renormalisation check; a plain run pays nothing for them);
* :mod:`.map`, :mod:`.indicators`: ``advance_map`` and ``advance_map_indicators`` (MEGNO, FLI);
* :mod:`.runtime`: Warp start-up and the compiler options.

Chosen options, and the measurement that chose them: throughput per CPU-second of one thread
(10^6 points of the strip B at K = 3, b1 = 0.1, b2 = 0.01, after 1024 steps, 1000 steps timed),
as a fraction of the hand-vectorised AVX-512 C program (best of 6 and 8 vectors per block)
measured just before and after, median of 3, on the 2-core AMD EPYC (Zen 4, AVX-512):

==============================================================  ==========
CPU body                                                        fraction
==============================================================  ==========
before: scalar Warp step per lane, 8 lanes in a ``wp.vec``         0.27
lane vectors (this body), :data:`INTERLEAVE` = 8                  0.38
lane vectors, 16                                                   0.62
**lane vectors, 32** (four 8-wide vectors per field)             **0.81**
lane vectors, 64 (registers spill)                                 0.64
lane vectors, 32, ``-mprefer-vector-width=256``                   0.67
lane vectors, 32, ``-mprefer-vector-width=512``                   0.84
==============================================================  ==========

So: :data:`INTERLEAVE` = 32, 512-bit vectors (stated in ``cpu_compiler_flags``, as LLVM's tuning
for some AVX-512 CPUs prefers 256 bits), ``-ffp-contract=off`` and ``fuse_fp=False`` (no FMA
contraction, for bitwise equality with NumPy), Warp's inline thresholds (:mod:`.runtime`).
On a CPU without AVX-512, :data:`INTERLEAVE` = 16: with code generation limited to AVX2
(``-target-cpu znver3`` on the same machine, same measure) 32 lanes spill registers and ran at
0.33, 16 lanes at 0.55, 8 lanes at 0.49, and the scalar body before at 0.10. The
step loop is then 143 instructions for 32 point-steps, 104 of them on ``zmm`` registers, four
``vrndscalepd`` and no scalar arithmetic (before: 171 instructions for 8 point-steps, 49 of them
scalar ``sd``); ``benchmarks/instruction_mix.py`` prints it.

``advance_map_indicators`` runs at ~0.64 of ``advance_map`` (0.52 of the C program): at every
renormalisation check it takes the C library's ``log`` of every lane, one call per point every
8 steps, ~3.4 ns against ~6.2 ns for the 8 steps themselves (measured as above). A vectorised
``log`` would be faster but would change MEGNO and the FLI in the last bits.
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
