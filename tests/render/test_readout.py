"""The fast read-out and the batched static stars against the reference rendering.

* The normal draws: a monotone map of 32 random bits, so the distance between the drawn
  distribution and the normal (Kolmogorov-Smirnov) is the largest ``|Phi(z(u)) - (u + 1/2) /
  2^32|`` over u: checked on a fine grid of u against scipy's ``ndtr`` (an independent
  implementation), the bound the module states (2e-5; 1.2e-9 relative in the quantile beyond
  the table, Acklam's published bound).
* Counts: for each mean charge (zero, folded, at the fold's cut, Poisson, near saturation) the
  mean, variance and above-threshold rate of 400,000 pixels of both read-outs against the exact
  distribution of ``clip(round(gain (Poisson(lambda) + N(0, sigma_r^2)) + bias))`` summed
  from its terms (scipy): within 5 standard errors (a false alarm of 6e-7 per comparison).
* Stars: a frame at rest draws every star in one batch and must equal the star-by-star
  rendering bit for bit (the same float64 products, float32 sums in the same order).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.special import ndtr, ndtri
from scipy.stats import norm, poisson

from starsense.catalog import load_catalog
from starsense.geometry.sampling import random_attitudes
from starsense.render import readout
from starsense.render.noise import apply_noise
from starsense.render.psf import Box
from starsense.render.scene import render_frame
from starsense.render.smear import pad_sigma_for, polyline_expected
from starsense.render.stamps import expected_image
from starsense.render.tracks import star_tracks
from starsense.sensor import load_sensor

needs_kernel = pytest.mark.skipif(
    readout.normal_draws(np.zeros(1, np.uint32)) is None, reason="compiled kernel not built"
)


@pytest.fixture(scope="module")
def st16():
    return load_sensor("st16")


@needs_kernel
def test_normal_draws_are_within_the_stated_distance_of_the_normal():
    # every 4096th value of u, both ends and the bins' edges
    u = np.arange(0, 2**32, 4093, dtype=np.uint64)
    edges = (np.arange(4097, dtype=np.uint64) << 20).clip(0, 2**32 - 1)
    u = np.unique(np.concatenate([u, edges, edges - 1, [0, 1, 2**32 - 2, 2**32 - 1]]))
    u = u[(u >= 0) & (u < 2**32)].astype(np.uint32)
    z = readout.normal_draws(u)
    p = (u.astype(float) + 0.5) / 2.0**32
    assert np.all(np.diff(z) >= 0)  # monotone: the distance is the largest CDF gap
    assert np.abs(ndtr(z) - p).max() < 2e-5
    tails = (u >> 20 == 0) | (u >> 20 == 4095)
    np.testing.assert_allclose(z[tails], ndtri(p[tails]), rtol=1.2e-9)
    assert z.max() == -z.min() and 6.3 < z.max() < 6.4  # symmetric; the 2^-32 quantile


@needs_kernel
def test_normal_quantiles_match_scipy():
    u = np.random.default_rng(0).integers(0, 2**32, 1_000_000, dtype=np.uint32)
    p = (u.astype(float) + 0.5) / 2.0**32
    np.testing.assert_allclose(readout.normal_quantiles(u), ndtri(p), rtol=1.2e-9)


def _exact_counts(lam: float, det) -> np.ndarray:
    """The probability of each count 0 .. saturation, from the model's terms."""
    sat = int(det.saturation_counts)
    sigma = det.read_noise_e
    k_hi = int(poisson.ppf(1 - 1e-15, lam)) + 1 if lam > 0 else 0
    k = np.arange(k_hi + 1)
    pk = poisson.pmf(k, lam) if lam > 0 else np.ones(1)
    charge = np.minimum(k, det.full_well_e)
    c = np.arange(sat + 1)
    # count c collects gain x electrons + bias in [c - 1/2, c + 1/2); the ends take the rest
    lo = (c - 0.5 - det.bias_counts) / det.gain_counts_per_e
    hi = (c + 0.5 - det.bias_counts) / det.gain_counts_per_e
    lo[0], hi[-1] = -np.inf, np.inf
    cdf_hi = norm.cdf((hi[None, :] - charge[:, None]) / sigma)
    cdf_lo = norm.cdf((lo[None, :] - charge[:, None]) / sigma)
    return pk @ (cdf_hi - cdf_lo)


