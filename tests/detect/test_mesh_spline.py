"""The background mesh's natural cubic spline weights (NumPy) against scipy's CubicSpline."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from starsense.detect.mesh import natural_spline_weights


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(3, 40))
def test_weights_are_scipy_natural_cubic_spline(seed, m):
    rng = np.random.default_rng(seed)
    knots = np.cumsum(rng.uniform(0.5, 80.0, m))  # box centres: uneven spacing allowed
    x = np.sort(rng.uniform(knots[0], knots[-1], 300))
    x[:2] = knots[0], knots[-1]  # the ends themselves
    expected = CubicSpline(knots, np.eye(m), bc_type="natural")(x)
    got = natural_spline_weights(knots, x)
    # the same spline, by another float64 evaluation: the second derivatives solve a
    # diagonally dominant tridiagonal system (condition <= 3), so the two agree to a few
    # hundred ulps of the weights (which are <= ~1.2)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_weights_reproduce_a_line_and_interpolate_the_knots():
    knots = np.array([31.5, 95.5, 159.5, 223.5, 287.5, 351.5, 415.5, 479.5])
    x = np.linspace(knots[0], knots[-1], 1001)
    w = natural_spline_weights(knots, x)
    np.testing.assert_allclose(w @ (3.0 * knots - 7.0), 3.0 * x - 7.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(natural_spline_weights(knots, knots), np.eye(knots.size), atol=1e-13)
