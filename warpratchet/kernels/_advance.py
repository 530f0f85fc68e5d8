"""The step loop, written once, and kernel variants built on it.

:func:`advance_kernel` turns a :class:`Variant` into an :class:`AdvanceKernel`: a Warp kernel
that loads a thread's lanes, runs ``steps`` iterations of the step body of
:mod:`warpratchet.kernels._step` (with the renormalisation check after every global step that
is a multiple of ``RENORM_CHECK_EVERY``) and stores them back, built twice, on the CPU body and
on the portable one. A variant adds per-step work on top through two hooks, inlined into the
loop: ``after_step`` (every step; sees the state and the step's facts ``gain`` and
``in_strip``) and ``after_check`` (after each renormalisation check, with the check number
``j = global_step / RENORM_CHECK_EVERY``). A variant without per-step work (``after_step`` None:
the plain variant, the indicators) runs, on the CPU body, the steps between two checks in one
call of the body's ``steps`` (the lanes stay in registers and the map's constants are computed
once per call), so a plain run pays nothing for the variants it does not use. On the CPU body
such a kernel's Warp thread takes two blocks of lanes, the block of its own index ``2 tid``
and the next (:func:`launch_dim` with ``paired``), advanced together by the body's
``pair_steps``: eight independent chains of registers per step instead of four, which the
out-of-order cores need to hide a step's latency (``_step.PAIRED``). A variant keeps per-lane
accumulators in its own struct and per-point arrays in another (a kernel argument), loaded and
stored with the state (for each block).

Checks sit at *global* step numbers (``step0`` is 64-bit), so a run split into any chunks, or
resumed, renormalises at the same steps and stays bitwise equal. One launch advances at most
:data:`MAX_LAUNCH_STEPS` steps (the loop counter is 32-bit); :meth:`AdvanceKernel.launch`
refuses more, and ``Ensemble`` splits longer chunks.

A variant without per-step work (``one_point=True``: the plain map, the indicators) also gets a
third kernel, ``point``, that runs one point per thread with the portable body's one-point
functions and the variant's one-point hooks; it is what a GPU runs. A GPU thread that holds
:data:`INTERLEAVE` lanes keeps more state than its registers hold, so the lanes spill to local
memory; one point per thread stays in registers (``benchmarks/README.md`` has the
measurements). The CPU keeps its lane vectors.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import warp as wp

from ._runtime import (
    CPU_MODULE,
    CPU_MODULE_OPTIONS,
    MODULE_OPTIONS,
    PAIRED_CPU_FLAGS,
    PORTABLE_MODULE,
    check_cpu_isa_runs,
)
from ._step import (
    CPU,
    INTERLEAVE,
    PAIRED,
    PORTABLE,
    RENORM_CHECK_EVERY,
    Body,
    Coefficients,
    State,
    force_bodies,
)

__all__ = ["MAX_LAUNCH_STEPS", "Variant", "AdvanceKernel", "advance_kernel", "launch_dim"]

#: A kernel's state or variant arrays, in the order of its struct.
Arrays = Sequence[wp.array]

#: Most steps one launch advances (the kernel's loop counter is a 32-bit int).
MAX_LAUNCH_STEPS = 2**31 - 1


def launch_dim(n: int, paired: bool = False) -> int:
    """Number of Warp threads that advance ``n`` points (``paired``: two blocks of lanes each)."""
    lanes = 2 * INTERLEAVE if paired else INTERLEAVE
    return (n + lanes - 1) // lanes


@dataclass(frozen=True)
class Variant:
    """Per-step work on top of the step body (see the module docstring).

    ``arrays``: a ``wp.struct`` of per-point arrays, shape ``(n,)`` each, passed to the kernel;
    ``accumulators``: a ``wp.struct`` of per-lane values. The hooks are ``wp.func``s::

        load(arrays, first, spacing, n) -> accumulators      # lane k is point first + k*spacing
        store(arrays, accumulators, first, spacing, n)
        after_step(ref accumulators, ref Lanes, global_step: int64)   # or None: no per-step work
        after_check(ref accumulators, ref Lanes, check: int64)

    ``point_load(arrays, i) -> accumulators``, ``point_after_check(accumulators, dx, dp,
    log_stretch, check) -> accumulators`` and ``point_store(arrays, i, accumulators)``: the same
    work for one point, whose accumulators are a struct of scalars (the one-point kernel's hooks;
    a variant needs them for ``one_point=True``).

    ``cpu_after_step``, ``cpu_after_check``, ``cpu_load``, ``cpu_store``: optional replacements
    used with the CPU body (e.g. a ``wp.func_native`` on whole lane vectors; ``cpu_load`` and
    ``cpu_store`` for a variant whose CPU hooks keep accumulators of their own type and defer
    work to the end of the launch); they must give bitwise the same results,
    which ``tests/kernels/test_kernels.py`` checks for the package's variants (add a new one there).
    """

    name: str
    arrays: type
    accumulators: type
    load: Any
    store: Any
    after_step: Any
    after_check: Any
    cpu_after_step: Any = None
    cpu_after_check: Any = None
    cpu_store: Any = None
    cpu_load: Any = None
    point_load: Any = None
    point_after_check: Any = None
    point_store: Any = None
    #: ``cpu_steps(force) -> wp.func (ref accumulators, ref Lanes, Coefficients, count: int32,
    #: global_step: int64)``: with the CPU body, ``count`` steps from ``global_step`` with the
    #: variant's per-step work inside them (:func:`._step.cpu_steps_source`), in place of the body's
    #: ``step`` and ``cpu_after_step`` one step at a time.
    cpu_steps: Any = None


@wp.func
def _no_step_work(acc: Any, s: Any, global_step: wp.int64):
    pass


@wp.func
def _no_steps(acc: Any, s: Any, p: Coefficients, count: wp.int32, global_step: wp.int64):
    pass


def _without_step_work(variant: Variant) -> bool:
    """Whether ``variant`` has no per-step work (the plain map, the indicators): its CPU kernel runs
    the body's own steps, two blocks of lanes per thread where the body has ``pair_steps``."""
    return variant.after_step is None and variant.cpu_steps is None


