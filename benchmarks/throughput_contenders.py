"""The rows of ``throughput.py``: one advance function per implementation and thread count.

Every contender advances a copy of the same state by the same float64 arithmetic (see
``throughput.py``) and returns its end state with the wall and CPU seconds the advancing took;
nothing else is timed. Unavailable contenders (no Numba, no gcc, no AVX-512) carry a one-line reason
instead.
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import json
import math
import os
import pickle
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np

from warpratchet import Ensemble, MapParams, kernels, reference
from warpratchet.ensemble import INTERLEAVE, RENORM_CHECK_EVERY, RENORM_THRESHOLD
from warpratchet.force import Force, c_source, python_source
from warpratchet.kernels import CPU_ISA
from warpratchet.sumrule import IndicatorEnsemble

#: The benchmark's ensemble: strip B of Eq. (B), seed 1.
INIT, SEED = "strip", 1
#: State fields a run changes (p0 is read only), compared bit for bit.
EVOLVED = ("x", "q", "winding", "dx", "dp", "log_stretch")

C_DIR = Path(__file__).resolve().parent / "c"
C_SOURCE = C_DIR / "ratchet_map.c"
C_FLAGS = ("-O3", "-march=native", "-fopenmp", "-ffp-contract=off")
#: The hand-vectorised programs: ISA -> (source, /proc/cpuinfo flag it needs, label, vectors per
#: block: each is built, the faster counts per measurement, doubles per vector).
C_SIMD = {
    "avx2": (C_DIR / "ratchet_map_avx2.c", "avx2", "C, hand-vectorised (AVX2)", (3, 4, 8), 4),
    "avx512": (C_DIR / "ratchet_map_avx512.c", "avx512f", "C, hand-vectorised (AVX-512)", (6, 8), 8),
}
#: Flags after ``-march=native`` per hand-vectorised ISA: the AVX2 program on an AVX-512 CPU is
#: kept to what an AVX2 CPU has (16 vector registers, no EVEX encodings), as the kernels' AVX2
#: path is (``WARPRATCHET_CPU_ISA=avx2``).
C_ISA_FLAGS = {"avx2": ("-mno-avx512f",), "avx512": ()}
#: The code paths of the CPU kernels and the labels of their rows.
PATH_LABELS = {"avx2": "AVX2", "avx512": "AVX-512"}

State = dict[str, np.ndarray]


@dataclass(frozen=True)
class Timing:
    """Wall seconds, and CPU seconds of the whole process (all its threads) in that time."""

    seconds: float
    cpu_seconds: float


class Clock:
    """``with Clock() as clock: ...`` then ``clock.timing``: the wall and process CPU seconds of the
    block (the overhead benchmarks time with it too)."""

    def __enter__(self) -> Clock:
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.timing = Timing(time.perf_counter() - self._wall, time.process_time() - self._cpu)


#: ``advance(state, step0, steps) -> (new_state, timing)``: ``steps`` iterations of ``state``,
#: which is at global step ``step0``. ``state`` is never modified and only the advancing itself is
#: timed (copies in and out are not).
Advance = Callable[[State, int, int], tuple[State, Timing]]


@dataclass
class Contender:
    """One row of the table."""

    key: str  # "numpy", "numba", "c", "c_avx2", "c_avx512", "warpratchet", "warpratchet_indicators"
    label: str
    threads: int
    advance: Advance | None  # None: unavailable
    unavailable: str = ""
    device: str = "cpu"  # Warp device of the warpratchet rows


def _copy(state: State) -> State:
    return {name: np.array(state[name], copy=True) for name in EVOLVED}


# -- NumPy ------------------------------------------------------------------------------------------
def numpy_contenders(params: MapParams) -> tuple[list[Contender], str]:
    def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
        with Clock() as clock:
            out = reference.advance(params, state, steps, step0=step0)
        return out, clock.timing

    build = f"numpy {np.__version__}: warpratchet.reference.advance (vectorised over points, steps in Python)"
    return [Contender("numpy", "NumPy", 1, advance)], build


# -- Numba ------------------------------------------------------------------------------------------
def _numba_advance(table: Force) -> Callable[..., None]:
    """The Numba twin of the kernel for the force ``table``, compiled on first use; one for the
    whole paper's family, whose coefficients it reads at run time."""
    return _numba_compile(Force.paper(0.5, 0.25) if table.family == "paper" else table)


