"""Warp start-up and the compiler options of warpratchet's Warp modules.

The kernels live in two Warp modules (``_advance.py`` builds them): ``warpratchet.kernels.cpu``
uses the CPU step body (clang vector extensions, AVX-512 where the CPU has it) and is only ever
compiled for the CPU; ``warpratchet.kernels.portable`` uses the plain Warp step body and is what
runs on CUDA devices (and in the test that checks both bodies agree bit for bit on the CPU).

The CPU body is built for one vector instruction set, :data:`CPU_ISA`: ``"avx512"`` where the CPU
has AVX-512, else ``"avx2"`` (AVX2, or whatever ``-march=native`` gives on other CPUs). The
environment variable ``WARPRATCHET_CPU_ISA`` (``avx2`` or ``avx512``) chooses it instead, so that
one machine can build both code paths: ``avx2`` on an AVX-512 CPU compiles and runs the AVX2 path
(AVX-512 switched off); ``avx512`` on a CPU without it compiles the AVX-512 path (for Zen 4) but
cannot run it, and :func:`check_cpu_isa_runs` refuses a launch. Both paths give the same bits.
"""

import ctypes.util
import os
import sys

import warp as wp

from ..errors import ParameterError

__all__ = [
    "init_warp",
    "CPU_MODULE",
    "PORTABLE_MODULE",
    "MODULE_OPTIONS",
    "CPU_MODULE_OPTIONS",
    "PAIRED_CPU_FLAGS",
    "CPU_ISA",
    "CPU_ISAS",
    "check_cpu_isa_runs",
    "arrays_struct",
]

CPU_MODULE = "warpratchet.kernels.cpu"
PORTABLE_MODULE = "warpratchet.kernels.portable"

#: Options of both modules. The tangent is carried explicitly, so Warp's adjoints would only cost
#: compile time. ``fuse_fp=False``: no a*b + c contraction into FMAs (one rounding instead of two),
#: which NumPy never does; on CUDA it makes nvcc round like the CPU, too.
MODULE_OPTIONS = {"enable_backward": False, "optimization_level": 3, "fuse_fp": False}


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:  # not Linux
        pass
    return set()


#: The vector instruction sets the CPU body can be built for.
CPU_ISAS = ("avx2", "avx512")
#: The environment variable that chooses one of them.
CPU_ISA_VARIABLE = "WARPRATCHET_CPU_ISA"
_NATIVE_AVX512 = "avx512f" in _cpu_flags()


def _cpu_isa() -> str:
    chosen = os.environ.get(CPU_ISA_VARIABLE, "").strip().lower()
    if not chosen:
        return "avx512" if _NATIVE_AVX512 else "avx2"
    if chosen not in CPU_ISAS:
        raise ParameterError(
            f"{CPU_ISA_VARIABLE} = {chosen!r} is not one of {', '.join(CPU_ISAS)} (or unset)"
        )
    return chosen


#: The instruction set of the CPU body (module docstring).
CPU_ISA = _cpu_isa()


def check_cpu_isa_runs() -> None:
    """Raise :class:`~warpratchet.errors.ParameterError` if the CPU body was built for an
    instruction set this CPU lacks (the user's setting; running it would crash the process)."""
    if CPU_ISA == "avx512" and not _NATIVE_AVX512:
        raise ParameterError(
            f"{CPU_ISA_VARIABLE} = avx512 builds the AVX-512 code path, which this CPU cannot run; "
            "unset it to run here"
        )


def _target() -> str:
    """The host's own features, or (Warp passes the flags to clang's front end) a named CPU where
    the path asked for is not the host's: Zen 3 (AVX2) or Zen 4 (AVX-512 with GFNI)."""
    if CPU_ISA == "avx2" and _NATIVE_AVX512:
        return "-target-cpu znver3"
    if CPU_ISA == "avx512" and not _NATIVE_AVX512:
        return "-target-cpu znver4"
    return "-march=native"


#: CPU compiler flags: Warp's default (``-march=native``, raised LLVM inline thresholds, a shallower
#: SLP search) plus two. ``-ffp-contract=off``: clang's front end would otherwise fuse an
#: ``a*b + c`` written in one C++ expression (Warp's generated code never writes one; the CPU
#: snippets are written one operation per statement, and this makes sure). ``-march=native`` gives
#: AVX-512 where the CPU has it; ``-mprefer-vector-width=512`` keeps the lane vectors in 512-bit
#: registers also where LLVM's tuning for the CPU prefers 256 bits, which splits them and runs
#: slower (measurements in ``benchmarks/README.md``).
CPU_COMPILER_FLAGS = (
    f"{_target()} -mprefer-vector-width=512 -ffp-contract=off -mllvm=-inline-threshold=9000"
    " -mllvm=-inline-cold-callsite-threshold=3000 -mllvm=-slp-recursion-max-depth=4"
)
CPU_MODULE_OPTIONS = {**MODULE_OPTIONS, "cpu_compiler_flags": CPU_COMPILER_FLAGS}
#: Added for the modules of kernels whose CPU steps go register by register over two blocks of
#: lanes (``_step.PAIRED``): LLVM's machine scheduler off. It interleaves the eight independent
#: chains of registers and then keeps part of them in memory; the source's order, one register's
#: step after another's, is what an out-of-order core runs fastest (``benchmarks/README.md``).
PAIRED_CPU_FLAGS = " -mllvm=-enable-misched=false"

_initialised = False


def init_warp() -> None:
    """Initialise Warp once, quietly (module-load lines on only if WARPRATCHET_VERBOSE is set)."""
    global _initialised
    if _initialised:
        return
    if os.environ.get("WARPRATCHET_VERBOSE"):
        wp.init()
    else:
        wp.config.quiet = True
        wp.config.log_level = 30  # logging.WARNING
        if ctypes.util.find_library("cuda") is None:
            # No CUDA driver on this machine: Warp's native "could not load the CUDA driver"
            # line says nothing the user can act on, so fd 2 is muted while Warp starts.
            with _stderr_muted():
                wp.init()
        else:
            wp.init()
    _initialised = True


class _stderr_muted:
    def __enter__(self):
        sys.stderr.flush()
        self._saved = os.dup(2)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)

    def __exit__(self, *exc):
        os.dup2(self._saved, 2)
        os.close(self._saved)


def arrays_struct(name: str, fields: dict) -> type:
    """A Warp struct of arrays, one per field (``name: dtype``), in the fields' order: what a
    kernel with many arrays takes as one argument."""
    annotations = {field: wp.array(dtype=dtype) for field, dtype in fields.items()}
    return wp.struct(type(name, (), {"__annotations__": annotations, "__module__": __name__}))
