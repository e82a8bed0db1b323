"""The lens fit of an unknown camera (attitude, focal length, radial terms) against scipy.

The fit has its own Levenberg-Marquardt with analytic derivatives; scipy's ``least_squares``
(finite-difference Jacobian, its own trust-region solvers) is the independent computation it is
held against, on cameras drawn at random: wide and narrow fields, barrel and pincushion, one or
two radial terms or none, with and without gross outliers under the soft-L1 loss.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from starsense.solve.radial_lsq import RadialModel

CENTRE = np.array([639.5, 479.5])


def _problem(seed: int):
    """A camera, its stars' directions and noisy detections of them (3 gross outliers)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(8, 90))
    focal = rng.uniform(600.0, 3000.0)
    r0 = Rotation.random(random_state=seed)
    tangent = rng.uniform(-0.45, 0.45, (n, 2)) * 1000.0 / focal
    v = np.column_stack([tangent, np.ones(n)])
    v /= np.linalg.norm(v, axis=1)[:, None]
    sky = r0.inv().apply(v)
    truth = np.array([1e-3, -2e-3, 5e-4, focal, rng.uniform(-0.3, 0.1), rng.uniform(-0.05, 0.05)])
    xy = RadialModel(np.zeros((n, 2)), CENTRE, r0, n_terms=2).project(truth, sky)
    xy = xy + rng.normal(0.0, 0.3, xy.shape)
    xy[:3] += rng.normal(0.0, 20.0, (3, 2))
    return xy, sky, r0, truth


@pytest.mark.parametrize("seed", range(24))
def test_fit_reaches_scipys_minimum(seed):
    xy, sky, r0, truth = _problem(seed)
    n_terms = seed % 3
    robust = seed % 2 == 1
    model = RadialModel(xy, CENTRE, r0, n_terms=n_terms, fixed=(truth[4], 0.0))
    start = np.array([0.0, 0.0, 0.0, truth[3] * 1.02, 0.0, 0.0])[: 4 + n_terms]
    det = np.arange(len(xy))
    scale = 2.0 if robust else None
    ours = model.fit(start, det, sky, scale_px=scale)

    def residuals(theta):
        return (xy - model.project(theta, sky)).ravel()

    if robust:
        ref = least_squares(residuals, start, loss="soft_l1", f_scale=scale, x_scale="jac")
        cost = scale**2 * np.sum(np.sqrt(1.0 + (ours.fun / scale) ** 2) - 1.0)
    else:
        ref = least_squares(residuals, start, method="lm", x_scale="jac")
        cost = 0.5 * float(ours.fun @ ours.fun)
    # both minimise the same cost: ours is no higher than scipy's beyond scipy's own tolerance
    # (ftol 1e-8 relative), and the residuals returned are those of the parameters returned
    assert cost <= ref.cost * (1.0 + 1e-7)
    assert np.allclose(ours.fun, residuals(ours.x), atol=1e-9)
    # the parameters agree to a small fraction of their own 1-sigma (the Gauss-Newton covariance):
    # two minimisers stopped within ftol 1e-8 of one minimum differ by ~sqrt(1e-8 n) sigma
    j = ours.jac
    s2 = float(ours.fun @ ours.fun) / (len(ours.fun) - j.shape[1])
    sigma = np.sqrt(np.diag(np.linalg.inv(j.T @ j)) * s2)
    turn = (Rotation.from_rotvec(ours.x[:3]) * Rotation.from_rotvec(ref.x[:3]).inv()).as_rotvec()
    delta = np.concatenate([turn, ours.x[3:] - ref.x[3:]])
    assert np.all(np.abs(delta) <= 0.01 * sigma), delta / sigma


@pytest.mark.parametrize("n_terms", [0, 1, 2])
def test_jacobian_matches_finite_differences(n_terms):
    xy, sky, r0, truth = _problem(100 + n_terms)
    model = RadialModel(xy, CENTRE, r0, n_terms=n_terms, fixed=(truth[4], 0.0))
    theta = truth[: 4 + n_terms]
    fit = model.fit(theta, np.arange(len(xy)), sky)
    # the returned Jacobian is about the fitted attitude: rotation columns are derivatives for a
    # rotation applied on the left of it, which at the fit equals d/d(rotvec) only at rotvec 0;
    # so compare on a model whose reference attitude is the fitted one
    r_fit = Rotation.from_rotvec(fit.x[:3]) * r0
    at_fit = RadialModel(xy, CENTRE, r_fit, n_terms=n_terms, fixed=(truth[4], 0.0))
    x0 = np.concatenate([[0.0, 0.0, 0.0], fit.x[3:]])

    def residuals(theta):
        return (xy - at_fit.project(theta, sky)).ravel()

    numeric = np.empty_like(fit.jac)
    for k in range(len(x0)):
        h = 1e-7 * max(1.0, abs(x0[k]))
        up, down = x0.copy(), x0.copy()
        up[k] += h
        down[k] -= h
        numeric[:, k] = (residuals(up) - residuals(down)) / (2 * h)
    # central differences: truncation ~h^2 and rounding ~1e-16 * 1e3 px / h, both < 1e-5 of the
    # largest entry
    assert np.max(np.abs(fit.jac - numeric)) <= 1e-5 * np.max(np.abs(numeric))


def test_star_behind_the_camera_is_not_a_minimum():
    xy, sky, r0, truth = _problem(7)
    sky = sky.copy()
    sky[0] = -sky[0]  # behind the camera: no finite place, the cost is infinite
    model = RadialModel(xy, CENTRE, r0, n_terms=1, fixed=(truth[4], 0.0))
    fit = model.fit(truth[:5], np.arange(len(xy)), sky)
    assert np.isnan(fit.fun[:2]).all()
    # nothing to minimise: the start is returned (to the rounding of a rotation round trip)
    assert np.allclose(fit.x, truth[:5], rtol=1e-12, atol=1e-15)
