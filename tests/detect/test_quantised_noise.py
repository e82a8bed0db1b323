"""Background noise of coarsely quantised, zero-clipped frames (starsense.detect.quantised).

The frames are drawn by the renderer's own noise model (render.noise.apply_noise: Gaussian read
noise, gain, bias, rounding, clipping at 0 and 255) on a sensor whose read noise is 0.6-0.8
counts, so the truth is known in closed form: the pixel values are round(clip(N(bias, s))) and
their mean and standard deviation follow from the normal CDF (scipy.stats.norm), independently
of the estimator.
"""

from __future__ import annotations

import numpy as np
import pytest
from camera8 import camera8
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import norm

from starsense.detect import estimate_background
from starsense.detect.quantised import clipped_gaussian_sigma, quantisation_step
from starsense.render.noise import apply_noise
from starsense.solve.frames import load_image


def _dark_frame(bias: float, read_noise_e: float, seed: int = 3) -> np.ndarray:
    sensor = camera8(bias_counts=bias, read_noise_e=read_noise_e)
    rows, cols = sensor.detector.rows, sensor.detector.columns
    return apply_noise(np.zeros((rows, cols)), sensor, rng=seed).astype(np.uint8)


def _clipped_moments(mu: float, s: float) -> tuple[float, float]:
    """Mean and std of round(max(N(mu, s), 0)) from the normal CDF (independent of the code)."""
    k = np.arange(0, 64)
    p = norm.cdf(k + 0.5, mu, s) - norm.cdf(k - 0.5, mu, s)
    p[0] = norm.cdf(0.5, mu, s)
    mean = float((k * p).sum())
    return mean, float(np.sqrt((p * (k - mean) ** 2).sum()))


@pytest.mark.parametrize(("bias", "read_noise_e"), [(0.0, 12.0), (1.0, 12.0), (2.0, 16.0)])
def test_noise_of_clipped_8bit_background_matches_the_closed_form(bias, read_noise_e):
    image = _dark_frame(bias, read_noise_e)
    s = read_noise_e * 0.05  # counts (gain 0.05 counts/e-)
    mean, std = _clipped_moments(bias, s)
    bg = estimate_background(image)
    assert bg.step == 1.0
    # median over 192 boxes of 1,024 samples: the std of one box scatters by ~2.2 %, the median
    # of the boxes by ~0.2 %; 3 % allows for the 5-sigma cut and the box-mean subtraction
    assert bg.noise == pytest.approx(std, rel=0.03)
    assert float(np.median(bg.level)) == pytest.approx(mean, abs=0.02)  # 0.02 counts: ~5 % of s


def test_mad_fails_where_the_quantised_estimate_holds():
    # The MAD's failure: the background at 0 counts with noise clipped at zero has a MAD of
    # zero (photutils' MAD-based rms says so too), which made every non-zero pixel a star.
    from astropy.stats import mad_std

    image = _dark_frame(0.0, 12.0)
    assert mad_std(image) == 0.0
    bg = estimate_background(image)
    assert bg.noise > 0.3 and np.all(bg.noise_map > 0.3)  # closed form: 0.42 counts


def test_quantised_estimate_agrees_with_photutils_sigma_clipped_std():
    # Away from the clip (bias 2 counts, noise 0.8) the values are a rounded Gaussian, and
    # photutils' Background2D with a mean level and a standard-deviation rms measures the same
    # thing as ours; agreement within 3 % (both have ~0.2 % statistical error over the frame; the
    # clipping rules differ: 3 sigma in photutils, 5 sigma of the fitted Gaussian in ours).
    photutils_background = pytest.importorskip("photutils.background")
    from astropy.stats import SigmaClip

    image = _dark_frame(2.0, 16.0)
    ref = photutils_background.Background2D(
        image.astype(float),
        64,
        filter_size=3,
        sigma_clip=SigmaClip(sigma=5.0, maxiters=10),
        bkg_estimator=photutils_background.MeanBackground(),
        bkg_rms_estimator=photutils_background.StdBackgroundRMS(),
    )
    bg = estimate_background(image)
    assert bg.noise == pytest.approx(ref.background_rms_median, rel=0.03)
    assert float(np.median(bg.level)) == pytest.approx(ref.background_median, abs=0.02)


