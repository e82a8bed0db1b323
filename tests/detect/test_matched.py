"""Matched-filter detection (starsense.detect.matched): stars, not noise spikes or plateaus."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage
from scipy.special import erf

from starsense.detect import StarDetector
from starsense.detect.matched import (
    _median_in_place,
    box_mean_at_peaks,
    gaussian_correlate,
    matched_filter,
)
from starsense.sensor import DetectionThresholds

SIGMA_PX = 1.0
LOGIC = DetectionThresholds(lit_pixel_counts=1e-6, min_pixels=1, min_integrated_counts=0)


def _stars(shape, xy, flux, sigma=SIGMA_PX):
    """Pixel-integrated Gaussians (independent construction with erf)."""
    rows, cols = shape
    s = np.sqrt(2) * sigma
    out = np.zeros(shape)
    for (x0, y0), f in zip(xy, flux, strict=True):
        gx = 0.5 * (erf((np.arange(cols) + 0.5 - x0) / s) - erf((np.arange(cols) - 0.5 - x0) / s))
        gy = 0.5 * (erf((np.arange(rows) + 0.5 - y0) / s) - erf((np.arange(rows) - 0.5 - y0) / s))
        out += f * np.outer(gy, gx)
    return out


def test_filtered_noise_of_white_noise_is_the_closed_form():
    # white noise through a unit-sum Gaussian of sigma s: sqrt(sum k^2) = 1 / (2 sqrt(pi) s)
    # (0.2821 at s = 1); the MAD over 87,000 samples scatters by ~0.4 %, 2 % allowed
    rng = np.random.default_rng(1)
    sub = rng.normal(0, 10.0, (768, 1024)).astype(np.float32)
    _, noise, ratio = matched_filter(sub, 10.0, psf_sigma_px=SIGMA_PX)
    assert ratio == pytest.approx(1 / (2 * np.sqrt(np.pi)), rel=0.02)
    assert float(noise) == pytest.approx(10.0 * ratio)


def test_correlated_noise_raises_the_filtered_noise():
    # noise smoothed over 2 x 2 pixels (as binning or demosaicing do) has a larger filtered
    # noise relative to its pixel noise than white noise: measured, not assumed
    rng = np.random.default_rng(2)
    white = rng.normal(0, 1.0, (512, 512))
    corr = white + np.roll(white, 1, 0) + np.roll(white, 1, 1) + np.roll(white, (1, 1), (0, 1))
    corr /= corr.std()
    _, _, ratio = matched_filter(corr.astype(np.float32), 1.0, psf_sigma_px=SIGMA_PX)
    assert ratio > 1.5 / (2 * np.sqrt(np.pi))


def test_single_pixel_spikes_are_not_stars():
    # 60 spikes of 5-6.5 sigma on single pixels (below the hot-pixel test's 8 sigma) and 20 stars
    # of 300 counts (peak 48 counts = 4.8 sigma, filtered peak 24 counts = 8.5 filtered sigma).
    # A 5-sigma threshold on single pixels takes every spike for a star. Filtered, a spike keeps
    # 0.159 of its height: 2.8-3.7 filtered sigma, so only a noise excursion of 1.3-2.2 sigma
    # lifts one over 5 (~4 %, ~2.4 of 60 expected): at most 6 allowed.
    rng = np.random.default_rng(3)
    shape = (400, 500)
    xy = rng.uniform([20, 20], [480, 380], (20, 2))
    image = 1000 + rng.normal(0, 10.0, shape) + _stars(shape, xy, np.full(20, 300.0))
    rr, cc = rng.integers(5, 395, 60), rng.integers(5, 495, 60)
    image[rr, cc] += rng.uniform(50, 65, 60)
    plain = StarDetector(LOGIC, background="auto", threshold_sigma=5)(image)
    matched = StarDetector(
        LOGIC, background="auto", threshold_sigma=5, matched_filter=True, psf_sigma_px=SIGMA_PX
    )(image)
    d = np.hypot(matched.x[:, None] - xy[:, 0], matched.y[:, None] - xy[:, 1]).min(axis=1)
    assert np.sum(d < 1.0) >= 18  # (nearly) every star is found: 8.5 sigma, two may blend
    assert np.sum(d >= 1.0) <= 6  # the spikes that a noise excursion lifts
    # (a spike's CoG over its 5 x 5 window of noise scatters by ~1 px)
    spikes = np.hypot(plain.x[:, None] - cc, plain.y[:, None] - rr).min(axis=1) < 2.5
    assert spikes.sum() >= 20  # the single-pixel test finds those lifted over 5 sigma (~26)


def test_plateau_one_step_up_is_not_a_star():
    # JPEG flattens a dark background into 8 x 8 blocks; a block one count above its neighbours
    # is neither peaked (sharpness 1) nor two steps high; a star of 60 counts is both
    image = np.ones((128, 128), np.uint8)
    rng = np.random.default_rng(4)
    image[rng.random(image.shape) < 0.02] = 2  # some spread, so the noise is measurable
    image[40:48, 40:48] = 2
    image[40:48, 48:56] = 2
    image += np.rint(_stars(image.shape, [(96.3, 90.7)], [60.0])).astype(np.uint8)
    det = StarDetector(
        LOGIC, background="auto", threshold_sigma=5, matched_filter=True, psf_sigma_px=SIGMA_PX
    )(image)
    assert len(det) == 1
    assert det.x[0] == pytest.approx(96.3, abs=0.2) and det.y[0] == pytest.approx(90.7, abs=0.2)


def test_min_snr_rejects_faint_regions():
    # the integrated-flux test: counts over the lit pixels / sqrt(sum of the noise variances)
    rng = np.random.default_rng(5)
    shape = (200, 200)
    image = 100 + rng.normal(0, 5.0, shape) + _stars(shape, [(50, 50), (150, 150)], [150, 3000])
    kw = dict(background="auto", threshold_sigma=5, matched_filter=True, psf_sigma_px=SIGMA_PX)
    loose = StarDetector(LOGIC, **kw)(image)
    strict = StarDetector(LOGIC, min_snr=40.0, **kw)(image)
    assert len(loose) == 2
    # the faint star: 150 counts over ~9 lit pixels of noise 5 -> SNR ~ 8; the bright ~ 150
    assert len(strict) == 1 and strict.x[0] == pytest.approx(150, abs=0.2)


@pytest.mark.parametrize("sigma", [0.3, 0.8, 1.0, 1.5, 2.7])
@pytest.mark.parametrize("shape", [(97, 131), (3, 3), (1, 9), (9, 1)])
def test_gaussian_correlate_is_scipys_gaussian_filter(shape, sigma):
    # scipy's gaussian_filter (float64 arithmetic, "nearest" edges, truncate 3) as the reference,
    # on frames smaller than the kernel too; the float32 sums round to within a few float32
    # ulps of the largest value (4.9e-4 at 6,000): 4 ulps allowed
    rng = np.random.default_rng(5)
    frame = (1000.0 + rng.normal(0, 10.0, shape)).astype(np.float32)
    frame[rng.random(shape) < 0.05] += 5000.0  # sharp features
    expected = ndimage.gaussian_filter(
        frame.astype(np.float64), sigma, mode="nearest", truncate=3.0
    )
    got = gaussian_correlate(frame, sigma)
    assert got.dtype == np.float32 and got.shape == shape
    ulp = float(np.spacing(frame.max()))
    np.testing.assert_allclose(got, expected, rtol=0, atol=4 * ulp)


@pytest.mark.parametrize("n", [1, 2, 3, 10, 11, 8_000, 8_001])
def test_median_in_place_is_numpys_median(n):
    # np.median is the reference: the same float32 value (ties included), for odd and even n
    rng = np.random.default_rng(n)
    z = rng.normal(0.0, 1.0, n).astype(np.float32)
    z[::3] = np.round(z[::3])
    expected = np.median(z)
    got = _median_in_place(z.copy())
    assert got == expected and got.dtype == expected.dtype


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), ties=st.booleans())
def test_box_mean_at_peaks_is_the_box_at_each_regions_last_largest_pixel(seed, ties):
    # reference: region by region, the last of its pixels (raster order) holding its largest
    # filtered value, and the mean of the box around it with edge pixels repeated
    rng = np.random.default_rng(seed)
    rows, cols, half = int(rng.integers(3, 40)), int(rng.integers(3, 40)), int(rng.integers(0, 4))
    sub = rng.normal(0, 10, (rows, cols)).astype(np.float32)
    filtered = rng.normal(0, 10, (rows, cols)).astype(np.float32)
    if ties:
        filtered = np.round(filtered / 8).astype(np.float32)  # many equal values
    idx = np.flatnonzero(rng.random(rows * cols) < 0.3)
    if idx.size == 0:
        idx = np.array([0])
    lab = rng.integers(1, 6, idx.size).astype(np.int32)
    where, peak, box = box_mean_at_peaks(sub, filtered, idx=idx, lab=lab, half=half)
    regions = np.unique(lab)
    np.testing.assert_array_equal(where, regions)
    for k, region in enumerate(regions):
        pix = idx[lab == region]
        vals = filtered.ravel()[pix]
        at = pix[np.flatnonzero(vals == vals.max())[-1]]
        r, c = divmod(int(at), cols)
        rr = np.clip(np.arange(r - half, r + half + 1), 0, rows - 1)
        cc = np.clip(np.arange(c - half, c + half + 1), 0, cols - 1)
        assert peak[k] == vals.max()
        # float64 sums of the same float32 values, in a different order: 1e-12 relative
        np.testing.assert_allclose(
            box[k], sub[np.ix_(rr, cc)].mean(dtype=np.float64), rtol=1e-12, atol=1e-12
        )


def test_local_noise_ratio_of_a_frame_narrower_than_a_box():
    # a 92 x 123 frame (a wide imager's) samples to fewer grid rows than a box holds: one box
    # across that axis, not a reshape error; white noise reads the frame's own ratio
    from starsense.detect.matched import local_noise_ratio

    rng = np.random.default_rng(3)
    filtered = rng.standard_normal((92, 123)).astype(np.float32)
    out = local_noise_ratio(filtered, 1.0, ratio=1.0)
    assert out.shape[0] == 1 and out.shape[1] >= 1
    assert np.all(out == 1.0)  # white noise of ratio 1: no box above LOCAL_EXCESS x 1
