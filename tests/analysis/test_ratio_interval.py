"""The 95 % interval of a measured / predicted ratio over the frames (percentile bootstrap)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.analysis.datasheet import verify
from starsense.analysis.datasheet.verify import N_BOOTSTRAP, ratio_interval


def _roll_frames(rng, n: int, true_ratio: float, spread: float = 0.0):
    """n frames of one axis: each frame's predicted sigma, and an error of true_ratio times it."""
    sigma = np.exp(spread * rng.standard_normal(n))  # the prediction differs frame to frame
    return (true_ratio * sigma * rng.standard_normal(n)) ** 2, sigma**2


def test_interval_covers_the_true_ratio_95_percent_of_the_time():
    rng = np.random.default_rng(7)
    runs, covered = 300, 0
    for k in range(runs):
        a, p = _roll_frames(rng, 100, 1.0, spread=0.3)
        lo, hi = ratio_interval(a, p, seed=k)
        covered += lo <= 1.0 <= hi
    # 300 runs: the binomial 1-sigma of a 95 % coverage is 1.3 %; the percentile bootstrap of
    # a chi-square mean at n = 100 under-covers by ~1 % (its skew), hence 0.90-0.99
    assert 0.90 <= covered / runs <= 0.99


def test_interval_width_is_the_delta_method_one():
    # one Gaussian axis, n frames of a constant prediction: the ratio is sqrt(chi2_n / n), whose
    # standard deviation is 1 / sqrt(2 n) (delta method); the 95 % interval spans 2 x 1.96 of it
    rng = np.random.default_rng(11)
    n = 400
    widths = []
    for k in range(40):
        a, p = _roll_frames(rng, n, 1.0)
        lo, hi = ratio_interval(a, p, seed=k)
        widths.append(hi - lo)
    expected = 2 * 1.96 / math.sqrt(2 * n)
    # 40 intervals: their median is known to ~3 %; the bootstrap's own 2,000 draws add ~2 %
    assert np.median(widths) == pytest.approx(expected, rel=0.10)


def test_interval_follows_a_scaled_prediction_and_is_reproducible():
    rng = np.random.default_rng(3)
    a, p = _roll_frames(rng, 200, 1.0, spread=0.2)
    lo, hi = ratio_interval(a, p, seed=5)
    # the prediction 4x the variance: the ratio and its interval halve exactly (same draws)
    lo2, hi2 = ratio_interval(a, 4.0 * p, seed=5)
    assert (lo2, hi2) == pytest.approx((0.5 * lo, 0.5 * hi), rel=1e-12)
    assert ratio_interval(a, p, seed=5) == [lo, hi]
    assert lo < math.sqrt(a.mean() / p.mean()) < hi


def test_interval_of_many_frames_is_drawn_in_chunks(monkeypatch):
    # a run of many frames resamples in chunks (memory bounded): the same interval, in law
    rng = np.random.default_rng(2)
    a, p = _roll_frames(rng, 3000, 1.0)
    whole = ratio_interval(a, p, seed=1)
    monkeypatch.setattr(verify, "_BOOTSTRAP_CHUNK", 3000 * 7)  # 7 resamples at a time
    chunked = ratio_interval(a, p, seed=1)
    # two independent sets of 2,000 resamples: their percentiles agree to ~1 % of the width
    # (width 0.05 here): 0.002 is three times that
    assert chunked == pytest.approx(whole, abs=0.002)
    assert N_BOOTSTRAP >= 1000


def test_interval_skips_frames_with_no_prediction_and_needs_two_frames():
    a = np.array([1.0, 4.0, 1.0, 1.0])
    p = np.array([1.0, np.nan, 1.0, 1.0])
    lo, hi = ratio_interval(a, p)
    assert lo <= math.sqrt(a.mean() / np.nanmean(p)) <= hi
    assert ratio_interval([1.0], [1.0]) is None
    assert ratio_interval([1.0, 2.0], [np.nan, np.nan]) is None
