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
* :mod:`.logarithm`: ``fdlog``, the indicators' logarithm, the same bits on every body;
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

``advance_map_indicators`` takes a logarithm of every point at every check (every 8 steps); the
C library's ``log``, lane by lane, took ~3.4 ns of it against ~6.2 ns for the 8 steps. It now uses
:func:`.logarithm.fdlog`, the project's own (fdlibm's algorithm; the same bits on the CPU body, the
portable body and in NumPy), on whole lane vectors. Measured per CPU-second of one thread as above
(medians of 4 interleaved runs of both kernels; stack accesses in the step loop in brackets):

=====================================================================  ==============
the indicators' logarithm                                              of advance_map
=====================================================================  ==============
before: the C library's ``log``, lane by lane                          0.64-0.69
``fdlog``, all 32 lanes at once (36)                                   0.78
``fdlog``, 8 lanes at a time in a rolled loop (21)                     0.81-0.83
the same, out of line (``noinline``)                                    0.71-0.73
the same, subnormal and special arguments on a branch                  0.82 (no gain)
=====================================================================  ==============

Measured again later the same way (and in ``benchmarks/throughput.py`` with every row on its own
cores), that build gave 0.73-0.81 of ``advance_map``, not reliably the 0.8 issue 12 asks for. Where
the rest went, measured per CPU-second of one thread on 2^18 points of the same state (512-step
launches of each kernel alternately, medians of 25-41 rounds; experiments, not kept): the check with
``fdlog`` stubbed out (its argument passed through) ran at 1.00-1.01 of ``advance_map``, with the
division ``2 lsum / j`` or ``fdlog``'s ``f / (2 + f)`` made a multiplication within +-0.04 (the
noise; +0.01-0.02 in the steadiest run), with two independent ``fdlog`` calls at 0.73 (the second
cost as much as the first). So the check's sums and divisions hide in the step loop's slack, and the
whole cost is ``fdlog``'s arithmetic: its throughput, not its dependency chain. At ~3.2 GHz, 8 steps
of 32 lanes take ~670 cycles (104 ``zmm`` operations per step) and ``fdlog`` of 32 lanes took ~175
more, ~100 now. What changed it (same measure; the short path finds ``k`` and ``m`` with
``vgetexppd`` and ``vgetmantpd`` and has no special-value selects, :mod:`.logarithm`):

=====================================================================  ==============
``fdlog`` on the CPU body                                              of advance_map
=====================================================================  ==============
8 lanes at a time, general form (~50 vector operations per 8 lanes)   0.75-0.84
short path if all lanes are positive and finite (~34 operations)      0.76-0.85
**the same, 16 lanes at a time** (two 512-bit registers, 17)           **0.85-0.88**
the same, 32 lanes at once                                             0.85-0.86
the same, ``2 + f`` as ``m + 1`` (equal bits, 3 cycles off the chain)  no gain
spread over the 4 steps after the check, 8 lanes per step (38)         0.73
the same, 16 lanes per step over 2 steps                               0.81
norm2 of 1, 4 or 8 checks buffered, then ``fdlog`` in one loop         0.62-0.77
check j's sums at check j + 1 (the sums off ``fdlog``'s chain)         0.80-0.83
=====================================================================  ==============

The last four lose to register pressure: the step loop holds ~30 of the 32 ``zmm`` registers, and
state carried across steps (pending logarithms, a buffer) spills it. With ``fdlog``'s ~136
operations per check fixed by the bitwise equality (fdlibm's evaluation order), against ~830 for 8
steps, ~0.86-0.9 is about the ceiling of this kernel. ``benchmarks/indicators_overhead.py`` measures
the ratio (alternating launches, 1 and 2 threads, per wall and per CPU second; its numbers and
``throughput.py``'s are in ``benchmarks/README.md``).

The renormalisation's ``log`` (once per ~660 steps for a chaotic point) stays the C library's,
lane by lane, for the lanes that need it: ``fdlog`` there made ``advance_map`` slower (1,090-1,190
against 1,220-1,235 M point-steps per CPU-second: a check that renormalises one lane would take
all 32 logarithms), and it keeps the log-stretch bitwise that of archives written before
(``tests/test_formats.py``). On CUDA that ``log`` is CUDA's (the log-stretch agrees to ~1e-14),
while ``fdlog`` gives the CPU's bits there too.

What ``fdlog`` changed: it and the C library's ``log`` differ by one ulp for ~1e-4 of arguments
log-uniform in ``[1e-300, 1e300]`` and ~7% in ``[0.5, 2]``, and the indicators' running sums
absorb most of that. MEGNO and FLI against the C library's ``log`` (``reference.advance_indicators``
with ``math.log`` for ``fdlog``), 20,000 torus points:

=========================  ======  ==========================  =========================
map                        steps   FLI: points differing       MEGNO: points differing
=========================  ======  ==========================  =========================
K 3, b1 0.1, b2 0.01       1,000   1 (1 ulp)                   3 (1 ulp)
K 3, b1 0.1, b2 0.01       16,000  0                           0
K 3, b1 0.3, b2 0.03       1,000   2 (1 ulp)                   2 (<= 2 ulp)
K 3, b1 0.3, b2 0.03       16,000  0                           0
K 2.99, b1 0.25, b2 0.07   4,000   9 (1 ulp)                   5,377 (<= 6e-16 absolute)
=========================  ======  ==========================  =========================

The last row's MEGNO differences sit on regular orbits whose MEGNO is ~0.01 (a mean of terms of
size ~1 that nearly cancel): up to 166 ulp of that small value, 6e-16 in absolute terms, against
the chaos threshold 4. The island census (``tests/test_sumrule.py``) is unchanged.
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
