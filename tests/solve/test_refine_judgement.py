"""How the solver judges its model fit: a local misfit from the groups' scores, the move rule."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.model.fit import ModelFit
from starsense.model.misfit import PULL_SIGMAS, misfit_pulls
from starsense.sensor import load_sensor
from starsense.solve.fit_judgement import LOCAL_MISFIT_SIGMAS, judged, local_misfit


def _fit(cov, rob, noise, rotation=None):
    p = cov.shape[0]
    return ModelFit(
        rotation=rotation or Rotation.identity(),
        rate_rad_s=np.zeros(3),
        covariance=cov,
        fluxes_e=np.ones(3),
        chi2=1000.0,
        dof=1000,
        n_pixels=1000 + p,
        iterations=3,
        converged=True,
        robust_covariance=rob,
        robust_noise=noise,
    )


def _sandwich(rng, groups, inflate=1.0):
    """Fisher, sandwich and its noise of ``groups`` windows whose scores are drawn from the
    model's own information (the last window's scaled by ``inflate``: one the model draws
    wrong); the windows' information of unequal weight, as bright and faint stars'."""
    infos = []
    for _ in range(groups):
        a = rng.normal(size=(3, 3)) * rng.uniform(0.3, 3.0)
        infos.append(a @ a.T + 0.1 * np.eye(3))
    s = sum(infos)
    scores = np.array([rng.multivariate_normal(np.zeros(3), f) for f in infos])
    scores[-1] *= inflate
    cov = np.linalg.inv(s)
    v = np.array([np.diag(cov @ f @ cov) for f in infos])  # as ModelFit.robust_noise
    noise = np.sqrt(2.0 * (v * v).sum(axis=0)) / v.sum(axis=0)
    return cov, cov @ (scores.T @ scores) @ cov, noise


def test_a_right_model_seldom_reads_as_alocal_misfit():
    # scores drawn from the model's own information: each axis's sandwich variance is a sum of
    # weighted chi-squares of one degree of freedom, above 3 of its own standard deviations
    # with probability ~0.5-1 % (its right tail is heavier than a normal's 0.13 %), 1.5-3 % on
    # one of three axes: below 4 % over 1,000 draws (binomial sd 0.5 %)
    rng = np.random.default_rng(5)
    alarms = sum(local_misfit(_fit(*_sandwich(rng, 40))) for _ in range(1000))
    assert alarms / 1000 < 0.04


def test_one_window_pulling_the_attitude_reads_as_alocal_misfit():
    # one of 40 windows whose score scatters 10 times what the model says (a streak's end drawn
    # wrong): its share of the variance, ~100 times a window's, lifts the sandwich to a few
    # times the bound, past 3 of its noise (~0.3-0.5 of the bound at 40 unequal windows) in
    # most draws: 69 % of 200 here, its own weight drawn as the others' (a faint window's pull
    # stays under the noise); any window at 20 times, 91 %. Both well above the 2.6 % of the
    # right model (binomial sd 3 %)
    rng = np.random.default_rng(6)
    seen = sum(local_misfit(_fit(*_sandwich(rng, 40, inflate=10.0))) for _ in range(200))
    assert seen / 200 > 0.5
    assert LOCAL_MISFIT_SIGMAS == 3.0  # the docstring's and these bounds' threshold


def test_a_fit_far_from_the_centroids_is_kept_on_a_smeared_frame_only():
    sensor = load_sensor("st16")
    cog_sigma = np.full(3, 1e-5)
    moved = Rotation.from_rotvec([3e-4, 0.0, 0.0])  # 30 centroid sigmas, ~5 px on the sky
    # the parameters: the attitude at rest (3), with the PSF's width (4), attitude and rate
    # (6), with the width (7); and a fit at rest drawn at a given rate (a smeared frame)
    cases = ((3, False, 0.0), (4, False, 0.0), (6, True, 0.0), (7, True, 0.0), (3, True, 1e-2))
    for p, kept, rate in cases:
        cov = np.eye(p) * 1e-12
        fit = _fit(cov, cov.copy(), np.full(p, 0.2), rotation=moved)
        fit = dataclasses.replace(fit, rate_rad_s=np.array([0.0, rate, 0.0]))
        verdict = judged(fit, sensor, Rotation.identity(), cog_sigma_rad=cog_sigma, counts=(10, 0))
        assert verdict.used is kept, verdict.note
        assert kept or "sigma from the centroids'" in verdict.note
    assert math.isfinite(sensor.focal_length_px)


def test_a_misfit_that_moves_the_stars_is_told_from_one_that_scatters_about_them():
    # pixels scattering 5 times their variance as noise would (reduced chi-square 5): each
    # window's score scatters sqrt(5) times the model's, the sandwich reads 5 times the Fisher
    # bound and the fit stands, with the sandwich's sigmas; past PULL_SIGMAS of its noise as
    # seldom as the local misfit's right model (< 4 % of 500 draws, as there). Scores that
    # scatter 6 times the model's at that chi-square (each star's position off by 6 of its
    # sigmas: a PSF or optics the sensor does not describe) read 36 times the bound: pulled,
    # in every draw, and the centroids' attitude is kept
    rng = np.random.default_rng(7)
    sensor = load_sensor("st16")

    def fit_at(scale):
        cov, rob, noise = _sandwich(rng, 40)
        return dataclasses.replace(_fit(cov, rob * scale**2, noise), chi2=5.0 * 1000.0)

    assert _fit(np.eye(3), np.eye(3), np.ones(3)).reduced_chi2 == 1.0  # chi2 over dof
    calm = [fit_at(math.sqrt(5.0)) for _ in range(500)]
    assert sum(misfit_pulls(f) for f in calm) / 500 < 0.04
    pulled = [fit_at(6.0) for _ in range(100)]
    assert all(misfit_pulls(f) for f in pulled)
    assert PULL_SIGMAS == 3.0  # the threshold these bounds are for
    cog_sigma = np.full(3, 1.0)  # no move rule here: both fits sit on the centroids' attitude
    kept = next(f for f in calm if not misfit_pulls(f))
    verdict = judged(kept, sensor, Rotation.identity(), cog_sigma_rad=cog_sigma, counts=(40, 0))
    assert verdict.used and "own scatter" in verdict.note, verdict.note
    np.testing.assert_allclose(
        verdict.fit.sigma_axes_rad, np.sqrt(np.diag(kept.robust_covariance)), rtol=1e-12
    )
    verdict = judged(
        pulled[0], sensor, Rotation.identity(), cog_sigma_rad=cog_sigma, counts=(40, 0)
    )
    assert not verdict.used and "moves the stars" in verdict.note


def test_a_fit_most_centroids_agree_with_stands_against_their_pulled_attitude():
    # ten stars of 0.5 px centroid noise, two of them pulled 20 of their sigmas the same way (a
    # blend each): the least-squares attitude follows them by ~2 x 20 / 10 = 4 star sigmas,
    # ~11 of its own and 1.7 px, past the move rule. A fit at the truth leaves eight of the ten
    # within their noise (median residual 1.2 sigma, the 1.18 of right stars), the pulled
    # attitude most of them 3-5 sigma off (median 4.8): the fit stands. A fit as far the other
    # way (every star off by as much, median 8.5) does not, as without the centroids' residuals
    from starsense.attitude.estimate import estimate_attitude
    from starsense.attitude.robust import median_misfit

    sensor = load_sensor("st16")
    rng = np.random.default_rng(11)
    det = sensor.detector
    xy = rng.uniform([0, 0], [det.columns, det.rows], size=(10, 2))
    sigma = 0.5 / sensor.focal_length_px  # rad
    ref = _pinhole(sensor, xy)  # the truth: identity
    pull = np.zeros((10, 2))
    pull[:2] = [20 * 0.5, 0.0]  # px
    body = _pinhole(sensor, xy + pull + rng.normal(0, 0.5, (10, 2)))
    cog = estimate_attitude(body, ref, np.full(10, sigma), method="svd")
    misfit = functools.partial(median_misfit, body, ref, sigma)
    cov = np.eye(3) * (0.1 * sigma) ** 2
    for rotation, used in ((Rotation.identity(), True), (cog.rotation * cog.rotation, False)):
        fit = _fit(cov, cov.copy(), np.full(3, 0.2), rotation=rotation)
        kwargs = {"cog_sigma_rad": cog.sigma_axes_rad, "counts": (10, 0)}
        alone = judged(fit, sensor, cog.rotation, **kwargs)
        assert not alone.used and "sigma from the centroids'" in alone.note, alone.note
        verdict = judged(fit, sensor, cog.rotation, misfit=misfit, **kwargs)
        assert verdict.used is used, verdict.note


def _pinhole(sensor, xy):
    """Unit vectors of pixel positions through a pinhole at the sensor's focal length."""
    det = sensor.detector
    v = np.column_stack([xy - [det.columns / 2, det.rows / 2], np.full(len(xy), 1.0)])
    v[:, 2] *= sensor.focal_length_px
    return v / np.linalg.norm(v, axis=1, keepdims=True)
