"""Warp start-up and the compiler options of warpratchet's Warp modules.

The kernels live in two Warp modules (``advance.py`` builds them): ``warpratchet.kernels.cpu``
uses the CPU step body (clang vector extensions, AVX-512 where the CPU has it) and is only ever
compiled for the CPU; ``warpratchet.kernels.portable`` uses the plain Warp step body and is what
runs on CUDA devices (and in the test that checks both bodies agree bit for bit on the CPU).
"""

import ctypes.util
import os
import sys

import warp as wp

__all__ = ["init_warp", "CPU_MODULE", "PORTABLE_MODULE", "MODULE_OPTIONS", "CPU_MODULE_OPTIONS"]

CPU_MODULE = "warpratchet.kernels.cpu"
PORTABLE_MODULE = "warpratchet.kernels.portable"

#: Options of both modules. The tangent is carried explicitly, so Warp's adjoints would only cost
#: compile time. ``fuse_fp=False``: no a*b + c contraction into FMAs (one rounding instead of two),
#: which NumPy never does; on CUDA it makes nvcc round like the CPU, too.
MODULE_OPTIONS = {"enable_backward": False, "optimization_level": 3, "fuse_fp": False}

#: CPU compiler flags: Warp's default (``-march=native``, raised LLVM inline thresholds, a shallower
#: SLP search) plus two. ``-ffp-contract=off``: clang's front end would otherwise fuse an
#: ``a*b + c`` written in one C++ expression (Warp's generated code never writes one; the CPU
#: snippets are written one operation per statement, and this makes sure). ``-march=native`` gives
#: AVX-512 where the CPU has it; ``-mprefer-vector-width=512`` keeps the lane vectors in 512-bit
#: registers also where LLVM's tuning for the CPU prefers 256 bits (measured here: 256 gave 0.67
#: of the C program's throughput, 512 and the default 0.81-0.84; see the package docstring).
CPU_COMPILER_FLAGS = (
    "-march=native -mprefer-vector-width=512 -ffp-contract=off -mllvm=-inline-threshold=9000"
    " -mllvm=-inline-cold-callsite-threshold=3000 -mllvm=-slp-recursion-max-depth=4"
)
CPU_MODULE_OPTIONS = {**MODULE_OPTIONS, "cpu_compiler_flags": CPU_COMPILER_FLAGS}

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