@functools.cache
def _numba_compile(table: Force) -> Callable[..., None]:
    """The Numba twin of the kernel (closure constants are frozen); the force's branches are
    generated from ``table`` (:func:`warpratchet.force.python_source`)."""
    import numba

    threshold = RENORM_THRESHOLD
    every = RENORM_CHECK_EVERY
    namespace: dict = {}
    exec(python_source(table, "force_at", MAP_FIELDS), namespace)  # noqa: S102
    force_at = numba.njit(fastmath=False, error_model="numpy", inline="always")(namespace["force_at"])

    # fastmath=False (the default) keeps IEEE semantics: no FMA contraction, no reassociation.
    @numba.njit(parallel=True, fastmath=False, error_model="numpy")
    def advance(x, q, winding, dx, dp, lsum, step0, steps, K, b1, right, l1, l2, c):
        for i in numba.prange(x.size):
            xi, qi, dxi, dpi, si = x[i], q[i], dx[i], dp[i], lsum[i]
            w = 0.0
            for s in range(steps):
                f, slope = force_at(xi, b1, right, l1, l2, c)  # the force and its slope
                t = qi + K * f
                fl = np.floor(t)  # math.floor would return an integer
                qi = t - fl
                wrap = qi >= 1.0
                if wrap:
                    qi = 0.0
                w = w + fl + (1.0 if wrap else 0.0)
                xi = xi + qi
                if xi >= 1.0:
                    xi = xi - 1.0
                dpi = dpi + (K * slope) * dxi
                dxi = dxi + dpi
                if (step0 + s + 1) % every == 0 and abs(dxi) > threshold:
                    h = math.sqrt(dxi * dxi + dpi * dpi)
                    si = si + math.log(h)
                    dxi = dxi / h
                    dpi = dpi / h
            x[i], q[i], dx[i], dp[i], lsum[i] = xi, qi, dxi, dpi, si
            winding[i] = winding[i] + np.int64(w)

    return advance


def numba_contenders(params: MapParams, threads: list[int]) -> tuple[list[Contender], str]:
    try:
        import numba
    except ImportError:
        reason = "unavailable: numba is not installed (pip install 'warpratchet[bench]')"
        return [Contender("numba", "Numba parallel", t, None, reason) for t in threads], reason
    kernel = _numba_advance(params.table)
    threads = [min(t, numba.config.NUMBA_NUM_THREADS) for t in threads]

    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
            out = _copy(state)
            numba.set_num_threads(n_threads)
            with Clock() as clock:
                kernel(*(out[name] for name in EVOLVED), step0, steps, *_map_args(params))
            return out, clock.timing

        return advance

    # Compile now (on a tiny copy) so that no measurement includes the JIT.
    tiny = {name: np.zeros(16, dtype=np.int64 if name == "winding" else np.float64) for name in EVOLVED}
    tiny["dx"][:] = 1.0
    make(1)(tiny, 0, 16)
    build = (
        f"numba {numba.__version__}: @njit(parallel=True, fastmath=False), prange over points, "
        f"threading layer {numba.threading_layer()}"
    )
    return [Contender("numba", "Numba parallel", t, make(t)) for t in threads], build


