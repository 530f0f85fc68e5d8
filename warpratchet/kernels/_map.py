"""``advance_map``: the map and its tangent, nothing else (the plain variant of the step loop)."""

import warp as wp

from ._advance import Variant, advance_kernel
from ._step import Lanes

__all__ = ["advance_map", "PLAIN"]


@wp.struct
class _NoArrays:
    pass


@wp.struct
class _NoAccumulators:
    pass


@wp.func
def _load(arrays: _NoArrays, first: int, spacing: int, n: int):
    return _NoAccumulators()


@wp.func
def _store(arrays: _NoArrays, acc: _NoAccumulators, first: int, spacing: int, n: int):
    pass


@wp.func
def _nothing(acc: wp.ref[_NoAccumulators], s: wp.ref[Lanes], counter: wp.int64):
    pass


@wp.func
def _point_load(arrays: _NoArrays, i: int):
    return _NoAccumulators()


@wp.func
def _point_after_check(
    acc: _NoAccumulators, dx: wp.float64, dp: wp.float64, log_stretch: wp.float64, check: wp.int64
):
    return acc


@wp.func
def _point_store(arrays: _NoArrays, i: int, acc: _NoAccumulators):
    pass


#: No per-step work: the hooks are empty and vanish when inlined.
PLAIN = Variant(
    "map",
    _NoArrays,
    _NoAccumulators,
    _load,
    _store,
    None,
    _nothing,
    point_load=_point_load,
    point_after_check=_point_after_check,
    point_store=_point_store,
)

#: Advance the state by ``steps`` iterations of Eq. (cpem) and of ``DM`` from global step ``step0``.
advance_map = advance_kernel(PLAIN, one_point=True)