def _build(variant: Variant, body: Body, module: str, options: dict) -> tuple[wp.Kernel, bool]:
    """``variant``'s kernel on ``body`` in ``module``, and whether its threads take two blocks of
    lanes (``pair_steps``; then the module is built with :data:`._runtime.PAIRED_CPU_FLAGS`)."""
    check_mask = wp.int64(RENORM_CHECK_EVERY - 1)
    check_shift = wp.int64(RENORM_CHECK_EVERY.bit_length() - 1)
    after_step, after_check, store = variant.after_step, variant.after_check, variant.store
    load = variant.load
    variant_steps = None
    if body.name == CPU.name:
        after_step = variant.cpu_after_step or after_step
        after_check = variant.cpu_after_check or after_check
        load = variant.cpu_load or load
        store = variant.cpu_store or store
        if variant.cpu_steps is not None:
            variant_steps = variant.cpu_steps(body.force)

    # Without per-step work, or with the variant's own steps, the CPU body runs the steps between
    # two checks in one call; the portable body keeps one step per iteration (what CUDA runs).
    runs = (after_step is None or variant_steps is not None) and body.name == CPU.name
    own_steps = variant_steps is not None
    pairs = body.pair_steps is not None and _without_step_work(variant)
    variant_steps = variant_steps or _no_steps
    after_step = after_step or _no_step_work

    def advance(state: State, extra: variant.arrays, step0: wp.int64, steps: int, p: Coefficients):
        tid = wp.tid()
        n = state.x.shape[0]
        first, spacing = wp.static(body.layout)(tid, n)
        if wp.static(pairs):
            first = first * 2  # this thread's two blocks: at 2 tid and 2 tid + 1 (launch_dim)
        s = wp.static(body.load)(state, first, spacing, n)
        acc = wp.static(load)(extra, first, spacing, n)
        global_step = step0
        if wp.static(pairs):
            second = first + wp.static(INTERLEAVE)
            s2 = wp.static(body.load)(state, second, spacing, n)
            acc2 = wp.static(load)(extra, second, spacing, n)
        if wp.static(runs):
            remaining = steps
            while remaining > 0:
                # The run of steps up to the next check (or the launch's end), in one call.
                run = wp.min(
                    wp.static(RENORM_CHECK_EVERY) - int(global_step & wp.static(check_mask)), remaining
                )
                if wp.static(pairs):
                    wp.static(body.pair_steps)(s, s2, p, wp.int32(run))
                elif wp.static(own_steps):
                    wp.static(variant_steps)(acc, s, p, wp.int32(run), global_step)
                else:
                    wp.static(body.steps)(s, p, wp.int32(run))
                global_step = global_step + wp.int64(run)
                remaining = remaining - run
                if (global_step & wp.static(check_mask)) == wp.int64(0):
                    wp.static(body.renorm)(s)
                    wp.static(after_check)(acc, s, global_step >> wp.static(check_shift))
                    if wp.static(pairs):
                        wp.static(body.renorm)(s2)
                        wp.static(after_check)(acc2, s2, global_step >> wp.static(check_shift))
        else:
            for _s in range(steps):
                wp.static(body.step)(s, p)
                global_step = global_step + wp.int64(1)
                wp.static(after_step)(acc, s, global_step)
                if (global_step & wp.static(check_mask)) == wp.int64(0):
                    wp.static(body.renorm)(s)
                    wp.static(after_check)(acc, s, global_step >> wp.static(check_shift))
        wp.static(body.store)(state, s, first, spacing, n)
        wp.static(store)(extra, acc, first, spacing, n)
        if wp.static(pairs):
            wp.static(body.store)(state, s2, second, spacing, n)
            wp.static(store)(extra, acc2, second, spacing, n)

    if pairs:
        options = {**options, "cpu_compiler_flags": options["cpu_compiler_flags"] + PAIRED_CPU_FLAGS}
    wp.set_module_options(options, module)
    return wp.kernel(advance, name=f"advance_{variant.name}", module=module), pairs


