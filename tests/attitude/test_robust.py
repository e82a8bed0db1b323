"""The final fit's outlier rejection: stars whose angles to the others disagree are dropped."""

from __future__ import annotations

import numpy as np
import pytest
from attitude_fields import ARCSEC, add_noise, star_field
from scipy.spatial.transform import Rotation

from starsense.attitude.robust import median_misfit, pair_outliers, robust_attitude
from starsense.geometry.attitude import small_rotation_angles


def _field(seed: int, n: int, n_bad: int, *, bad_arcsec: float = 600.0):
    """Stars of 1-30 arcsec noise, ``n_bad`` of them moved ``bad_arcsec``, the first of those
    given the smallest sigma of all (a fit follows it)."""
    rng = np.random.default_rng(seed)
    attitude = Rotation.random(random_state=rng)
    b_true = star_field(rng, n, 15.0)
    sigma = rng.uniform(1.0, 30.0, n) * ARCSEC
    bad = rng.choice(n, n_bad, replace=False)
    if n_bad:
        sigma[bad[0]] = 0.1 * ARCSEC
    body = add_noise(rng, b_true, sigma)
    push = rng.normal(size=(n_bad, 3))  # a tangent direction, bad_arcsec long
    push -= np.sum(push * body[bad], axis=1)[:, None] * body[bad]
    push *= bad_arcsec * ARCSEC / np.linalg.norm(push, axis=1)[:, None]
    body[bad] = (body[bad] + push) / np.linalg.norm(body[bad] + push, axis=1)[:, None]
    return attitude, body, attitude.inv().apply(b_true), sigma, bad


def test_no_star_of_a_gaussian_field_is_dropped():
    # a right star is flagged when the median of its ~N normalised pair errors (half-normal,
    # median 0.674) exceeds 7 times that: with 20 stars, essentially never; 200 fields
    flagged = 0
    for seed in range(200):
        _, body, ref, sigma, _ = _field(seed, 20, 0)
        flagged += int(pair_outliers(body, ref, sigma).sum())
    assert flagged == 0


def test_gross_outliers_are_found_even_when_one_dominates_the_fit():
    for seed in range(50):
        attitude, body, ref, sigma, bad = _field(seed, 30, 6)
        flagged = np.flatnonzero(pair_outliers(body, ref, sigma))
        # 600 arcsec against sigmas of at most 30 arcsec: a moved star disagrees with its
        # pairs by 600 |cos| arcsec, median ~420, over sqrt(2) 30 arcsec at most: ~10 sigma
        # in the median, twice the threshold (4.7); no right star is flagged
        assert set(flagged) == set(bad), (seed, flagged, bad)
        att, _ = robust_attitude(body, ref, sigma)
        err = np.abs(small_rotation_angles(attitude, att.rotation))
        # the attitude of the kept stars: within 5 of its own sigma per axis (the fit's
        # iterative drop alone, one star at a time, follows the 0.1-arcsec star: 50 of 50 off)
        assert np.all(err < 5.0 * np.sqrt(np.diag(att.covariance_rad2))), (seed, err)


def test_too_few_stars_or_a_disagreeing_majority_drop_nothing():
    _, body, ref, sigma, _ = _field(1, 4, 1)
    assert not pair_outliers(body, ref, sigma).any()
    # half of the stars moved: the median cannot tell which half is right
    _, body, ref, sigma, _ = _field(2, 10, 5)
    assert not pair_outliers(body, ref, sigma).any()


def test_median_misfit_is_the_rayleigh_median_for_right_measurements():
    rng = np.random.default_rng(3)
    ref = rng.normal(size=(4000, 3))
    ref /= np.linalg.norm(ref, axis=1)[:, None]
    rot = Rotation.from_rotvec([0.1, -0.2, 0.3])
    sigma = 1e-5
    body = rot.apply(ref) + rng.normal(scale=sigma, size=ref.shape)  # ~ per axis across
    body /= np.linalg.norm(body, axis=1)[:, None]
    # the noise's part across each direction: 2-d, per-axis sigma -> median sqrt(2 ln 2);
    # 4000 stars put the sample median within ~2 %
    got = median_misfit(body, ref, sigma, rotation=rot)
    assert got == pytest.approx(np.sqrt(2 * np.log(2)), rel=0.05)
    # the same stars turned 20 sigma about an axis: a misfit of ~20 x sin(angle to the axis)
    off = Rotation.from_rotvec([0.0, 0.0, 20 * sigma]) * rot
    assert median_misfit(body, ref, sigma, rotation=off) > 10.0
    # only the kept stars count
    keep = np.zeros(len(ref), bool)
    keep[:10] = True
    assert median_misfit(body, ref, sigma, rotation=rot, keep=keep) < 3.0
