"""starsense._validate: the one home of scalar, array and rotation checks.

Messages name the parameter they were given (never a command-line option) and show values as
plain numbers, never as ``np.float64(...)`` reprs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense._validate import (
    check_int,
    check_rotation,
    check_scalar,
    finite_array,
    finite_float,
    positive_float,
    show,
    vectors3,
)
from starsense.errors import InputError


def _message(func, *args, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        func(*args, **kwargs)
    text = str(info.value)
    assert "np.float" not in text and "np.int" not in text and "array(" not in text, text
    return text


@pytest.mark.parametrize("value", [np.float64(2.5), np.float32(2.5), 2.5, "2.5", np.array(2.5)])
def test_finite_float_accepts_real_numbers(value):
    out = finite_float(value, "x")
    assert out == 2.5 and type(out) is float


@pytest.mark.parametrize(
    ("value", "expect"),
    [
        (math.nan, "rate_rad_s must be finite, got nan"),
        (np.float64(np.inf), "rate_rad_s must be finite, got inf"),
        ("abc", "rate_rad_s must be a real number, got 'abc'"),
        (True, "rate_rad_s must be a real number, got True"),
        (None, "rate_rad_s must be a real number, got None"),
        ([1.0], "rate_rad_s must be a real number"),
    ],
)
def test_finite_float_messages_name_the_parameter(value, expect):
    assert expect in _message(finite_float, value, "rate_rad_s")


def test_check_scalar_bounds_closed_and_open():
    assert check_scalar(0.0, "x", 0.0, 1.0) == 0.0
    assert check_scalar(1.0, "x", 0.0, 1.0) == 1.0
    text = _message(check_scalar, np.float64(0.0), "exposure_s", 0.0, lo_open=True)
    assert text == "exposure_s = 0.0 is out of range; must be in (0.0, inf]"
    text = _message(check_scalar, 2, "fraction", 0, 1, hi_open=True)
    assert text == "fraction = 2 is out of range; must be in [0, 1)"
    text = _message(check_scalar, np.float64(-3.5), "dec_rad", -1.5, 1.5)
    assert text == "dec_rad = -3.5 is out of range; must be in [-1.5, 1.5]"


def test_check_scalar_infinity_only_when_allowed():
    assert "must be finite" in _message(check_scalar, math.inf, "max_mag")
    assert check_scalar(math.inf, "max_mag", allow_inf=True) == math.inf
    assert "out of range" in _message(check_scalar, -math.inf, "max_mag", 0.0, allow_inf=True)
    assert "must be a real number" in _message(check_scalar, math.nan, "max_mag", allow_inf=True)
    assert "must be a real number" in _message(check_scalar, True, "max_mag", allow_inf=True)


def test_positive_float():
    assert positive_float(np.float64(0.1), "diameter_m") == 0.1
    assert _message(positive_float, 0, "diameter_m") == "diameter_m must be > 0, got 0"
    assert _message(positive_float, np.float64(-2.0), "diameter_m") == (
        "diameter_m must be > 0, got -2.0"
    )


def test_check_int():
    assert check_int(np.int64(3), "n_trials", 1) == 3
    assert check_int(4.0, "n_trials", 1) == 4
    assert _message(check_int, True, "n_trials") == "n_trials must be an integer, got True"
    assert _message(check_int, 2.5, "n_trials") == "n_trials must be an integer, got 2.5"
    assert _message(check_int, np.int64(0), "n_trials", 1) == "n_trials must be >= 1, got 0"
    assert _message(check_int, 11, "n_min", 1, 10) == "n_min must be <= 10, got 11"


def test_finite_array_and_vectors3():
    arr = finite_array([1, 2, 3], "weights")
    assert arr.dtype == np.float64 and arr.tolist() == [1.0, 2.0, 3.0]
    assert _message(finite_array, [1.0, np.nan], "weights") == (
        "weights = nan is not allowed; must be finite"
    )
    assert "weights must be a real number or array" in _message(finite_array, ["a"], "weights")
    assert vectors3([0.0, 0.0, 1.0], "v").shape == (3,)
    assert _message(vectors3, np.zeros((4, 2)), "vectors") == (
        "vectors must have shape (N, 3) or (3,), got shape (4, 2)"
    )


def test_check_rotation():
    single = Rotation.identity()
    assert check_rotation(single, "attitude") is single
    batch = Rotation.identity(3)
    assert check_rotation(batch, "attitudes") is batch
    assert _message(check_rotation, np.eye(3), "attitude") == (
        "attitude must be a scipy Rotation, got ndarray"
    )


def test_show_is_plain():
    assert show(np.float64(1.5)) == "1.5"
    assert show(np.float64(2.0)) == "2.0"
    assert show(np.int64(7)) == "7"
    assert show("x") == "'x'"
