"""The final fit's outlier rejection: stars whose angles to the others disagree are dropped."""

from __future__ import annotations

import numpy as np
import pytest
from attitude_fields import ARCSEC, add_noise, star_field
from scipy.spatial.transform import Rotation

from starsense.attitude.estimate import estimate_attitude
from starsense.attitude.robust import (
    SCATTER_STARS,
    median_misfit,
    pair_disagreements,
    pair_outliers,
    pair_scatter,
    robust_attitude,
)
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.attitude_fit import kernel_fit


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


def _pair_outliers_reference(body, ref, sigma):
    """pair_outliers as first written: np.cross, and np.nanmedian with the diagonal NaN."""
    n = len(body)
    if n < 5:
        return np.zeros(n, dtype=bool)

    def angles(v):
        cross = np.linalg.norm(np.cross(v[:, None, :], v[None, :, :]), axis=2)
        return np.arctan2(cross, v @ v.T)

    z = np.abs(angles(body) - angles(ref)) / np.sqrt(sigma[:, None] ** 2 + sigma[None, :] ** 2)
    np.fill_diagonal(z, np.nan)
    bad = np.nanmedian(z, axis=1) > 7.0 * 0.6744897501960817
    return bad if 2 * bad.sum() < n else np.zeros(n, dtype=bool)


def _robust_reference(body, ref, sigma, max_drop=5):
    """robust_attitude's documented algorithm, step by step: pair outliers, then the drops."""
    keep = ~_pair_outliers_reference(body, ref, sigma)
    att = estimate_attitude(body[keep], ref[keep], sigma[keep], method="svd")
    for _ in range(max_drop):
        if keep.sum() <= 3:
            break
        z = np.full(len(body), -np.inf)
        z[keep] = att.residuals_rad / sigma[keep]
        if z.max() <= 7.0:
            break
        keep[int(np.argmax(z))] = False
        att = estimate_attitude(body[keep], ref[keep], sigma[keep], method="svd")
    return att, keep


