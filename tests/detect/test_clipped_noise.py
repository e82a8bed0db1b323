"""Background noise of frames clipped at zero but not coarsely quantised (detect.quantised).

The luminance of a colour camera's frame whose three channels were each clipped at zero takes
many distinct values (no lattice: not the quantised path), a quarter of its pixels sit at 0
and its median absolute deviation reads a fraction of the noise (0 where more than half the
pixels are 0). The truths here are closed forms of the rectified Gaussian (scipy.stats.norm)
or large seeded draws of the same process, independent of the estimator.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from camera_class import CHANNEL_RHO, LUMA
from scipy.stats import norm

from starsense.detect import StarDetector, estimate_background
from starsense.detect.quantised import CLIPPED_FRACTION, clip_floor, clipped_box_stats


def _rectified_moments(mu: float, s: float) -> tuple[float, float]:
    """Mean and std of max(N(mu, s), 0), closed form."""
    a = mu / s
    mean = mu * norm.cdf(a) + s * norm.pdf(a)
    second = (mu * mu + s * s) * norm.cdf(a) + mu * s * norm.pdf(a)
    return float(mean), float(math.sqrt(second - mean * mean))


def _colour_dark(rng, shape, offset: float, noise: float) -> np.ndarray:
    """Luminance of three partly correlated channels, each rounded and clipped at zero."""
    common = rng.standard_normal(shape)
    chans = [
        np.clip(
            np.rint(
                offset
                + noise
                * (
                    math.sqrt(CHANNEL_RHO) * common
                    + math.sqrt(1 - CHANNEL_RHO) * rng.standard_normal(shape)
                )
            ),
            0,
            255,
        )
        for _ in range(3)
    ]
    return np.stack(chans, axis=-1) @ LUMA


@pytest.mark.parametrize(("mu", "s"), [(0.0, 2.0), (0.5, 3.0), (2.0, 1.5)])
def test_continuous_clipped_noise_matches_the_closed_form(mu, s):
    rng = np.random.default_rng(11)
    image = np.maximum(rng.normal(mu, s, (768, 1024)), 0.0)
    mean, std = _rectified_moments(mu, s)
    bg = estimate_background(image)
    assert bg.step is None
    # 192 boxes of 1,024 samples: one box's std scatters by ~3 %, their median by ~0.3 %;
    # 3 % allows for the 5-sigma cut of the fitted Gaussian (it drops ~3e-7 of the samples)
    assert bg.noise == pytest.approx(std, rel=0.03)
    assert float(np.median(bg.level)) == pytest.approx(mean, abs=0.03 * s)


def test_clipped_probit_recovers_the_gaussian_and_the_box_moments():
    # 4 boxes of 25,000 samples of max(N(0.4, 3), 0): the pixel moments are the closed form's
    rng = np.random.default_rng(2)
    cells = np.maximum(rng.normal(0.4, 3.0, (4, 25_000)), 0.0).astype(np.float32)
    mean, std, keep = clipped_box_stats(cells, np.median(cells, axis=-1), 0.0)
    want_mean, want_std = _rectified_moments(0.4, 3.0)
    # 25,000 samples: the mean's error is 0.6 % of s, the std's ~0.6 %; 2 % allowed
    np.testing.assert_allclose(mean, want_mean, atol=0.02 * 3.0)
    np.testing.assert_allclose(std, want_std, rtol=0.02)
    assert keep.mean() > 0.999


def test_colour_luminance_of_clipped_channels_gets_its_noise():
    # the openstartracker class: the luminance lies on a lattice of 0.001 count (the weights'
    # decimals) and the MAD reads ~0.6 of the noise: it was taken for a quantised frame of
    # steps of a few thousandths, noise 0.002, and lit thousands of candidates. The clipped
    # statistics read the std of the luminance of a large independent draw of the same
    # process (3 % over the frame's median, as for the closed form above)
    rng = np.random.default_rng(5)
    image = _colour_dark(rng, (768, 1024), offset=0.0, noise=3.0)
    truth = float(_colour_dark(np.random.default_rng(99), (400, 1000), 0.0, 3.0).std())
    assert np.mean(image == 0) > 0.3
    bg = estimate_background(image)
    assert bg.step is None
    assert bg.noise == pytest.approx(truth, rel=0.03)
    mad = 1.4826 * np.median(np.abs(image - np.median(image)))
    assert mad < 0.7 * truth  # what the MAD path measured


def test_clip_floor_needs_a_point_mass():
    rng = np.random.default_rng(3)
    assert clip_floor(rng.normal(5.0, 2.0, 100_000)) is None  # continuous, unclipped
    # integers with a noise of 3 counts, 4 sigma above zero: the least value holds ~1e-5
    assert clip_floor(np.rint(rng.normal(12.0, 3.0, 100_000))) is None
    clipped = np.maximum(rng.normal(0.0, 2.0, 100_000), 0.0)
    assert clip_floor(clipped) == 0.0
    # the limit: a point mass just above CLIPPED_FRACTION is a floor, just below it is not
    v = rng.normal(10.0, 1.0, 10_000)
    n = int(CLIPPED_FRACTION * v.size)
    v[:n] = 3.0
    assert clip_floor(v) == 3.0
    v[n - 1] = 10.0
    assert clip_floor(v) is None


@pytest.mark.parametrize("offset", [0.0, 0.8])
def test_clipped_colour_noise_alone_gives_few_candidates(offset):
    # no stars: a 5 sigma matched-filter threshold on the right noise lights a handful of
    # chance regions; on the MAD's noise it lit thousands
    rng = np.random.default_rng(int(offset * 10))
    image = _colour_dark(rng, (768, 1024), offset=offset, noise=3.0)
    det = StarDetector(background="auto", threshold_sigma=5.0, matched_filter=True, min_snr=5)(
        image
    )
    assert det.counts["candidates"] < 50
    assert len(det) < 10
