"""Static PSF: eq. 9 integrated exactly over pixel areas."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.special import erf

from starsense.errors import InputError
from starsense.render.psf import Box, erf_diff, gaussian_intensity, gaussian_stamp, pixel_profile


def test_pixel_value_equals_numerical_area_integral_of_eq9() -> None:
    # One pixel of the stamp against scipy's adaptive 2-D quadrature of eq. 9 over the pixel's
    # area (dblquad reaches ~1e-12 relative on this smooth integrand; we ask 1e-9).
    x, y, sigma, e = 10.3, 7.8, 1.5, 1234.0
    stamp, r0, c0 = gaussian_stamp(x, y, sigma_px=sigma, electrons=e)
    for r, c in [(8, 10), (7, 12), (5, 9), (9, 14)]:
        ref, _ = integrate.dblquad(
            lambda py, px: gaussian_intensity(px, py, x=x, y=y, sigma_px=sigma, electrons=e),
            c - 0.5,
            c + 0.5,
            r - 0.5,
            r + 0.5,
            epsabs=0,
            epsrel=1e-12,
        )
        assert stamp[r - r0, c - c0] == pytest.approx(ref, rel=1e-9)


def test_stamp_sum_is_the_mass_inside_the_box() -> None:
    # The box's mass is the product of the two 1-D masses: erf at the box edges.
    x, y, sigma = 3.2, -1.7, 0.9
    box = Box(-4, 2, 0, 9)
    stamp, _, _ = gaussian_stamp(x, y, sigma_px=sigma, electrons=1.0, box=box)
    k = 1 / (math.sqrt(2) * sigma)
    mx = 0.5 * (erf((box.col1 - 0.5 - x) * k) - erf((box.col0 - 0.5 - x) * k))
    my = 0.5 * (erf((box.row1 - 0.5 - y) * k) - erf((box.row0 - 0.5 - y) * k))
    assert stamp.shape == box.shape
    assert stamp.sum() == pytest.approx(mx * my, rel=1e-13)


def test_default_box_holds_all_but_1e6_of_the_flux() -> None:
    # 5 sigma each side: the flux outside is at most 4 x P(|X| > 5)/2 ~ 1.1e-6.
    stamp, _, _ = gaussian_stamp(100.37, 50.81, sigma_px=1.5, electrons=1.0)
    assert 0 < 1 - stamp.sum() < 1.2e-6


def test_erf_diff_keeps_relative_accuracy_in_the_tails() -> None:
    # erf(10) - erf(9) is ~4e-37: 1 - 1 in double precision; the erfc form keeps it.
    # Reference: adaptive quadrature of 2/sqrt(pi) exp(-t^2), relative 1e-10.
    for a, b in [(10.0, 9.0), (-9.0, -10.0), (6.0, 5.5), (0.3, -0.2), (1e-9, -1e-9)]:
        ref, _ = integrate.quad(
            lambda t: 2 / math.sqrt(math.pi) * math.exp(-t * t), b, a, epsabs=0, epsrel=1e-13
        )
        assert float(erf_diff(a, b)) == pytest.approx(ref, rel=1e-10)
    assert erf(10.0) - erf(9.0) == 0.0  # the naive form has lost everything


def test_pixel_profile_sums_to_one_and_is_symmetric() -> None:
    p = pixel_profile(-20, 21, [0.0, 0.25], sigma_px=2.0)
    assert p.shape == (2, 41)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(p[0], p[0][::-1], rtol=1e-14)


def test_box_around_and_clip() -> None:
    b = Box.around(x_min=10.0, x_max=10.0, y_min=5.0, y_max=5.0, pad_px=1.0)
    # pixels meeting [9, 11] x [4, 6]: columns 9..11, rows 4..6
    assert b == Box(4, 7, 9, 12)
    assert Box(-3, 5, 10, 20).clip(4, 15) == Box(0, 4, 10, 15)
    assert Box(-3, -1, 0, 5).clip(10, 10) is None


def test_bad_sigma_and_position() -> None:
    with pytest.raises(InputError, match="sigma_px"):
        gaussian_stamp(0.0, 0.0, sigma_px=0.0)
    with pytest.raises(InputError, match="position"):
        gaussian_stamp(float("nan"), 0.0, sigma_px=1.0)
    with pytest.raises(InputError, match="non-empty"):
        gaussian_stamp(0.0, 0.0, sigma_px=1.0, box=(0, 0, 0, 3))