@pytest.mark.parametrize("n_bad", [0, 1, 3, 6])
def test_pair_outliers_and_the_fit_are_those_of_the_reference_algorithm(n_bad):
    # the fast forms (no np.cross, a partition for the medians, the pair test skipped when
    # a fit to all leaves every residual below its bound) against the algorithm as written;
    # fields from 4 to 30 stars, clean and with gross outliers, some just moved 5-60 arcsec
    # (near the thresholds); the attitudes of one set of stars agree to rounding, amplified by
    # the problem's conditioning: weights spread 1e5-fold (0.1-30 arcsec) leave the kernel's
    # Jacobi eigenvector ~1e-11 rad from LAPACK's SVD, ~1e-6 of the attitude's own sigma;
    # 1e-5 sigma bounds it
    for seed in range(60):
        n = 4 + seed % 27
        bad_arcsec = (600.0, 60.0, 20.0, 5.0)[seed % 4]
        _, body, ref, sigma, _ = _field(seed, n, min(n_bad, n // 2), bad_arcsec=bad_arcsec)
        want = _pair_outliers_reference(body, ref, sigma)
        assert np.array_equal(pair_outliers(body, ref, sigma), want), seed
        att_ref, keep_ref = _robust_reference(body, ref, sigma)
        for fit in (None, kernel_fit):
            att, keep = robust_attitude(body, ref, sigma, fit=fit)
            assert np.array_equal(keep, keep_ref), (seed, fit)
            err = small_rotation_angles(att_ref.rotation, att.rotation)
            own = np.sqrt(np.diag(att_ref.covariance_rad2))
            assert np.all(np.abs(err) < 1e-5 * own), (seed, fit, err / own)


def test_pair_outliers_with_zero_sigmas_takes_the_median_of_what_is_defined():
    # two stars of zero sigma that agree exactly with each other give 0/0 = NaN: the medians
    # are then NaN-aware; the moved star is still found
    _, body, _, sigma, bad = _field(5, 12, 1)
    ref = body.copy()  # the same angles, computed from the same numbers: differences exactly 0
    body[bad] = _field(6, 12, 0)[1][0]  # a star elsewhere in the field
    calm = [i for i in range(12) if i not in bad][:2]
    sigma[calm] = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        got = pair_outliers(body, ref, sigma)
        assert np.array_equal(got, _pair_outliers_reference(body, ref, sigma))
    assert set(np.flatnonzero(got)) == set(bad)


def _list(rng, n, noise_rad, *, n_blends=0, blend_sigmas=30.0):
    """A matched centroid list: n stars of `noise_rad` per axis, the first `n_blends` of them
    moved exactly `blend_sigmas` noise sigmas in a random direction; (body, reference)."""
    attitude = Rotation.random(random_state=rng)
    b_true = star_field(rng, n, 15.0)
    body = add_noise(rng, b_true, np.full(n, noise_rad))
    step = rng.normal(size=(n_blends, 3))  # random directions in the stars' tangent planes
    step -= np.sum(step * body[:n_blends], axis=1)[:, None] * body[:n_blends]
    step /= np.linalg.norm(step, axis=1)[:, None]
    angle = blend_sigmas * noise_rad
    body[:n_blends] = np.cos(angle) * body[:n_blends] + np.sin(angle) * step
    return body, attitude.inv().apply(b_true)


def test_pair_scatter_is_the_medians_of_the_pair_angle_errors():
    # against the definition written out: np.median over each star's other stars, then over
    # the stars, of |measured - catalogue angle|, over 0.674 sqrt(2); and, over 400 lists of
    # 14 stars, the noise itself: its mean within 4 % (one list's estimate scatters by ~20 %,
    # the mean of 400 by ~1 %; a median of medians of correlated pairs is not exactly the
    # half-normal's median: a few % of bias are allowed)
    rng = np.random.default_rng(5)
    noise = 40.0 * ARCSEC
    got = []
    for k in range(400):
        body, ref = _list(rng, 14, noise)
        got.append(pair_scatter(body, ref) / noise)
        if k < 20:
            d = np.abs(
                np.arccos(np.clip(body @ body.T, -1, 1)) - np.arccos(np.clip(ref @ ref.T, -1, 1))
            )
            np.fill_diagonal(d, np.nan)
            want = np.median(np.nanmedian(d, axis=1)) / (0.6744897501960817 * np.sqrt(2.0))
            # arccos of a dot product near 1 loses ~1e-8 rad (sqrt of rounding) per angle
            assert got[-1] * noise == pytest.approx(want, abs=1e-7 * noise / ARCSEC * ARCSEC)
    assert abs(np.mean(got) - 1.0) < 0.04


def test_a_lists_floor_sigma_rises_to_its_scatter_and_keeps_its_right_stars():
    # 1 px centroids (40 arcsec) given a floor of 0.3 px (12 arcsec): at the floor the drops
    # take right stars (about 1 in 9 lies beyond 7 floor sigmas); at the stars' own scatter
    # none of 14 right stars is dropped in 200 lists (7 sigma of the estimate: P ~ 1e-10)
    rng = np.random.default_rng(6)
    noise, floor = 40.0 * ARCSEC, 12.0 * ARCSEC
    dropped_at_floor = 0
    for _ in range(200):
        body, ref = _list(rng, 14, noise)
        att, keep = robust_attitude(body, ref, floor, fit=kernel_fit, scatter=True)
        assert keep.all()
        # the fit of every star, its covariance at the sigma the stars show (>= the floor)
        want = kernel_fit(body, ref, np.full(14, max(floor, pair_scatter(body, ref))))
        assert np.array_equal(att.rotation.as_matrix(), want.rotation.as_matrix())
        dropped_at_floor += int((~robust_attitude(body, ref, floor, fit=kernel_fit)[1]).sum())
    assert dropped_at_floor > 100  # the defect this guards: ~14/9 per list at the floor


def test_a_floor_above_the_scatter_and_few_stars_change_nothing():
    rng = np.random.default_rng(7)
    for n, noise in ((14, 2.0 * ARCSEC), (14, 12.0 * ARCSEC), (SCATTER_STARS - 1, 40.0 * ARCSEC)):
        for _ in range(30):
            body, ref = _list(rng, n, noise)
            a, ka = robust_attitude(body, ref, 12.0 * ARCSEC, fit=kernel_fit, scatter=True)
            b, kb = robust_attitude(body, ref, 12.0 * ARCSEC, fit=kernel_fit)
            assert np.array_equal(ka, kb)
            assert np.array_equal(a.covariance_rad2, b.covariance_rad2)


@pytest.mark.parametrize("n, n_blends, most", [(16, 2, 0), (16, 3, 0), (SCATTER_STARS, 2, 9)])
def test_blends_among_a_list_do_not_hide_in_its_scatter(n, n_blends, most):
    # right stars at the floor's noise, some centroided 30 sigma off (blends): each right
    # star's median pair ignores them, the scale stays near the floor (2 of 16: mean 1.23,
    # largest 2.07 times it over 400 draws) and the drops take every blend and no right star;
    # a quarter of 8 stars weighs in the medians: 1.1 % of such lists keep a blend (11 of
    # 1,000 draws; the floor alone, none), at most 9 of these 300 (3 %; Poisson P ~ 0.2 %)
    rng = np.random.default_rng(8)
    sigma = 12.0 * ARCSEC
    missed = 0
    for _ in range(300):
        body, ref = _list(rng, n, sigma, n_blends=n_blends)
        _att, keep = robust_attitude(body, ref, sigma, fit=kernel_fit, scatter=True)
        assert keep[n_blends:].all()
        missed += bool(keep[:n_blends].any())
    assert missed <= most


def test_residual_scaled_keeps_a_fits_matrix_unbuilt():
    # the Birge-scaled copy of a fit given as a matrix: the same matrix, not yet a Rotation
    # (building it is ~50 us a centroid solve need not pay), and the Rotation when read
    from starsense.attitude.robust import residual_scaled

    rng = np.random.default_rng(9)
    b_true = star_field(rng, 12, 15.0)
    sigma = np.full(12, 10.0 * ARCSEC)
    body = add_noise(rng, b_true, 3.0 * sigma)  # residuals 3 times their sigma: ratio ~9
    att = kernel_fit(body, b_true, sigma)
    if att.__dict__["_matrix"] is None:
        pytest.skip("no compiled kernel: the fit is a Rotation already")
    got = residual_scaled(att)
    assert got.__dict__["_rotation"] is None and got.matrix is att.matrix
    ratio = 2.0 * att.loss / att.chi2_dof
    assert ratio > 1.0
    np.testing.assert_allclose(got.covariance_rad2, att.covariance_rad2 * ratio, rtol=1e-15)
    np.testing.assert_array_equal(got.rotation.as_matrix(), att.rotation.as_matrix())


def test_residuals_well_below_their_sigmas_lower_the_covariance_to_their_95_bound():
    """Bright stars given a sigma 20 times their scatter: the covariance follows the scatter.

    40 stars (dof 77) whose centroids scatter 1/20 of the sigma they were given: over 200
    fields the lowered sigma lies at or above each field's true one (the chi-square's 95 %
    upper bound is conservative: below it in at most ~5 % of fields, binomial 3 sd ~ 4.6 %,
    so at most 20 of 200) and within 1.3 times it (the bound over the estimate at dof 77 is
    77 / 57.8 = 1.33 in variance, 1.15 in sigma; the chi-square of a field scatters by
    sqrt(2 / 77) = 16 % about it). With 8 stars (dof 13, fewer than MIN_DOF_LOWERED) nothing
    is lowered: the ratio of so few is no measurement.
    """
    from starsense.attitude.robust import MIN_DOF_LOWERED, residual_scaled

    rng = np.random.default_rng(4)
    below, ratios = 0, []
    for _ in range(200):
        b_true = star_field(rng, 40, 15.0)
        given = np.full(40, 20.0 * ARCSEC)
        att = kernel_fit(add_noise(rng, b_true, given / 20.0), b_true, given)
        truth = att.covariance_rad2 / 400.0  # the covariance of the stars' actual scatter
        got = residual_scaled(att)
        ratio = float(np.sqrt(np.trace(got.covariance_rad2) / np.trace(truth)))
        below += ratio < 1.0
        ratios.append(ratio)
    assert below <= 20
    assert float(np.median(ratios)) < 1.3
    few = star_field(rng, 8, 15.0)
    att = kernel_fit(add_noise(rng, few, np.full(8, ARCSEC)), few, np.full(8, 20.0 * ARCSEC))
    assert att.chi2_dof < MIN_DOF_LOWERED
    np.testing.assert_array_equal(residual_scaled(att).covariance_rad2, att.covariance_rad2)


def test_residuals_beyond_noise_alarm_at_their_chance_and_always_at_four_times():
    # 10 stars of right sigmas (dof 17): the chi-square passes its 1e-3 upper quantile in
    # 1e-3 of fields; over 3,000 at most 10 (Poisson mean 3, P(> 10) ~ 3e-4). At sigmas a
    # quarter of the scatter the chi-square is 16 times a right one (272 against the bound
    # 40.8): under it only where a chi-square of 17 dof falls under 2.55 (P 2e-5), so in
    # every one of 200 fields
    from starsense.attitude.robust import RESIDUALS_P, residuals_beyond_noise

    assert RESIDUALS_P == 1e-3  # the chance these bounds are for
    rng = np.random.default_rng(21)
    sigma = np.full(10, 10.0 * ARCSEC)
    alarms = stated_low = 0
    for _ in range(3000):
        b_true = star_field(rng, 10, 15.0)
        alarms += residuals_beyond_noise(kernel_fit(add_noise(rng, b_true, sigma), b_true, sigma))
    for _ in range(200):
        b_true = star_field(rng, 10, 15.0)
        att = kernel_fit(add_noise(rng, b_true, 4.0 * sigma), b_true, sigma)
        stated_low += residuals_beyond_noise(att)
    assert alarms <= 10
    assert stated_low == 200


@pytest.mark.parametrize("spread_rad", [5e-6, 1e-3, 0.3, 1.5])
def test_pair_disagreements_are_the_angles_differences(spread_rad):
    # the angles from the chords against atan2(|a x b|, a . b) (accurate at every angle): the
    # dot product's rounding (a few 1e-16) moves an angle theta by about 1e-16 / theta rad,
    # 2e-11 rad for stars 1 arcsec apart; bound: 2e-15 / spread + 1e-12 rad, at most 4e-10 rad
    # (1e-4 arcsec), far below any centroid's noise
    rng = np.random.default_rng(7)

    def units(n):
        v = np.column_stack([spread_rad * rng.normal(size=(n, 2)), np.ones(n)])
        return v / np.linalg.norm(v, axis=1)[:, None]

    body, ref = units(12), units(12)

    def angles(v):
        cross = np.linalg.norm(np.cross(v[:, None, :], v[None, :, :]), axis=-1)
        return np.arctan2(cross, v @ v.T)

    want = np.abs(angles(body) - angles(ref))
    tol = 2e-15 / spread_rad + 1e-12
    np.testing.assert_allclose(pair_disagreements(body, ref), want, rtol=0, atol=tol)
    assert np.all(np.diag(pair_disagreements(body, ref)) == 0.0)
