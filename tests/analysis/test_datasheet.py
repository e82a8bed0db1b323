"""The datasheet's parts: centroid noise, the Fisher propagation, the terms, the interpolations."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from importlib import resources

import numpy as np
import pytest
from scipy import integrate, stats

from starsense.analysis.availability.field import catalog_stars
from starsense.analysis.datasheet.field import axis_sigmas, field_stars_cam, fisher_per_pointing
from starsense.analysis.datasheet.noise import centroid_noise, clipped_moments
from starsense.analysis.datasheet.predict import (
    StarModel,
    fastest_rate,
    limiting_magnitude,
    nea_at,
    slew_grids,
)
from starsense.analysis.datasheet.terms import (
    EARTH_ORBITAL_SPEED_M_S,
    aberration_error,
    pixel_spatial_error,
)
from starsense.analysis.datasheet.verify import wrong_rate_upper
from starsense.attitude.covariance import fisher_matrix
from starsense.catalog import load_catalog
from starsense.detect.threshold import StarDetector
from starsense.errors import InputError
from starsense.geometry.sampling import random_attitudes
from starsense.render.noise import quantise
from starsense.render.psf import gaussian_stamp
from starsense.sensor import load_sensor, sensor_from_dict
from starsense.units import ARCSEC, DEG

CASES = [(0.0, 1.0, 0.0, math.inf), (3.0, 2.0, 0.0, 4.0), (-1.0, 0.5, 0.0, 9.0)]


@pytest.mark.parametrize(("mu", "sigma", "lo", "hi"), CASES)
def test_clipped_moments_against_quadrature(mu, sigma, lo, hi):
    # independent: integrate the clipped variable's density numerically (scipy.integrate.quad)
    pdf = stats.norm(mu, sigma).pdf
    top = hi if math.isfinite(hi) else mu + 12 * sigma
    p_lo, p_hi = stats.norm.cdf(lo, mu, sigma), stats.norm.sf(top, mu, sigma)
    m1 = integrate.quad(lambda x: x * pdf(x), lo, top)[0] + lo * p_lo + top * p_hi
    m2 = integrate.quad(lambda x: x * x * pdf(x), lo, top)[0] + lo**2 * p_lo + top**2 * p_hi
    mean, var = clipped_moments(mu, sigma, lo=lo, hi=hi)
    # quadrature is good to ~1e-10 here; 1e-8 leaves room for the 12-sigma truncation
    assert mean == pytest.approx(m1, abs=1e-8)
    assert var == pytest.approx(m2 - m1 * m1, abs=1e-8)


def _ideal(read_noise_e: float, sigma_px: float = 1.5):
    st16 = load_sensor("st16")
    det = dataclasses.replace(
        st16.detector, read_noise_e=read_noise_e, psf_sigma_px=sigma_px, bit_depth=24
    )
    return dataclasses.replace(st16, detector=det)


def test_crb_photon_limited_is_sigma_over_sqrt_n():
    # invariant: a Gaussian PSF sampled by pixels much smaller than it, shot noise only, has
    # the Cramer-Rao bound sigma / sqrt(N) (pixelation adds ~ 1/(12 sigma^2) = 0.3 % at 3 px)
    sens = _ideal(read_noise_e=0.0, sigma_px=3.0)
    table = centroid_noise(sens, 1e5, 1e6, n_grid=3, n_stamps=20)
    assert table.crb(4e5) == pytest.approx(3.0 / math.sqrt(4e5), rel=0.01)


def test_measured_centroid_noise_photon_limited():
    # the tracker's CoG on a bright star with no read noise: ~ sqrt(sigma^2 + 1/12) / sqrt(N);
    # 300 renders give the rms to +-4 % (1 sigma), the window truncation a few % more: 15 %
    sens = _ideal(read_noise_e=0.0)
    table = centroid_noise(sens, 2e5, 4e5, n_grid=2, n_stamps=300, rng=4)
    expected = math.sqrt(1.5**2 + 1 / 12) / math.sqrt(2e5)
    assert table.sigma_px[0] == pytest.approx(expected, rel=0.15)


def test_nea_photon_limited_scales_as_one_over_d():
    # photon-limited: sigma ~ 1/sqrt(N) ~ 1/D; the same star through apertures D and 2D (N x 4);
    # 300 renders per point give each rms to +-4 %, so the ratio to ~6 %: 15 %
    table = centroid_noise(_ideal(0.0), 2e4, 8e4, n_grid=2, n_stamps=300, rng=5)
    assert table.sigma_px[0] / table.sigma_px[1] == pytest.approx(2.0, rel=0.15)


def test_nea_read_noise_limited_scales_steeper():
    # read-noise-limited: a fixed window gives sigma ~ 1/N ~ 1/D^2; the tracker's window (the
    # lit pixels plus a margin) grows with the star, so the CoG falls a little slower. The
    # measured ratio must match the linearised window model (an independent computation: no
    # rendering) to 15 %, and be clearly steeper than the photon-limited 2
    sens = _ideal(30.0)
    det = dataclasses.replace(sens.detector, gain_counts_per_e=1.0)
    logic = dataclasses.replace(
        sens.detection, lit_pixel_counts=150.0, min_pixels=3, min_integrated_counts=500.0
    )
    sens = dataclasses.replace(sens, detector=det, detection=logic)
    table = centroid_noise(sens, 2e4, 8e4, n_grid=2, n_stamps=300, rng=6)
    measured = table.sigma_px[0] / table.sigma_px[1]
    model = table.window_model_px[0] / table.window_model_px[1]
    assert model > 2.8
    assert measured == pytest.approx(model, rel=0.15)


def test_fisher_per_pointing_matches_eq21_and_n_scaling():
    sens = load_sensor("st16")
    rng = np.random.default_rng(2)
    att = random_attitudes(5, rng).as_matrix()
    stars = rng.normal(size=(20_000, 3))
    stars /= np.linalg.norm(stars, axis=1)[:, None]
    pairs = field_stars_cam(sens.fov(), att, stars)
    w = np.full(len(pairs.star), 1.0 / (5 * ARCSEC) ** 2)
    f = fisher_per_pointing(pairs, w)
    k = pairs.point == 3
    # the one copy of eq. 21, on the same stars in the camera frame: identical to rounding
    np.testing.assert_allclose(f[3], fisher_matrix(pairs.v_cam[k], w[k]), rtol=1e-12)
    cross1, roll1 = axis_sigmas(f)
    cross4, roll4 = axis_sigmas(4 * f)  # 4x the stars at the same places: sigma / 2 exactly
    np.testing.assert_allclose(cross4, cross1 / 2, rtol=1e-12)
    np.testing.assert_allclose(roll4, roll1 / 2, rtol=1e-12)


def test_axis_sigmas_singular_is_nan():
    r = np.array([[0.0, 0.0, 1.0]])
    f = fisher_matrix(r, np.array([1.0]))[None]
    cross, roll = axis_sigmas(f)
    assert np.isnan(cross[0]) and np.isnan(roll[0])


def test_annual_aberration_is_a_cross_boresight_error_of_20_5_arcsec():
    # IAU 1976 constant of aberration 20.4955 arcsec = v/c; the worst apex is across the
    # boresight; across a 20 deg field the directions differ by < 1 % of it (sin of the angle)
    cross, roll = aberration_error(load_sensor("st16"), EARTH_ORBITAL_SPEED_M_S)
    assert cross / ARCSEC == pytest.approx(20.4955, rel=0.01)
    assert roll / ARCSEC < 0.01  # a common displacement has no roll to first order


def test_pixel_spatial_error_small_for_a_wide_psf():
    # a well-sampled Gaussian (1.5 px) centroids almost without bias: < 0.05 px (Liebe 2002)
    pse = pixel_spatial_error(load_sensor("st16"), [5e3, 5e4], n_side=4)
    assert np.all(pse.max_px < 0.05)


@pytest.mark.parametrize(
    "changes",
    [
        # a bias of 168 counts (the ST-16's) under a 12-bit ADC: the signal clips at
        # (4095 - 168) / 0.05 = 78,540 e-, not at 4095 / 0.05 = 81,900 e-
        {"full_well_e": 1e5, "bias_counts": 168.0},
        # no bias, a well of 60,000 e- below the ADC's 81,900 e-: the well clips first
        {"full_well_e": 6e4, "bias_counts": 0.0},
    ],
)
def test_pixel_spatial_error_clips_as_the_renderer_does(changes):
    # the centroider's sub-pixel error is measured on noiseless stars; past saturation it is the
    # flat top's, so those stars must be clipped as the renderer clips them. The independent
    # measurement: each phase's star read out by the renderer (quantise: the well clips the
    # charge, the ADC the counts with the bias in them), alone on a frame, through the same
    # detector. The two differ only by quantise's rounding: +-0.5 count (0.29 rms) a pixel
    # moves a CoG of 2e4-5e4 counts over a ~9 x 9 px window by ~2e-4 px; ask 5e-4 px. Clipped
    # at the wrong level (the ADC's top over the bias, or no well) the rms is off by 1.3e-3 px
    # (ADC, 1e6 e-) and 8e-3 px (well, 4e5 e-).
    s = load_sensor("st16")
    det = dataclasses.replace(
        s.detector, psf_sigma_px=0.8, gain_counts_per_e=0.05, read_noise_e=5.0, **changes
    )
    sens = dataclasses.replace(s, detector=det)
    detector = StarDetector.for_sensor(sens)
    offsets = (np.arange(4) + 0.5) / 4
    half = 12  # 15 PSF sigmas
    box = (0, 2 * half + 1, 0, 2 * half + 1)
    for n_e in (4e5, 1e6):  # peak pixels 2-3 times past the clip at the worst phase
        err = []
        for dx in offsets:
            for dy in offsets:
                x, y = half + dx - 0.5, half + dy - 0.5
                stamp, _, _ = gaussian_stamp(x, y, sigma_px=0.8, electrons=n_e, box=box)
                found = detector(quantise(stamp, sens).astype(float))
                i = int(np.argmax(found.integrated_counts))
                err += [found.x[i] - x, found.y[i] - y]
        ref = math.sqrt(np.mean(np.square(err)))
        got = pixel_spatial_error(sens, [n_e], n_side=4).rms_px[0]
        assert got == pytest.approx(ref, abs=5e-4), n_e


def test_interpolations():
    mags = np.array([4.0, 5.0, 6.0])
    assert limiting_magnitude(mags, [1.0, 0.7, 0.3]) == pytest.approx(5.5)
    assert limiting_magnitude(mags, [0.2, 0.1, 0.0]) is None
    assert limiting_magnitude(mags, [1.0, 1.0, 1.0]) == 6.0
    assert fastest_rate([0, 1, 2], [1.0, 0.95, 0.85], 0.9) == pytest.approx(1.5)
    assert fastest_rate([0, 1, 2], [0.5, 0.4, 0.3], 0.9) is None


def test_slew_grids_bracket_the_limit_and_fit_the_detector():
    sens = load_sensor("st16")
    mags, rates = slew_grids(sens, 5.6)
    # 20 steps of 0.25 mag ending past the limit, then 0.5 mag steps to the sky's brightest
    # star (Sirius, V = -1.46): m_t(w) is known wherever some star is still detected
    assert mags[-1] >= 5.6 + 0.25 and np.allclose(np.diff(mags[-20:]), 0.25)
    assert mags[0] <= -1.46 and np.all(np.diff(mags) > 0) and np.all(np.diff(mags) <= 0.5)
    assert rates[-1] == pytest.approx(10 * DEG)  # the ST-16 streak at 10 deg/s fits
    slow = dataclasses.replace(sens, exposure_s=2.0)
    assert sens.streak_length_px(slew_grids(slow, 5.6)[1][-1] * 20) <= sens.detector.columns


def test_wrong_rate_upper_bound_zero_of_n():
    # Clopper-Pearson with no failure has the closed form 1 - 0.05^(1/n)
    assert wrong_rate_upper(0, 200) == pytest.approx(1 - 0.05 ** (1 / 200), rel=1e-9)


def _toml(extra: dict) -> dict:
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    return {**tomllib.loads(text), **extra}


def test_quoted_table_checked():
    s = sensor_from_dict(_toml({"quoted": {"source": "vendor sheet", "nea_cross_arcsec": 7.0}}))
    assert dict(s.quoted)["nea_cross_arcsec"] == 7.0
    with pytest.raises(InputError, match="unknown key 'accuracy_arcsec'"):
        sensor_from_dict(_toml({"quoted": {"source": "x", "accuracy_arcsec": 7.0}}))
    with pytest.raises(InputError, match="needs source"):
        sensor_from_dict(_toml({"quoted": {"nea_cross_arcsec": 7.0}}))
    with pytest.raises(InputError, match="bias_cross_arcsec = -1"):
        sensor_from_dict(_toml({"budget": {"bias_cross_arcsec": -1}}))


def _sky_nea(sens, n=60):
    vectors, mags = catalog_stars(
        load_catalog("hipparcos"), 4.0, band="V"
    )  # the same stars for all
    model = StarModel.build(sens, model="reed", bright_mag=float(mags.min()), faint_mag=4.0)
    att = random_attitudes(n, np.random.default_rng(8)).as_matrix()
    sig, _ = nea_at(model, sens.fov(), att, vectors=vectors, magnitudes=mags)
    return float(np.nanmedian(sig["nea"][0])), float(np.nanmedian(sig["nea"][1]))


def _aperture(sens, d):
    return dataclasses.replace(sens, optics=dataclasses.replace(sens.optics, aperture_m=d))


@pytest.mark.slow
def test_datasheet_nea_scales_with_aperture_over_the_sky():
    # the datasheet's NEA (per-star noise through eq. 21) of two sensors differing only in
    # aperture, over the same stars (V <= 4, detected by both): photon-limited ~ 1/D (ratio 2
    # for 2D, within 15 %: the measured noise table); read-noise-limited steeper, between the
    # CoG's growing window (~1/D^1.5) and a fixed window's 1/D^2
    photon = _ideal(0.0)
    small, large = _sky_nea(_aperture(photon, 0.012)), _sky_nea(_aperture(photon, 0.024))
    assert small[0] / large[0] == pytest.approx(2.0, rel=0.15)
    assert small[1] / large[1] == pytest.approx(2.0, rel=0.15)
    read = _ideal(30.0)
    read = dataclasses.replace(
        read,
        detector=dataclasses.replace(read.detector, gain_counts_per_e=1.0),
        detection=dataclasses.replace(
            read.detection, lit_pixel_counts=150.0, min_pixels=3, min_integrated_counts=500.0
        ),
    )
    small, large = _sky_nea(_aperture(read, 0.006)), _sky_nea(_aperture(read, 0.012))
    assert 2.0**1.5 <= small[0] / large[0] <= 4.0 * 1.1
