"""The shared validators of warpratchet.errors: accepted types, refused values, one-line messages."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warpratchet.errors import ParameterError, check_choice, check_count, check_optional, check_real


@pytest.mark.parametrize("value", [5, np.int64(5), np.int32(5), np.uint8(5)])
def test_count_accepts_any_integral_type_and_returns_int(value):
    out = check_count("points", value, low=1)
    assert out == 5 and type(out) is int


@pytest.mark.parametrize("value", [True, 5.0, "5", None, np.float64(5.0)])
def test_count_refuses_bool_floats_and_strings(value):
    with pytest.raises(
        ParameterError, match=r"^points = .* is not an integer \(allowed range 1 <= points\)$"
    ):
        check_count("points", value, low=1)


def test_count_range_message_names_value_and_range():
    with pytest.raises(
        ParameterError, match=r"^threads = 0 is outside the allowed range 1 <= threads <= 64$"
    ):
        check_count("threads", 0, low=1, high=64)
    with pytest.raises(ParameterError, match="outside the allowed range"):
        check_count("threads", np.int64(65), low=1, high=64)


@pytest.mark.parametrize("value", [0.5, np.float32(0.5), np.float64(0.5), 1, np.int64(1)])
def test_real_accepts_any_real_type_and_returns_float(value):
    out = check_real("threshold", value, low=0.0)
    assert out == float(value) and type(out) is float


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, np.float64("nan")])
def test_real_refuses_non_finite(value):
    with pytest.raises(
        ParameterError, match=r"^threshold = .* is not finite \(allowed range 0.0 <= threshold\)$"
    ):
        check_real("threshold", value, low=0.0)


def test_real_bounds_open_and_closed():
    assert check_real("K", 4.0, 0.0, 4.0) == 4.0
    with pytest.raises(ParameterError, match=r"^K = 4.0 is outside the allowed range 0.0 < K < 4.0$"):
        check_real("K", 4.0, 0.0, 4.0, low_open=True, high_open=True)
    with pytest.raises(ParameterError, match="not a real number"):
        check_real("K", True)


def test_choice_and_optional():
    assert check_choice("init", "strip", ("strip", "torus")) == "strip"
    with pytest.raises(ParameterError, match=r"^init = 'disk' is not one of strip, torus$"):
        check_choice("init", "disk", ("strip", "torus"))
    assert check_optional(check_real, "threshold", None, low=0.0) is None
    assert check_optional(check_real, "threshold", 1, low=0.0) == 1.0


@given(st.integers(min_value=-(2**70), max_value=2**70), st.integers(-5, 5), st.integers(-5, 5))
def test_count_is_exactly_the_range_check(value, low, span):
    high = low + abs(span)
    inside = low <= value <= high
    if inside:
        assert check_count("n", value, low, high) == value
    else:
        with pytest.raises(ParameterError):
            check_count("n", value, low, high)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_real_never_returns_non_finite(value):
    try:
        out = check_real("x", value)
    except ParameterError as exc:
        assert "\n" not in str(exc)
    else:
        assert math.isfinite(out)
