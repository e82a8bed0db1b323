"""The adaptive moments' streak of a star, checked on images GalSim draws.

GalSim renders the stars (an independent renderer); the expected answer is analytic: a
Gaussian of covariance ``C`` drawn into unit pixels has covariance ``C + I/12``, whose
anisotropy ``12 (lambda_1 - lambda_2)`` is that of ``C`` (the pixel's part is round), and a
streak ``l`` drawn on a round PSF adds ``l l^T / 12`` (a uniform segment's variance) along it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.detect.adaptive_moments import adaptive_axes

galsim = pytest.importorskip("galsim", reason="GalSim (the dev extra) draws the reference stars")

SIDE = 41


def _drawn(profile, x, y, flux=1.0e4):
    """``profile`` drawn at (x, y) (x = column) on a SIDE x SIDE frame of unit pixels."""
    img = galsim.ImageD(SIDE, SIDE, scale=1.0)
    # GalSim's pixel centres are at 1..SIDE; the frame's at 0..SIDE-1
    centre = galsim.PositionD(x + 1.0, y + 1.0)
    (profile.withFlux(flux)).drawImage(img, center=centre, add_to_image=True)
    return img.array


def _anisotropy(sig_a, sig_b, angle):
    lam = 12.0 * (sig_a**2 - sig_b**2)
    e = np.array([math.cos(angle), math.sin(angle)])
    return lam * np.outer(e, e)


@pytest.mark.parametrize(
    ("sig_a", "sig_b", "angle"), [(2.0, 2.0, 0.0), (3.0, 1.5, 0.4), (2.5, 1.2, -1.1)]
)
def test_a_gaussian_stars_anisotropy_is_its_covariances(sig_a, sig_b, angle):
    # the covariance R diag(a^2, b^2) R^T: a unit Gaussian stretched along the rotated axes
    c, s = math.cos(angle), math.sin(angle)
    jac = np.array([[c, -s], [s, c]]) @ np.diag([sig_a, sig_b])
    star = galsim.Gaussian(sigma=1.0).transform(*jac.ravel())
    x, y = 20.3, 19.8
    got = adaptive_axes(_drawn(star, x, y), [x], [y], half_px=20, start_sigma_px=1.5, level=0.0)
    # noise-free and Gaussian, the fixed point is exact: what is left is where the weight stops
    # (settled to 1e-3 px^2, times 12) and the window's cut of the wings (at 6.7 sigma_a):
    # 1e-2 px^2 of entries 12-70 px^2
    np.testing.assert_allclose(got[0], _anisotropy(sig_a, sig_b, angle), atol=1e-2)


def test_a_faint_streak_on_a_round_psf_measures_its_length_and_direction():
    # a 10 px streak of a sigma 2.5 px Gaussian, 300 electrons in noise of 2 per pixel:
    # a peak of under 3 sigma per pixel, too faint to light a streak, yet its direction and
    # length come out (40 noise draws)
    length, angle, sigma = 10.0, 0.6, 2.5
    segment = galsim.Box(width=length, height=1e-3).rotate(angle * galsim.radians)
    star = galsim.Convolve(galsim.Gaussian(sigma=sigma), segment)
    clean = _drawn(star, 20.0, 20.0, flux=300.0)
    assert clean.max() < 3.0 * 2.0
    rng = np.random.default_rng(20261207)
    lengths, turns = [], []
    for _ in range(40):
        frame = clean + rng.normal(0.0, 2.0, clean.shape)
        got = adaptive_axes(frame, [20.0], [20.0], half_px=18, start_sigma_px=sigma, level=0.0)[0]
        lam, vec = np.linalg.eigh(got)
        lengths.append(math.sqrt(max(lam[1], 0.0)))
        turns.append(abs(math.remainder(math.atan2(vec[1, 1], vec[0, 1]) - angle, math.pi)))
    # the median streak within 25 % (a uniform segment on a Gaussian is not Gaussian: the
    # weighted moments read it 12 % long without noise) and its direction within 12 deg (the
    # noise's scatter of a 300 e- star: 6 deg)
    assert abs(np.median(lengths) / length - 1.0) < 0.25
    assert np.median(turns) < math.radians(12.0)


def test_noise_alone_or_an_empty_window_is_not_measured():
    rng = np.random.default_rng(5)
    frame = rng.normal(0.0, 1.0, (SIDE, SIDE))
    frame[:, :] -= frame.mean()
    got = adaptive_axes(np.zeros((SIDE, SIDE)), [20.0], [20.0], half_px=10, start_sigma_px=2.0)
    assert np.isnan(got).all()
    off = adaptive_axes(frame, [-40.0], [20.0], half_px=10, start_sigma_px=2.0, level=0.0)
    assert np.isnan(off).all()
