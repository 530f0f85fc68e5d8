"""The step loop, written once, and kernel variants built on it.

:func:`advance_kernel` turns a :class:`Variant` into an :class:`AdvanceKernel`: a Warp kernel
that loads a thread's lanes, runs ``steps`` iterations of the step body of
:mod:`warpratchet.kernels.step` (with the renormalisation check after every global step that
is a multiple of ``RENORM_CHECK_EVERY``) and stores them back, built twice, on the CPU body and
on the portable one. A variant adds per-step work on top through two hooks, inlined into the
loop: ``after_step`` (every step; sees the state and the step's facts ``gain`` and
``in_strip``) and ``after_check`` (after each renormalisation check, with the check number
``j = global_step / RENORM_CHECK_EVERY``). A variant without per-step work (``after_step`` None:
the plain variant, the indicators) runs, on the CPU body, the steps between two checks in one
call of the body's ``steps`` (the lanes stay in registers and the map's constants are computed
once per call), so a plain run pays nothing for the variants it does not use. A variant keeps
per-lane accumulators in its own struct and per-point arrays in another (a kernel argument),
loaded and stored with the state.

Checks sit at *global* step numbers (``step0`` is 64-bit), so a run split into any chunks, or
resumed, renormalises at the same steps and stays bitwise equal. One launch advances at most
:data:`MAX_LAUNCH_STEPS` steps (the loop counter is 32-bit); :meth:`AdvanceKernel.launch`
refuses more, and ``Ensemble`` splits longer chunks.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import warp as wp

from .runtime import CPU_MODULE, CPU_MODULE_OPTIONS, MODULE_OPTIONS, PORTABLE_MODULE, check_cpu_isa_runs
from .step import CPU, INTERLEAVE, PORTABLE, RENORM_CHECK_EVERY, Body, Coefficients, State

__all__ = ["MAX_LAUNCH_STEPS", "Variant", "AdvanceKernel", "advance_kernel", "launch_dim"]

#: Most steps one launch advances (the kernel's loop counter is a 32-bit int).
MAX_LAUNCH_STEPS = 2**31 - 1


def launch_dim(n: int) -> int:
    """Number of Warp threads that advance ``n`` points."""
    return (n + INTERLEAVE - 1) // INTERLEAVE


@dataclass(frozen=True)
class Variant:
    """Per-step work on top of the step body (see the module docstring).

    ``arrays``: a ``wp.struct`` of per-point arrays, shape ``(n,)`` each, passed to the kernel;
    ``accumulators``: a ``wp.struct`` of per-lane values. The hooks are ``wp.func``s::

        load(arrays, first, spacing, n) -> accumulators      # lane k is point first + k*spacing
        store(arrays, accumulators, first, spacing, n)
        after_step(ref accumulators, ref Lanes, global_step: int64)   # or None: no per-step work
        after_check(ref accumulators, ref Lanes, check: int64)

    ``cpu_after_step``, ``cpu_after_check``, ``cpu_load``, ``cpu_store``: optional replacements
    used with the CPU body (e.g. a ``wp.func_native`` on whole lane vectors; ``cpu_load`` and
    ``cpu_store`` for a variant whose CPU hooks keep accumulators of their own type and defer
    work to the end of the launch); they must give bitwise the same results,
    which ``tests/test_kernels.py`` checks for the package's variants (add a new one there).
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


@wp.func
def _no_step_work(acc: Any, s: Any, global_step: wp.int64):
    pass


