"""Angular rate from consecutive attitudes, and attitude prediction at a rate, with covariances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.attitude.rate import predict_attitude, rate_from_attitudes
from starsense.errors import InputError
from starsense.render.sequence import propagate_attitude


def _spd(rng, scale):
    a = rng.normal(size=(3, 3)) * scale
    return a @ a.T + np.eye(3) * scale**2


def test_rate_from_attitudes_inverts_the_render_convention():
    # render: A(t) = R(-w t) A(0) (render/scene.py); the rate recovered from two of its
    # attitudes is w to rounding (1e-12 rad/s: double precision on rotations of ~0.02 rad)
    rng = np.random.default_rng(1)
    for _ in range(5):
        a0 = Rotation.random(random_state=rng)
        w = rng.normal(size=3) * np.radians(1.0)
        a1 = propagate_attitude(a0, w, 0.5)
        rate, cov = rate_from_attitudes(a0, a1, 0.5)
        np.testing.assert_allclose(rate, w, atol=1e-12)
        np.testing.assert_array_equal(cov, np.zeros((3, 3)))
        pred, _ = predict_attitude(a0, 0.5, rate_rad_s=w)
        assert (pred * a1.inv()).magnitude() < 1e-12


def test_rate_covariance_against_monte_carlo():
    # errors d ~ N(0, P) on both attitudes (A_est = R(d) A_true); the sample covariance of
    # 20000 rates matches (P1 + M P0 M^T) / dt^2: the standard error of a variance from
    # 20000 draws is sqrt(2/20000) = 1 %, so 5 % is 5 sigma; the first-order formula's own
    # error is of order |w dt| ~ 2 % of the off-diagonal mixing, well inside it
    rng = np.random.default_rng(2)
    a0 = Rotation.random(random_state=rng)
    w = np.radians([1.0, -2.0, 0.5])
    dt = 0.4
    a1 = propagate_attitude(a0, w, dt)
    p0, p1 = _spd(rng, 1e-5), _spd(rng, 2e-5)
    n = 20000
    d0 = rng.multivariate_normal(np.zeros(3), p0, size=n)
    d1 = rng.multivariate_normal(np.zeros(3), p1, size=n)
    e0 = Rotation.from_rotvec(d0) * a0
    e1 = Rotation.from_rotvec(d1) * a1
    rates = -(e1 * e0.inv()).as_rotvec() / dt
    _, cov = rate_from_attitudes(a0, a1, dt, cov0_rad2=p0, cov1_rad2=p1)
    sample = np.cov(rates.T)
    np.testing.assert_allclose(np.diag(sample), np.diag(cov), rtol=0.05)
    scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    assert np.max(np.abs(sample - cov) / scale) < 0.05
    assert np.all(np.abs(rates.mean(axis=0) - w) < 5 * np.sqrt(np.diag(cov) / n))


def test_predicted_covariance_against_monte_carlo():
    # P_pred = M P0 M^T + dt^2 cov(w); same sampling argument as above (5 % = 5 sigma)
    rng = np.random.default_rng(3)
    a0 = Rotation.random(random_state=rng)
    w = np.radians([2.0, 0.5, -1.0])
    dt = 1.0
    p0, pw = _spd(rng, 1e-5), _spd(rng, 1e-5)
    pred, cov = predict_attitude(a0, dt, rate_rad_s=w, cov_rad2=p0, rate_cov_rad2_s2=pw)
    n = 20000
    d0 = rng.multivariate_normal(np.zeros(3), p0, size=n)
    dw = rng.multivariate_normal(np.zeros(3), pw, size=n)
    truth = Rotation.from_rotvec(np.zeros((n, 3))) * a0
    est = Rotation.from_rotvec(-(w + dw) * dt) * (Rotation.from_rotvec(d0) * truth)
    err = (est * pred.inv()).as_rotvec()
    np.testing.assert_allclose(np.diag(np.cov(err.T)), np.diag(cov), rtol=0.05)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dt_s": 0.0}, "dt_s"),
        ({"dt_s": float("nan")}, "dt_s"),
        ({"cov0_rad2": np.eye(2)}, "cov0_rad2"),
        ({"cov1_rad2": np.full((3, 3), np.inf)}, "cov1_rad2"),
    ],
)
def test_rate_bad_input(kwargs, match):
    a = Rotation.identity()
    args = {"attitude0": a, "attitude1": a, "dt_s": 1.0, **kwargs}
    with pytest.raises(InputError, match=match):
        rate_from_attitudes(**args)


def test_predict_bad_input():
    with pytest.raises(InputError, match="dt_s"):
        predict_attitude(Rotation.identity(), -1.0)
    with pytest.raises(InputError, match="rate_rad_s"):
        predict_attitude(Rotation.identity(), 1.0, rate_rad_s=[1.0, 2.0])
    with pytest.raises(InputError, match="attitude"):
        predict_attitude("north", 1.0)