@needs_kernel
@pytest.mark.parametrize("lam", [0.0, 0.3, 0.857, 0.86, 3.0, 30.0, 600.0])
def test_counts_have_the_models_statistics(st16, lam):
    det = st16.detector
    pmf = _exact_counts(lam, det)
    c = np.arange(len(pmf))
    mean = float(pmf @ c)
    var = float(pmf @ (c - mean) ** 2)
    threshold = st16.detection.lit_pixel_counts
    p_lit = float(pmf[c >= threshold].sum())
    n = 400_000
    e = np.full((400, 1000), lam, np.float32)
    for counts in (readout.fast_read_out(e, st16, rng=1), apply_noise(e, st16, rng=2)):
        x = counts.astype(float).ravel()
        assert abs(x.mean() - mean) < 5 * math.sqrt(var / n)
        m4 = float(pmf @ (c - mean) ** 4)
        assert abs(x.var() - var) < 5 * math.sqrt((m4 - var**2) / n)
        lit = np.count_nonzero(x >= threshold)
        assert abs(lit - n * p_lit) < 5 * math.sqrt(n * p_lit * (1 - p_lit)) + 1


def test_fast_read_out_declines_what_it_does_not_model(st16):
    e = np.zeros((8, 8), np.float32)
    hot = dataclasses.replace(st16.detector, hot_pixel_fraction=0.01)
    assert readout.fast_read_out(e, st16.with_(detector=hot), rng=0) is None
    assert readout.fast_read_out(e.astype(float), st16, rng=0) is None  # not float32
    bad = e.copy()
    bad[3, 3] = np.nan
    assert readout.fast_read_out(bad, st16, rng=0) is None  # apply_noise names it


def _star_by_star(sensor, frame_tracks, electrons, sigmas):
    """The expected image drawn one star at a time (the reference loop)."""
    det = sensor.detector
    pads = pad_sigma_for(electrons, sigmas) * sigmas
    out = np.zeros((det.rows, det.columns), np.float32)
    for i, v in enumerate(frame_tracks.vertices):
        xs, ys = v[:, 0], v[:, 1]
        full = Box.around(
            x_min=xs.min(), x_max=xs.max(), y_min=ys.min(), y_max=ys.max(), pad_px=pads[i]
        )
        box = full.clip(det.rows, det.columns)
        if box is None:
            continue
        stamp, _ = polyline_expected(
            xs,
            ys,
            sigma_px=float(sigmas[i]),
            electrons=electrons[i],
            pad_sigma=pads[i] / sigmas[i],
            box=box,
        )
        out[box.slices] += stamp
    return out


@pytest.mark.parametrize("seed", range(3))
def test_a_frame_at_rest_equals_the_star_by_star_rendering(st16, seed):
    cat = load_catalog("hipparcos")
    att = random_attitudes(1, np.random.default_rng(seed))[0]
    frame = render_frame(st16, att, cat, rng=seed, noise=False)
    stars = frame.truth.stars
    assert len(stars) > 500  # the faint catalogue stars too
    order = np.argsort(cat.ids)
    rows = order[np.searchsorted(cat.ids[order], stars.ids)]
    assert np.array_equal(cat.ids[rows], stars.ids)
    vectors = att.apply(cat.vectors[rows])
    tracks = star_tracks(st16, vectors)
    sigmas = np.full(len(stars), st16.detector.psf_sigma_px)
    ref = _star_by_star(st16, tracks, stars.electrons, sigmas)
    got, table = expected_image(st16, tracks, stars.electrons, method="track", sigmas=sigmas)
    assert np.array_equal(got, ref)
    assert np.array_equal(got, frame.expected_e)
    np.testing.assert_allclose(table[1], stars.electrons_on_detector, rtol=1e-12)