def _build(variant: Variant, body: Body, module: str, options: dict) -> wp.Kernel:
    check_mask = wp.int64(RENORM_CHECK_EVERY - 1)
    check_shift = wp.int64(RENORM_CHECK_EVERY.bit_length() - 1)
    after_step, after_check, store = variant.after_step, variant.after_check, variant.store
    load = variant.load
    if body is CPU:
        after_step = variant.cpu_after_step or after_step
        after_check = variant.cpu_after_check or after_check
        load = variant.cpu_load or load
        store = variant.cpu_store or store

    # Without per-step work the CPU body runs the steps between two checks in one call; the
    # portable body keeps one step per iteration (what CUDA runs).
    runs = after_step is None and body is CPU
    after_step = after_step or _no_step_work

    def advance(state: State, extra: variant.arrays, step0: wp.int64, steps: int, p: Coefficients):
        tid = wp.tid()
        n = state.x.shape[0]
        first, spacing = wp.static(body.layout)(tid, n)
        s = wp.static(body.load)(state, first, spacing, n)
        acc = wp.static(load)(extra, first, spacing, n)
        global_step = step0
        if wp.static(runs):
            remaining = steps
            while remaining > 0:
                # The run of steps up to the next check (or the launch's end), in one call.
                run = wp.min(
                    wp.static(RENORM_CHECK_EVERY) - int(global_step & wp.static(check_mask)), remaining
                )
                wp.static(body.steps)(s, p, wp.int32(run))
                global_step = global_step + wp.int64(run)
                remaining = remaining - run
                if (global_step & wp.static(check_mask)) == wp.int64(0):
                    wp.static(body.renorm)(s)
                    wp.static(after_check)(acc, s, global_step >> wp.static(check_shift))
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

    wp.set_module_options(options, module)
    return wp.kernel(advance, name=f"advance_{variant.name}", module=module)


class AdvanceKernel:
    """A variant's kernel on both step bodies; :meth:`launch` picks the body for the device."""

    def __init__(self, variant: Variant, module_suffix: str = "") -> None:
        self.variant = variant
        self.cpu = _build(variant, CPU, CPU_MODULE + module_suffix, CPU_MODULE_OPTIONS)
        self.portable = _build(variant, PORTABLE, PORTABLE_MODULE + module_suffix, MODULE_OPTIONS)

    def kernel(self, device: str, body: str | None = None) -> wp.Kernel:
        """The Warp kernel for ``device``: the CPU body on the CPU, the portable one elsewhere.

        ``body="portable"`` forces the portable body (tests compare the two on the CPU).
        """
        if body is None:
            body = "cpu" if wp.get_device(device).is_cpu else "portable"
        if body == "cpu" and not wp.get_device(device).is_cpu:
            raise ValueError(f"the CPU step body does not run on {device}")
        return {"cpu": self.cpu, "portable": self.portable}[body]

    def load(self, device: str, body: str | None = None) -> None:
        """Compile (or load from Warp's kernel cache) the module that :meth:`launch` will use."""
        wp.load_module(self.kernel(device, body).module, device=device)

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
        if not 0 <= steps <= MAX_LAUNCH_STEPS:
            raise ValueError(f"steps = {steps} is outside the allowed range 0 <= steps <= {MAX_LAUNCH_STEPS}")
        if not 0 <= step0 < 2**63 - steps:
            raise ValueError(f"step0 = {step0} is outside the allowed range 0 <= step0 < 2^63 - steps")
        arguments = [_fill(State(), state), _fill(self.variant.arrays(), extra), step0, steps]
        kernel = self.kernel(device, body)
        if kernel is self.cpu:
            check_cpu_isa_runs()
        wp.launch(
            kernel,
            dim=launch_dim(state[0].shape[0]),
            inputs=[*arguments, coefficients(params)],
            device=device,
        )


def _fill(struct: Any, arrays: Sequence[wp.array]) -> Any:
    names = list(struct._cls.vars)
    if len(names) != len(arrays):
        raise ValueError(f"expected {len(names)} arrays ({', '.join(names)}), got {len(arrays)}")
    for name, array in zip(names, arrays, strict=True):
        setattr(struct, name, array)
    return struct


def coefficients(params: Any) -> Coefficients:
    """The kernel's view of the map (Eqs. fx, mmc) from a ``MapParams``."""
    c = Coefficients()
    c.K, c.b1, c.right, c.l1, c.l2, c.c = params.K, params.b1, 1.0 - params.b2, params.l1, params.l2, params.c
    return c


def advance_kernel(variant: Variant, module_suffix: str = "") -> AdvanceKernel:
    """Build ``variant``'s kernel on both step bodies.

    The package's kernels share two Warp modules (one compilation each); ``module_suffix`` puts a
    variant in modules of its own (e.g. ``".transport"``), compiled only when it is used.
    """
    return AdvanceKernel(variant, module_suffix)