def _build_point(variant: Variant, body: Body, module: str, options: dict) -> wp.Kernel:
    """``variant`` with one point per thread (thread ``i`` advances point ``i``), from the
    portable ``body``'s one-point step and check and the variant's one-point hooks."""
    if variant.point_after_check is None:
        raise ValueError(f"the {variant.name} variant has no one-point hooks")
    check_mask = wp.int64(RENORM_CHECK_EVERY - 1)
    check_shift = wp.int64(RENORM_CHECK_EVERY.bit_length() - 1)

    def advance_point(state: State, extra: variant.arrays, step0: wp.int64, steps: int, p: Coefficients):
        i = wp.tid()
        x = state.x[i]
        q = state.q[i]
        dx = state.dx[i]
        dp = state.dp[i]
        log_stretch = state.log_stretch[i]
        acc = wp.static(variant.point_load)(extra, i)
        w = wp.float64(0.0)
        global_step = step0
        for _s in range(steps):
            x, q, w, dx, dp, gain, in_strip = wp.static(body.point_step)(x, q, w, dx, dp, p)
            global_step = global_step + wp.int64(1)
            if (global_step & wp.static(check_mask)) == wp.int64(0):
                dx, dp, log_stretch = wp.static(body.point_renorm)(dx, dp, log_stretch)
                acc = wp.static(variant.point_after_check)(
                    acc, dx, dp, log_stretch, global_step >> wp.static(check_shift)
                )
        state.x[i] = x
        state.q[i] = q
        state.dx[i] = dx
        state.dp[i] = dp
        state.log_stretch[i] = log_stretch
        state.winding[i] = state.winding[i] + wp.int64(w)
        wp.static(variant.point_store)(extra, i, acc)

    wp.set_module_options(options, module)
    return wp.kernel(advance_point, name=f"advance_{variant.name}_point", module=module)