# -- C: plain and hand-vectorised ------------------------------------------------------------------
def _build_c(
    source: Path, library: Path, params: MapParams, isa: str, defines: tuple[str, ...] = ()
) -> tuple[ctypes.CDLL | None, str]:
    """Compile ``source`` into ``library`` with the force of ``params`` for ``isa`` (``force.h``,
    :func:`warpratchet.force.c_source`, written next to ``library``); ``(library, gcc version)``
    or ``(None, reason)``."""
    gcc = shutil.which("gcc")
    if gcc is None:
        return None, "unavailable: gcc not found on PATH"
    include = library.parent / f"force_{isa}"
    include.mkdir(exist_ok=True)
    (include / "force.h").write_text(c_source(params.table, isa, MAP_FIELDS))
    gcc_version = subprocess.run([gcc, "-dumpfullversion"], capture_output=True, text=True).stdout.strip()
    defines = (
        *defines,
        f"-DRENORM_THRESHOLD={RENORM_THRESHOLD!r}",
        f"-DRENORM_CHECK_EVERY={RENORM_CHECK_EVERY}",
    )
    command = [gcc, *C_FLAGS, *C_ISA_FLAGS.get(isa, ()), "-fPIC", "-shared", f"-I{include}", *defines]
    command += ["-o", str(library), str(source), "-lm"]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        first = (done.stderr.strip().splitlines() or ["(no output)"])[0]
        return None, f"unavailable: gcc failed: {first}"
    lib = ctypes.CDLL(str(library))
    f64 = np.ctypeslib.ndpointer(dtype=np.float64, ndim=1, flags="C_CONTIGUOUS")
    i64 = np.ctypeslib.ndpointer(dtype=np.int64, ndim=1, flags="C_CONTIGUOUS")
    lib.advance_map.restype = None
    lib.advance_map.argtypes = [*[ctypes.c_int64] * 3, *[ctypes.c_double] * 6, f64, f64, i64, f64, f64, f64]
    lib.advance_map.argtypes += [ctypes.c_int]
    return lib, f"gcc {gcc_version}"


def _c_advance(libs: list[ctypes.CDLL], params: MapParams, n_threads: int) -> Advance:
    """Advance with each library in turn and keep the faster (the libraries differ in tuning only)."""

    def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
        best = None
        for lib in libs:
            out = _copy(state)
            arrays = [out[name] for name in EVOLVED]
            with Clock() as clock:
                lib.advance_map(out["x"].size, step0, steps, *_map_args(params), *arrays, n_threads)
            if best is None or clock.timing.seconds < best[1].seconds:
                best = (out, clock.timing)
        return best

    return advance


def c_contenders(params: MapParams, threads: list[int], workdir: Path) -> tuple[list[Contender], str]:
    lib, build = _build_c(C_SOURCE, workdir / "ratchet_map.so", params, "c")
    if lib is None:
        return [Contender("c", "C OpenMP", t, None, build) for t in threads], build
    build = f"{build}: {' '.join(C_FLAGS)}, OpenMP over points, called via ctypes"
    return [Contender("c", "C OpenMP", t, _c_advance([lib], params, t)) for t in threads], build


def _cpu_has(flag: str) -> bool:
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            return any(line.startswith("flags") and f" {flag}" in line for line in cpuinfo)
    except OSError:
        return False


def c_simd_contenders(
    isa: str, params: MapParams, threads: list[int], workdir: Path
) -> tuple[list[Contender], str]:
    """The hand-vectorised C of ``isa`` (:data:`C_SIMD`), built with each of its vector counts per
    block; the faster counts. Unavailable (with the reason) where the CPU lacks the ISA."""
    source, flag, label, vectors, width = C_SIMD[isa]
    key = f"c_{isa}"
    if not _cpu_has(flag):
        reason = f"unavailable: this CPU has no {label.split('(')[1].rstrip(')')}"
        return [Contender(key, label, t, None, reason) for t in threads], reason
    libs = []
    for nv in vectors:
        lib, build = _build_c(source, workdir / f"{source.stem}_nv{nv}.so", params, isa, (f"-DNV={nv}",))
        if lib is None:
            return [Contender(key, label, t, None, build) for t in threads], build
        libs.append(lib)
    build = (
        f"{build}: {' '.join(C_FLAGS + C_ISA_FLAGS[isa])}, {isa} intrinsics, NV = "
        f"{', '.join(map(str, vectors))} "
        f"{width}-wide vectors per block (the fastest per measurement)"
    )
    return [Contender(key, label, t, _c_advance(libs, params, t)) for t in threads], build