def test_probit_fit_recovers_the_gaussian_behind_clipped_values():
    # 100,000 samples of round(max(N(0.3, 0.7), 0)): the probit line through the bin edges gives
    # back s = 0.7 (its statistical error at this n is ~0.5 %; 3 % allowed)
    rng = np.random.default_rng(0)
    cells = np.maximum(np.rint(rng.normal(0.3, 0.7, (4, 25_000))), 0).astype(np.float32)
    sigma = clipped_gaussian_sigma(cells, np.median(cells, axis=-1), 1.0)
    np.testing.assert_allclose(sigma, 0.7, rtol=0.03)
    # a noiseless box has nothing to fit
    assert np.isnan(clipped_gaussian_sigma(np.zeros((1, 100), np.float32), np.zeros(1), 1.0))[0]


def test_quantisation_step():
    assert quantisation_step(np.array([0, 1, 3, 7], np.uint8)) == 1.0
    assert quantisation_step(np.array([16, 48, 4096, 65520], np.uint16)) == 16.0
    assert quantisation_step(np.array([0.5, 1.25])) is None  # too few samples to tell
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 6, 1000)
    # float data of few distinct values: a lattice (a Bayer cell's sum, 2.95 x counts)...
    assert quantisation_step(np.float32(2.95) * counts) == pytest.approx(2.95, rel=1e-6)
    # ... or not (the luminance of tinted 8-bit colour: values 0, 1, 2, 2.886, 3.886, 4.886,
    # spacings 1 and 0.886: the median spacing)
    tinted = 0.886 * counts + 0.114 * np.round(0.8 * counts)
    assert quantisation_step(tinted) == pytest.approx(1.0)
    assert quantisation_step(rng.standard_normal(1000)) is None  # continuous
    assert quantisation_step(np.full(10, 7)) is None


def test_esa_frames_keep_the_mad_estimate(shared_dir):
    # 12-bit data stored as 16-bit (steps of 16 counts) with 92-221 counts of noise: far from
    # quantised, so the MAD path applies unchanged
    folder = shared_dir / "data" / "images" / "esa"
    bg = estimate_background(load_image(next(iter(sorted(folder.glob("*.tiff"))))))
    assert bg.step is None and bg.noise > 50


def test_12bit_data_in_16bit_words_with_low_noise():
    # 12-bit counts stored as 16-bit (steps of 16), noise 1.2 steps at 1.5 steps of bias, clipped
    # at zero: the step is found and the noise is 16 x the closed-form std in steps (3 %, as above)
    rng = np.random.default_rng(8)
    steps = np.maximum(np.rint(rng.normal(1.5, 1.2, (768, 1024))), 0)
    image = (16 * steps).astype(np.uint16)
    mean, std = _clipped_moments(1.5, 1.2)
    bg = estimate_background(image)
    assert bg.step == 16.0
    assert bg.noise == pytest.approx(16 * std, rel=0.03)
    assert float(np.median(bg.level)) == pytest.approx(16 * mean, abs=16 * 0.02)


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    step=st.sampled_from([1, 2, 3, 16, 48]),
    n=st.integers(1, 3000),
    late=st.booleans(),
)
def test_quantisation_step_is_the_gcd_of_all_differences(seed, step, n, late):
    # the gcd taken on a prefix first must give the gcd of every difference, also when the
    # prefix's is larger (a value off the prefix's lattice comes late)
    rng = np.random.default_rng(seed)
    v = (rng.integers(0, 400, n) * step * 2 + 1000).astype(np.uint16)
    if late and n > 300:
        v[-1] += step  # breaks the lattice of 2 step only after the prefix
    d = v.astype(np.int64) - int(v.min())
    d = d[d > 0]
    expected = float(np.gcd.reduce(d)) if d.size else None
    assert quantisation_step(v) == expected
