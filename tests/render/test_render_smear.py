"""Smeared PSF (eqs. 13-22) and its pixel integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate
from scipy.special import erf

from starsense.render.psf import Box, gaussian_intensity, gaussian_stamp
from starsense.render.smear import (
    gauss_legendre_order,
    polyline_expected,
    segment_expected,
    smear_intensity,
)
from starsense.render.tracks import star_tracks


def paper_eq20(x, y, x0, y0, dbx, dby, sigma, s_e, t_e):
    """Dzamba & Enright eqs. 16-22 as printed (S_b, electrons x seconds per px^2)."""
    a2 = -(dbx**2 + dby**2) / (2 * sigma**2 * t_e**2)  # eq. 17
    a1 = (dbx * (x - x0) + dby * (y - y0)) / (sigma**2 * t_e)  # eq. 18
    a0 = (-(x0**2 + x**2 + y0**2 + y**2) + 2 * (x0 * x + y0 * y)) / (2 * sigma**2)  # eq. 19
    big_a0 = s_e / (2 * math.pi * sigma**2)  # eq. 21
    r = np.sqrt(-a2)
    big_b0 = math.sqrt(math.pi) / (2 * r) * (erf(0.5 * a1 / r) - erf(0.5 * (2 * a2 * t_e + a1) / r))
    return big_a0 * big_b0 * np.exp((4 * a0 * a2 - a1**2) / (4 * a2))  # eq. 20


def brute_force(px, py, x0, y0, x1, y1, sigma, s_e, steps=2000):
    """Time average of the moving eq. 9 (eqs. 13-14): composite Simpson over `steps` steps.

    Error ~ (L / steps / sigma)^4 / 180 relative to the peak: < 1e-10 for the streaks here.
    """
    f = np.linspace(0.0, 1.0, steps + 1)
    xs, ys = x0 + f * (x1 - x0), y0 + f * (y1 - y0)
    px = np.asarray(px, dtype=float)[..., None]
    py = np.asarray(py, dtype=float)[..., None]
    r2 = (px - xs) ** 2 + (py - ys) ** 2
    s_t = s_e / (2 * math.pi * sigma**2) * np.exp(-r2 / (2 * sigma**2))
    return integrate.simpson(s_t, x=f, axis=-1)


def test_closed_form_is_eq20_divided_by_exposure() -> None:
    # The along/across form is eq. 20 rearranged (smear.py docstring): same numbers where the
    # printed form is well conditioned (exponent and erf arguments of order 1-30).
    rng = np.random.default_rng(1)
    x0, y0, dbx, dby, sigma, s_e, t_e = 3.0, -2.0, 9.0, 4.0, 1.5, 800.0, 0.1
    px = rng.uniform(-5, 15, 200)
    py = rng.uniform(-8, 6, 200)
    ours = (
        smear_intensity(
            px, py, x0=x0, y0=y0, x1=x0 + dbx, y1=y0 + dby, sigma_px=sigma, electrons=s_e
        )
        * t_e
    )
    ref = paper_eq20(px, py, x0, y0, dbx, dby, sigma, s_e, t_e)
    np.testing.assert_allclose(ours, ref, rtol=1e-10, atol=1e-12 * ref.max())


@pytest.mark.parametrize(
    ("x0", "y0", "x1", "y1", "sigma"),
    [
        (0.0, 0.0, 10.0, 0.0, 1.5),
        (1.0, 2.0, 8.0, 9.0, 1.0),
        (0.0, 0.0, 0.3, -0.2, 2.0),
        (5.0, 5.0, -20.0, 30.0, 0.8),
    ],
)
def test_closed_form_equals_brute_force_time_integral(x0, y0, x1, y1, sigma) -> None:
    # Simpson with 2000 time steps (error < 1e-10 of the peak); we ask 1e-6 of the peak.
    g = np.linspace(-8, 8, 33)
    px = (x0 + x1) / 2 + g[:, None] * 2 + 0 * g[None, :]
    py = (y0 + y1) / 2 + g[None, :] * 2 + 0 * g[:, None]
    ours = smear_intensity(px, py, x0=x0, y0=y0, x1=x1, y1=y1, sigma_px=sigma, electrons=1000.0)
    ref = brute_force(px, py, x0, y0, x1, y1, sigma, 1000.0)
    peak = ref.max()
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-6 * peak)


def test_closed_form_keeps_relative_accuracy_far_in_the_tails() -> None:
    # Points 8-9 sigma beyond either end and 0-2 sigma across: both erf arguments large, and
    # the printed eq. 22 cancels to ~1e-16 absolute, i.e. loses everything (values < 1e-14).
    # The brute-force Simpson sum of positive terms stays accurate relative to the values
    # themselves (the integrand changes by exp(-u L / sigma^2) ~ e^-36 along the streak, steep
    # but resolved by 20000 steps to ~1e-8); we ask 1e-6 relative.
    sigma, x0, x1 = 1.0, 0.0, 4.0
    px = np.array([-8.0, -9.0, 12.0, 13.0, -8.5])
    py = np.array([0.0, 1.0, 0.5, 2.0, -1.5])
    ours = smear_intensity(px, py, x0=x0, y0=0.0, x1=x1, y1=0.0, sigma_px=sigma)
    ref = brute_force(px, py, x0, 0.0, x1, 0.0, sigma, 1.0, steps=20000)
    assert np.all(ref > 0) and np.all(ref < 1e-14)
    np.testing.assert_allclose(ours, ref, rtol=1e-6)
    naive = paper_eq20(px, py, x0, 0.0, x1 - x0, 0.0, sigma, 1.0, 1.0)
    assert not np.allclose(naive, ref, rtol=1e-2, atol=0)


def test_zero_length_limit_is_eq9() -> None:
    px, py = np.meshgrid(np.linspace(-5, 5, 11), np.linspace(-4, 4, 9))
    static = gaussian_intensity(px, py, x=0.2, y=-0.3, sigma_px=1.5, electrons=10.0)
    exact0 = smear_intensity(px, py, x0=0.2, y0=-0.3, x1=0.2, y1=-0.3, sigma_px=1.5, electrons=10.0)
    np.testing.assert_array_equal(exact0, static)
    # just above the switch to eq. 9 (L = 1e-6 sigma): continuous to ~1e-9
    tiny = smear_intensity(
        px, py, x0=0.2, y0=-0.3, x1=0.2 + 3e-6, y1=-0.3, sigma_px=1.5, electrons=10.0
    )
    np.testing.assert_allclose(
        tiny,
        gaussian_intensity(px, py, x=0.2 + 1.5e-6, y=-0.3, sigma_px=1.5, electrons=10.0),
        rtol=1e-8,
    )


@pytest.mark.parametrize("method", ["track", "closed-form"])
@pytest.mark.parametrize(
    ("dx", "dy"), [(0.0, 0.0), (12.7, 0.0), (0.0, -30.0), (20.0, 20.0), (-100.0, 37.0)]
)
def test_flux_is_conserved(method, dx, dy) -> None:
    # A streak stamp (not clipped) holds the star's electrons less the tails beyond 5 sigma of
    # the track: < 1.2e-6 (static: 4 sides x P(X > 5 sigma) = 4 x 2.9e-7) and less for streaks.
    # Ask 2e-6 (the brief asks 0.1 %), and that nothing is created: the sum never exceeds the
    # electrons (+ 1e-9 for the quadrature's ~1e-8 error).
    e = 5000.0
    stamp, _ = polyline_expected(
        [100.3, 100.3 + dx], [50.6, 50.6 + dy], sigma_px=1.5, electrons=e, method=method
    )
    assert stamp.sum() == pytest.approx(e, rel=2e-6)
    assert stamp.sum() <= e * (1 + 1e-9)
    assert stamp.min() >= 0


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-3, 3),
    y=st.floats(-3, 3),
    dx=st.floats(-60, 60),
    dy=st.floats(-60, 60),
    sigma=st.floats(0.6, 3.0),
)
def test_flux_is_conserved_property(x, y, dx, dy, sigma) -> None:
    stamp, _ = polyline_expected([x, x + dx], [y, y + dy], sigma_px=sigma, electrons=1.0)
    assert abs(stamp.sum() - 1.0) < 2e-6


def test_zero_rate_gives_the_static_gaussian_exactly(st16) -> None:
    # Both quadratures fall back on the exact erf products for a track of zero length.
    for method in ("track", "closed-form"):
        stamp, box = polyline_expected(
            [12.3, 12.3], [40.8, 40.8], sigma_px=1.5, electrons=777.0, method=method
        )
        ref, r0, c0 = gaussian_stamp(12.3, 40.8, sigma_px=1.5, electrons=777.0, box=box)
        assert (r0, c0) == (box.row0, box.col0)
        np.testing.assert_allclose(stamp, ref, rtol=1e-15, atol=1e-15 * ref.max())
    # ... and so does a whole track at zero body rate
    v = st16.unproject([1000.25], [700.5])
    tr = star_tracks(st16, v, rate_rad_s=(0.0, 0.0, 0.0))
    assert tr.n_segments.tolist() == [1]
    np.testing.assert_allclose(tr.vertices[0], [[1000.25, 700.5]] * 2, atol=1e-9)


@pytest.mark.parametrize("sigma", [0.4, 0.5, 0.8, 1.0, 1.5, 2.5])
def test_closed_form_pixel_quadrature_error_bound(sigma) -> None:
    # The n x n Gauss-Legendre rule (n = gauss_legendre_order) on the closed form of a
    # 1e-5 px streak (above the eq. 9 switch; the smear itself changes the image by
    # ~(L / sigma)^2 / 12 < 1e-10) against the exact erf products: the summed absolute error is
    # the rule's error, documented as < 1e-7 of the flux for every sigma.
    assert gauss_legendre_order(sigma) == max(4, math.ceil(4 / sigma))
    worst = 0.0
    for x0, y0 in [(0.0, 0.0), (0.5, 0.25), (0.31, -0.47)]:
        box = Box.around(x_min=x0, x_max=x0, y_min=y0, y_max=y0, pad_px=8 * sigma)
        gl = segment_expected(
            x0=x0,
            y0=y0,
            x1=x0 + 1e-5,
            y1=y0,
            sigma_px=sigma,
            electrons=1.0,
            box=box,
            method="closed-form",
        )
        exact = gaussian_stamp(x0 + 5e-6, y0, sigma_px=sigma, electrons=1.0, box=box)[0]
        worst = max(worst, np.abs(gl - exact).sum())
    assert worst < 1e-7


@pytest.mark.parametrize("sigma", [0.7, 1.0, 1.5, 2.5])
def test_the_two_quadratures_agree(sigma) -> None:
    # Two orders of integration of the same triple integral: "track" (exact in x, y;
    # Gauss-Legendre in time, error < 1e-8) and "closed-form" (exact in time; Gauss-Legendre
    # in x, y, error < 1e-7). They must agree to the sum of their bounds.
    for xs, ys in [([0.2, 14.0], [0.1, 3.0]), ([0.0, 30.0], [0.0, 30.0]), ([5.0, 4.0], [0.0, 0.2])]:
        a, box = polyline_expected(xs, ys, sigma_px=sigma, electrons=1.0, method="track")
        b, _ = polyline_expected(
            xs, ys, sigma_px=sigma, electrons=1.0, box=box, method="closed-form"
        )
        assert np.abs(a - b).sum() < 1.1e-7


def test_long_streak_pieces_match_a_single_box() -> None:
    # Long streaks are rendered in <= 48 px pieces, each in its own box: the same image as one
    # evaluation of the whole streak over the whole box, within the flux beyond 5 sigma of
    # each piece (< 1e-6).
    xs, ys = [0.0, 150.0], [0.0, 110.0]
    pieces, box = polyline_expected(xs, ys, sigma_px=1.5, electrons=1.0)
    whole = segment_expected(
        x0=0.0, y0=0.0, x1=150.0, y1=110.0, sigma_px=1.5, electrons=1.0, box=box
    )
    assert np.abs(pieces - whole).sum() < 2e-6
    assert pieces.sum() == pytest.approx(1.0, abs=2e-6)