# -- warpratchet ------------------------------------------------------------------------------------
def _label(label: str, device: str) -> str:
    return label if device == "cpu" else f"{label} ({device})"


def warp_contenders(
    params: MapParams, threads: list[int], device: str = "cpu"
) -> tuple[list[Contender], str]:
    """``Ensemble.run`` on ``device`` (on a GPU one row: CPU threads do not apply)."""
    threads = threads if device == "cpu" else [1]

    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
            ens = Ensemble.from_state(params, state, step0, threads=n_threads, device=device)
            with Clock() as clock:
                ens.run(steps)
            out = ens.state()
            return {name: out[name] for name in EVOLVED}, clock.timing

        return advance

    # Warm-up: compiles the kernel (or loads it from Warp's cache) outside every measurement.
    Ensemble.sample(params, 64, init=INIT, seed=SEED, threads=1, device=device).run(16)
    build = f"warp {version('warp-lang')} {device}: Ensemble.run, "
    if device == "cpu":
        lanes = f"two blocks of {INTERLEAVE}" if kernels.advance_map.cpu_paired else f"{INTERLEAVE}"
        build += f"{lanes} points per Warp thread, the {CPU_ISA} code path"
        build += ", one Warp launch per Python thread"
    else:
        build += "one point per GPU thread"
    label = _label("warpratchet", device)
    return [Contender("warpratchet", label, t, make(t), device=device) for t in threads], build


