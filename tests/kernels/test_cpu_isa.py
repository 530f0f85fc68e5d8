"""Both vector code paths of the CPU body: AVX2 and AVX-512, the same bits.

``WARPRATCHET_CPU_ISA`` chooses the path at import (``warpratchet.kernels._runtime``), so each
path runs in a subprocess of its own. The AVX2 path runs on any x86-64 CPU with AVX2, an AVX-512
one included (AVX-512 switched off), and must equal the NumPy twin bit for bit. The AVX-512 path
runs and is checked the same way where the CPU has AVX-512; elsewhere it is compiled (for Zen 4:
both kernels, the transport kernel's AVX-512 block decoding and the logarithm's AVX-512 branch
included) and a launch must be refused rather than crash on an illegal instruction.
"""

import os
import subprocess
import sys

import pytest
import support

from warpratchet.kernels import _runtime as runtime

_CHECK = r"""
import sys
import numpy as np
from warpratchet import reference
from warpratchet.ensemble import Ensemble
from warpratchet.kernels import INTERLEAVE, advance_map, advance_map_indicators, init_warp
from warpratchet.kernels import _runtime as runtime
from warpratchet.params import MapParams
from warpratchet.kernels._transport import advance_map_transport

init_warp()
print(runtime.CPU_ISA, INTERLEAVE, runtime.CPU_COMPILER_FLAGS)
for kernel in (advance_map, advance_map_indicators, advance_map_transport):
    kernel.load("cpu")
from warpratchet.transport import TransportEnsemble
from warpratchet.transport import _twin as twin

p = MapParams(3.0, 0.1, 0.01)
rng = np.random.default_rng(5)
x, q = rng.random(1003), rng.random(1003) - 3.0
# 8 points whose first step folds q (K f a tiny negative, q the next double below -K f)
x[:8] = np.nextafter(p.table.fields()["c"], 1.0) + np.arange(8) * 2.0**-53
q[:8] = np.nextafter(-p.K * p.table.evaluate(x[:8])[0], 0.0)
ens = Ensemble(p, x, q, threads=2)
ens.step = 3
start = ens.state()
try:
    ens.run(700, chunk_steps=97)
except ValueError as error:  # ParameterError
    print("refused:", error)
    sys.exit(3)
expected = reference.advance(p, start, 700, step0=3)
got = ens.state()
for name in ("x", "q", "winding", "dx", "dp", "log_stretch"):
    assert np.array_equal(got[name], expected[name]), name
assert np.count_nonzero(expected["log_stretch"]) > 100  # renormalised on this path too
assert np.all(reference.advance(p, start, 1, step0=3)["q"][:8] == 0.0)  # the folds happened
# transport: its own steps (the recording inside), the orbit and every count the twin's
transport = TransportEnsemble(p, x, q, threads=2)
start = transport.state()
expected, carry, counts = twin.advance(p, start, twin.initial_carry(p, start["x"], 0), 700)
transport.run(700, chunk_steps=97)
got = transport.state()
for name in ("x", "q", "winding", "dx", "dp", "log_stretch"):
    assert np.array_equal(got[name], expected[name]), f"transport {name}"
done = transport.transport_state()
assert np.array_equal(done.counts, counts) and counts.sum() > 1000, "transport counts"
assert all(np.array_equal(done.carry[name], carry[name]) for name in carry), "transport carry"
print("bitwise equal")
"""


def _has(flag: str) -> bool:
    return flag in runtime._cpu_flags()


def _run(isa: str) -> subprocess.CompletedProcess:
    env = {**os.environ, runtime.CPU_ISA_VARIABLE: isa}
    return subprocess.run(
        [sys.executable, "-c", _CHECK], env=env, capture_output=True, text=True, timeout=900
    )


@pytest.mark.skipif(not _has("avx2"), reason="the AVX2 path needs an x86-64 CPU with AVX2")
def test_the_avx2_path_equals_the_numpy_twin_bit_for_bit():
    done = _run("avx2")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("avx2 16 ")
    assert "bitwise equal" in done.stdout


def test_the_avx512_path_compiles_and_runs_where_the_cpu_has_it():
    done = _run("avx512")
    assert done.stdout.startswith("avx512 32 "), done.stderr
    if _has("avx512f"):
        assert done.returncode == 0, done.stderr
        assert "bitwise equal" in done.stdout
    else:
        # Compiled for Zen 4 (all three kernels loaded above), and refused before any launch.
        assert "-target-cpu znver4" in done.stdout
        assert done.returncode == 3, done.stderr
        assert "which this CPU cannot run" in done.stdout
        # and the CLI says so in one line, exit status 2 (the user's setting), no traceback
        env = {**os.environ, runtime.CPU_ISA_VARIABLE: "avx512"}
        argv = ["run", "--K", "3", "--b1", "0.1", "--b2", "0.01"]
        argv += ["--points", "10", "--steps", "10", "--quiet"]
        cli = support.cli(*argv, module="warpratchet", env=env, timeout=900)
        assert cli.returncode == 2 and cli.stdout == ""
        lines = cli.stderr.strip().splitlines()
        assert len(lines) == 1 and "which this CPU cannot run" in lines[0], cli.stderr


def test_an_unknown_instruction_set_is_refused_in_one_line():
    env = {**os.environ, runtime.CPU_ISA_VARIABLE: "sse9"}
    done = subprocess.run(
        [sys.executable, "-c", "import warpratchet.kernels"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode != 0
    assert "WARPRATCHET_CPU_ISA = 'sse9' is not one of avx2, avx512 (or unset)" in done.stderr
