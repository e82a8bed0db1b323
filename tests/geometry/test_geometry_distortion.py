"""Brown-Conrady distortion: the inverse, the Jacobian, and the sensor's projection with it."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.geometry.distortion import distort, distortion_jacobian, undistort
from starsense.sensor import load_sensor
from starsense.sensor.dump import sensor_to_toml
from starsense.sensor.load import sensor_from_dict

COEFFS = (2.0, -3.0, 1e-3, -5e-4)  # 10 % radial at r = 0.22, decentring 1e-3


def test_undistort_inverts_distort():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.2, 0.2, size=(2, 2000))
    xd, yd = distort(x, y, COEFFS)
    xi, yi = undistort(xd, yd, COEFFS)
    assert np.max(np.hypot(xi - x, yi - y)) < 1e-14  # Newton converges to rounding


def test_undistort_beyond_a_barrels_fold_is_nan():
    # r_d = r (1 + k1 r^2) with k1 = -2/9 rises to its fold at r = 1 / sqrt(3 |k1|) = 1.2247,
    # r_d = 0.8165, then falls: a distorted radius below that has one preimage inside the fold
    # (returned), one above it has none there; the preimages on the fold's far side (negative
    # r, the point flipped through the centre: distort(-2.5087) = 1.0) are not the lens's
    k1 = -2.0 / 9.0
    fold_r = 1.0 / np.sqrt(3.0 * abs(k1))
    fold_rd = fold_r * (1.0 + k1 * fold_r**2)
    rd = np.array([0.3, 0.8, 0.999 * fold_rd, 1.01 * fold_rd, 1.0, 1.2, 2.0, 5.0])
    x, y = undistort(rd, np.zeros_like(rd), (k1, 0.0, 0.0, 0.0))
    inside = rd < fold_rd
    assert np.all(np.isnan(x[~inside]) & np.isnan(y[~inside]))
    assert np.all((x[inside] > 0) & (x[inside] < fold_r))
    np.testing.assert_allclose(x[inside] * (1.0 + k1 * x[inside] ** 2), rd[inside], rtol=1e-12)


def test_jacobian_matches_central_differences():
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-0.2, 0.2, size=(2, 50))
    j = distortion_jacobian(x, y, COEFFS)
    h = 1e-6  # central differences: error ~ h^2 * third derivative ~ 1e-11
    dx = (np.array(distort(x + h, y, COEFFS)) - np.array(distort(x - h, y, COEFFS))) / (2 * h)
    dy = (np.array(distort(x, y + h, COEFFS)) - np.array(distort(x, y - h, COEFFS))) / (2 * h)
    assert np.allclose(j[:, :, 0], dx.T, atol=1e-8)
    assert np.allclose(j[:, :, 1], dy.T, atol=1e-8)


def test_opencv_convention_by_hand():
    # OpenCV's projectPoints: x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
    x, y = 0.1, -0.05
    r2 = x * x + y * y
    k1, k2, p1, p2 = COEFFS
    want_x = x * (1 + k1 * r2 + k2 * r2**2) + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    want_y = y * (1 + k1 * r2 + k2 * r2**2) + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    got = distort(np.array([x]), np.array([y]), COEFFS)
    assert got[0][0] == pytest.approx(want_x, rel=1e-15)
    assert got[1][0] == pytest.approx(want_y, rel=1e-15)


def _lens(**kw):
    s = load_sensor("st16")
    return s.with_(optics=dataclasses.replace(s.optics, **kw))


def test_sensor_project_unproject_round_trip_with_principal_point():
    s = _lens(
        distortion_k1=2.0,
        distortion_k2=-3.0,
        distortion_p1=1e-3,
        distortion_p2=-5e-4,
        principal_offset_x_px=12.5,
        principal_offset_y_px=-7.0,
    )
    rng = np.random.default_rng(2)
    xs = rng.uniform(-0.5, s.detector.columns - 0.5, 500)
    ys = rng.uniform(-0.5, s.detector.rows - 0.5, 500)
    x2, y2 = s.project(s.unproject(xs, ys))
    assert np.max(np.hypot(x2 - xs, y2 - ys)) < 1e-9
    # the optical axis lands on the principal point
    assert s.project([[0.0, 0.0, 1.0]])[0][0] == pytest.approx(s.principal_point_px[0])


def test_sensor_toml_round_trip_and_bad_values():
    s = _lens(distortion_k1=0.11, distortion_p2=3e-4, principal_offset_x_px=10.5)
    again = sensor_from_dict(tomllib.loads(sensor_to_toml(s, "calibrated")), "x.toml")
    assert again == s  # frozen dataclasses: every field equal, floats exactly (repr)
    with pytest.raises(InputError, match=r"optics.distortion_p1"):
        _lens(distortion_p1=5.0)
    with pytest.raises(InputError, match="attitude areas"):
        sensor_to_toml(load_sensor("lin2024"))