class AdvanceKernel:
    """A variant's kernel on each step body; :meth:`launch` picks the body for the device.

    ``one_point=True`` (a variant with no per-step work) adds the ``point`` kernel, the default
    off the CPU.
    """

    def __init__(
        self,
        variant: Variant,
        module_suffix: str = "",
        bodies: tuple[Body, Body] = (CPU, PORTABLE),
        one_point: bool = False,
    ) -> None:
        if PAIRED and not module_suffix and not _without_step_work(variant):
            # not paired: a module of its own, so that the shared one keeps the paired kernels' flags
            module_suffix = f".{variant.name}"
        self.variant = variant
        self.module_suffix = module_suffix
        self.one_point = one_point
        self.cpu, self.cpu_paired = _build(variant, bodies[0], CPU_MODULE + module_suffix, CPU_MODULE_OPTIONS)
        self.portable, _ = _build(variant, bodies[1], PORTABLE_MODULE + module_suffix, MODULE_OPTIONS)
        self.point = (
            _build_point(variant, bodies[1], PORTABLE_MODULE + module_suffix, MODULE_OPTIONS)
            if one_point
            else None
        )
        self._forces: dict[str, AdvanceKernel] = {}

    def for_force(self, table: Any) -> "AdvanceKernel":
        """This variant on the bodies of a force's piece table (:mod:`warpratchet.force`): itself
        for the paper's family, else kernels in modules of the force's own (built on first use)."""
        if table.family == "paper":
            return self
        if table.key not in self._forces:
            suffix = f"{self.module_suffix}.force_{table.key}"
            self._forces[table.key] = type(self)(self.variant, suffix, force_bodies(table), self.one_point)
        return self._forces[table.key]

    def _body(self, device: str, body: str | None) -> str:
        on_cpu = wp.get_device(device).is_cpu
        if body is None:
            body = "cpu" if on_cpu else ("point" if self.point is not None else "portable")
        if body == "cpu" and not on_cpu:
            raise ValueError(f"the CPU step body does not run on {device}")
        if body == "point" and self.point is None:
            raise ValueError(f"the {self.variant.name} variant has no one-point kernel")
        return body

    def kernel(self, device: str, body: str | None = None, table: Any = None) -> wp.Kernel:
        """The Warp kernel for ``device``: the CPU body on the CPU; elsewhere the one-point kernel
        where the variant has one, else the portable body.

        ``body="portable"`` or ``"point"`` forces that kernel (tests compare them on the CPU);
        ``table``, a force's piece table (default: the paper's family).
        """
        if table is not None:
            return self.for_force(table).kernel(device, body)
        return {"cpu": self.cpu, "portable": self.portable, "point": self.point}[self._body(device, body)]

    def load(self, device: str, body: str | None = None, table: Any = None) -> None:
        """Compile (or load from Warp's kernel cache) the module that :meth:`launch` will use."""
        wp.load_module(self.kernel(device, body, table).module, device=device)

    def launch(
        self,
        device: str,
        state: Sequence[wp.array],
        extra: Sequence[wp.array],
        step0: int,
        steps: int,
        params: Any,
        body: str | None = None,
    ) -> None:
        """Advance the points of ``state`` by ``steps`` iterations from global step ``step0``.

        ``state``: the arrays ``x, q, winding, dx, dp, log_stretch`` (shape ``(n,)``);
        ``extra``: the variant's arrays, in the order of its ``arrays`` struct; ``params``: a
        :class:`~warpratchet.params.MapParams` (``K, b1, b2, l1, l2, c``).
        """
        self.replay(self.recorded(device, state, extra, params, body), step0, steps)

    def recorded(self, device: str, state: Arrays, extra: Arrays, params: Any, body: str | None = None):
        """The launch :meth:`launch` would make on these arrays, recorded and not run: a ``wp.Launch``
        (Warp's ``wp.launch(..., record_cmd=True)``). :meth:`replay` runs it from any step without
        packing the arrays and the map's coefficients again, the Python work that a run would
        otherwise pay at every stop (``benchmarks/README.md``, "launch_cost.py")."""
        body = self._body(device, body)
        n = state[0].shape[0]
        dim = n if body == "point" else launch_dim(n, paired=body == "cpu" and self.cpu_paired)
        if body == "cpu":
            check_cpu_isa_runs()  # a setting fixed for the process: once per recording will do
        return wp.launch(
            self.kernel(device, body, params.table),
            dim=dim,
            inputs=[_fill(State(), state), _fill(self.variant.arrays(), extra), 0, 0, coefficients(params)],
            device=device,
            record_cmd=True,
        )

    def replay(self, launch: wp.Launch, step0: int, steps: int) -> None:
        """Run a :meth:`recorded` launch for ``steps`` iterations from global step ``step0``."""
        if not 0 <= steps <= MAX_LAUNCH_STEPS:
            raise ValueError(f"steps = {steps} is outside the allowed range 0 <= steps <= {MAX_LAUNCH_STEPS}")
        if not 0 <= step0 < 2**63 - steps:
            raise ValueError(f"step0 = {step0} is outside the allowed range 0 <= step0 < 2^63 - steps")
        launch.set_param_at_index_from_ctype(2, step0)  # the kernel's (state, extra, step0, steps, p)
        launch.set_param_at_index_from_ctype(3, steps)
        launch.launch()


def _fill(struct: Any, arrays: Sequence[wp.array]) -> Any:
    names = list(struct._cls.vars)
    if len(names) != len(arrays):
        raise ValueError(f"expected {len(names)} arrays ({', '.join(names)}), got {len(arrays)}")
    for name, array in zip(names, arrays, strict=True):
        setattr(struct, name, array)
    return struct


def coefficients(params: Any) -> Coefficients:
    """The kernel's view of the map (Eqs. fx, mmc) from a ``MapParams``: ``K`` and the paper's
    run-time coefficients by their fields (another force's are constants of its code)."""
    c = Coefficients()
    c.K = params.K
    for field, value in params.table.fields().items():
        setattr(c, field, value)
    return c


def advance_kernel(variant: Variant, module_suffix: str = "", one_point: bool = False) -> AdvanceKernel:
    """Build ``variant``'s kernel on both step bodies (and the one-point kernel if ``one_point``).

    The package's kernels share two Warp modules (one compilation each); ``module_suffix`` puts a
    variant in modules of its own (e.g. ``".transport"``), compiled only when it is used. A variant
    with per-step work always gets modules of its own (``.<name>`` where no suffix is given): the
    shared module is built with the paired kernels' flags.
    """
    return AdvanceKernel(variant, module_suffix, one_point=one_point)