def warp_indicator_contenders(
    params: MapParams, threads: list[int], points: int, device: str = "cpu"
) -> tuple[list[Contender], str]:
    """``IndicatorEnsemble.run``: the same orbit plus MEGNO and FLI (``advance_map_indicators``).

    The indicators must start at step 0, so each measurement samples the benchmark's ensemble
    afresh and advances it ``WARMUP_STEPS`` untimed, to the very state the other rows start from.
    """
    threads = threads if device == "cpu" else [1]

    def make(n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
            start_points = Ensemble.sample(params, points, init=INIT, seed=SEED, threads=1)
            ens = IndicatorEnsemble(
                params, start_points.array("x"), start_points.array("p0"), threads=n_threads, device=device
            ).run(step0)
            del start_points
            with Clock() as clock:
                ens.run(steps)
            out = ens.state()
            return {name: out[name] for name in EVOLVED}, clock.timing

        return advance

    IndicatorEnsemble(params, np.zeros(64), np.zeros(64), threads=1, device=device).run(16)  # compile
    build = f"{device}: IndicatorEnsemble.run, advance_map plus MEGNO and FLI (fdlog per point every 8 steps)"
    label = _label("warpratchet + indicators", device)
    rows = [Contender("warpratchet_indicators", label, t, make(t), device=device) for t in threads]
    return rows, build


#: The paper's run-time coefficients, in the order the contenders take them after ``K``.
MAP_FIELDS = ("b1", "right", "l1", "l2", "c")


def _map_args(params: MapParams) -> tuple[float, ...]:
    """The contenders' scalar arguments ``K, b1, right = 1 - b2, l1, l2, c`` (Eqs. fx, mmc), read
    from the force's piece table as the Warp kernels read them. Another force's code holds its
    coefficients as constants and leaves these five unused (they are 0)."""
    fields = params.table.fields()
    return (params.K, *(fields.get(name, 0.0) for name in MAP_FIELDS))


# -- benchmarks in child processes -----------------------------------------------------------------
def child_json(script: str, args: list[str], isa: str | None = None) -> object:
    """``benchmarks/SCRIPT ARGS`` in a child process (with ``isa``: its kernels built for that
    code path, ``WARPRATCHET_CPU_ISA``): the JSON of the last line it prints, or, where it exits
    with an error or prints nothing, why, as a string."""
    env = dict(os.environ)
    if isa is not None:
        env["WARPRATCHET_CPU_ISA"] = isa
    command = [sys.executable, str(Path(__file__).with_name(script)), *args]
    proc = subprocess.run(command, capture_output=True, text=True, env=env)
    if proc.returncode != 0 or not proc.stdout.strip():
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        return f"{script} exited with status {proc.returncode}: {last}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


# -- warpratchet on the other code path -------------------------------------------------------------
def path_key(key: str, isa: str) -> str:
    """The row key of a warpratchet row (``warpratchet``, ``warpratchet_indicators``) on code path
    ``isa``: the key itself on this process's path, else with the path appended."""
    return key if isa == CPU_ISA else f"{key}_{isa}"


class _PathWorker:
    """A child process whose kernels are built for another code path (``WARPRATCHET_CPU_ISA``,
    fixed once per process), serving the warpratchet rows' ``advance`` there (:func:`serve`)."""

    def __init__(self, isa: str, params: MapParams, threads: list[int], points: int) -> None:
        self.isa = isa
        env = {**os.environ, "WARPRATCHET_CPU_ISA": isa}
        here = str(Path(__file__).resolve().parent)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (here, env.get("PYTHONPATH"))))
        self.process = subprocess.Popen(
            [sys.executable, "-c", "import throughput_contenders; throughput_contenders.serve()"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
        )
        atexit.register(self.close)
        self.build = self._ask((params, threads, points))

    def _ask(self, message: object) -> object:
        try:
            pickle.dump(message, self.process.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.process.stdin.flush()
            reply = pickle.load(self.process.stdout)
        except (EOFError, BrokenPipeError):
            status = self.process.wait()
            raise RuntimeError(
                f"the worker for the {self.isa} code path exited with status {status}"
            ) from None
        if isinstance(reply, BaseException):
            raise reply
        return reply

    def advance(self, key: str, n_threads: int) -> Advance:
        def advance(state: State, step0: int, steps: int) -> tuple[State, Timing]:
            return self._ask((key, n_threads, state, step0, steps))

        return advance

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.stdin.close()
            self.process.wait()


def other_path_contenders(
    isa: str, params: MapParams, threads: list[int], points: int
) -> tuple[list[Contender], str]:
    """The warpratchet rows (``advance_map``, the indicators) with the kernels built for code path
    ``isa``, run in a child process; unavailable where this CPU cannot run that path."""
    names = (("warpratchet", "warpratchet"), ("warpratchet_indicators", "warpratchet + indicators"))

    def rows(make: Callable[[str, int], Advance | None], reason: str = "") -> list[Contender]:
        return [
            Contender(path_key(key, isa), f"{label} ({PATH_LABELS[isa]} path)", t, make(key, t), reason)
            for key, label in names
            for t in threads
        ]

    if not _cpu_has(C_SIMD[isa][1]):
        reason = f"unavailable: this CPU has no {PATH_LABELS[isa]}"
        return rows(lambda key, t: None, reason), reason
    try:
        worker = _PathWorker(isa, params, threads, points)
    except RuntimeError as error:  # the child could not build its path: say so in the rows
        reason = f"unavailable: {error}"
        return rows(lambda key, t: None, reason), reason
    return rows(worker.advance), str(worker.build)


def serve() -> None:
    """The child of :class:`_PathWorker`: pickled requests on stdin, pickled replies on stdout.

    First ``(params, threads, points)`` (reply: the build text), then ``(key, threads, state, step0,
    steps)`` per measurement (reply: the row's ``advance``). What else writes to stdout here
    (Warp's messages) goes to stderr, so the replies stay whole."""
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    requests = sys.stdin.buffer
    params, threads, points = pickle.load(requests)
    rows = {}
    builds = []
    for made, build in (
        warp_contenders(params, threads),
        warp_indicator_contenders(params, threads, points),
    ):
        rows.update({(c.key, c.threads): c.advance for c in made})
        builds.append(build)
    pickle.dump("; ".join(builds), replies)
    replies.flush()
    while True:
        try:
            key, n_threads, state, step0, steps = pickle.load(requests)
        except EOFError:
            return
        try:
            reply = rows[(key, n_threads)](state, step0, steps)
        except Exception as error:  # told to the parent, which raises it
            reply = RuntimeError(f"{type(error).__name__}: {error}")
        pickle.dump(reply, replies, protocol=pickle.HIGHEST_PROTOCOL)
        replies.flush()
