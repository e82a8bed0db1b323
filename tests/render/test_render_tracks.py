"""Star tracks: exact rotation of the camera, arcs by sub-stepping (eqs. 1, 2, 10, 12)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.render.smear import polyline_expected
from starsense.render.tracks import star_tracks
from starsense.units import DEG


@pytest.mark.parametrize("w_deg_s", [(1.0, 0.0), (0.0, 3.0), (-6.0, 8.0), (0.3, 0.2)])
def test_streak_length_eq1_for_a_star_starting_at_the_boresight(st16, w_deg_s) -> None:
    # A star on the boresight at t = 0 moves along a great circle through the boresight, a
    # straight line in the gnomonic projection, to the angle |w| t_e: length f tan(|w| t_e)
    # (eq. 1) exactly. (Our attitude is mid-exposure, so b_mid = R(-w t_e / 2) z.)
    w = np.array([w_deg_s[0], w_deg_s[1], 0.0]) * DEG
    b_mid = Rotation.from_rotvec(-w * st16.exposure_s / 2).apply([0.0, 0.0, 1.0])
    tr = star_tracks(st16, b_mid, rate_rad_s=w)
    cx, cy = st16.principal_point_px
    np.testing.assert_allclose(tr.start[0], [cx, cy], atol=1e-9)
    v = tr.vertices[0]
    length = np.hypot(*np.diff(v, axis=0).T).sum()
    expected = st16.streak_length_px(np.hypot(*w[:2]))
    assert length == pytest.approx(expected, rel=1e-10)
    assert np.hypot(*(tr.end[0] - tr.start[0])) == pytest.approx(expected, rel=1e-10)
    # direction of eq. 12 at the boresight (b = z): delta b ~ (-w_y, w_x)
    d = (tr.end[0] - tr.start[0]) / expected
    np.testing.assert_allclose(d, np.array([-w[1], w[0]]) / np.hypot(*w[:2]), atol=1e-6)


@pytest.mark.parametrize("wz_deg_s", [1.0, 10.0, -30.0])
def test_roll_arc_eq2_at_the_edge_of_the_minor_axis(st16, wz_deg_s) -> None:
    # A star at h/2 from the boresight on the minor (row) axis turns about the boresight by
    # theta = w_z t_e: an exact circle of radius r = h/2 px, arc length r theta. Eq. 2 gives
    # r tan(theta), the small-angle form; they differ by r (tan theta - theta) ~ r theta^3 / 3
    # (1.7e-6 px at 1 deg/s, 1.7e-3 px at 10 deg/s, 0.05 px at 30 deg/s). The sub-stepped
    # polyline is shorter than the arc by at most r theta^3 / (24 K^2).
    wz = wz_deg_s * DEG
    theta = abs(wz) * st16.exposure_s
    r = min(st16.detector.rows, st16.detector.columns) / 2
    cx, cy = st16.principal_point_px
    tr = star_tracks(st16, st16.unproject([cx], [cy - r]), rate_rad_s=(0.0, 0.0, wz), tol_px=1e-4)
    v = tr.vertices[0]
    np.testing.assert_allclose(np.hypot(v[:, 0] - cx, v[:, 1] - cy), r, rtol=1e-12)
    polyline = np.hypot(*np.diff(v, axis=0).T).sum()
    k = len(v) - 1
    assert r * theta - r * theta**3 / (24 * k**2) - 1e-9 <= polyline <= r * theta + 1e-9
    eq2 = st16.roll_arc_px(wz)
    assert abs(polyline - eq2) <= r * (math.tan(theta) - theta) + r * theta**3 / 24 + 1e-9


def test_arcs_are_sub_stepped_to_one_thousandth_of_a_pixel(st16) -> None:
    # Fast roll and cross-axis rate for a star in a corner: the straight uniform motion on
    # each segment must stay within 0.001 px of the exact motion, checked at 4001 times.
    w = np.array([2.0, -1.0, 40.0]) * DEG
    x, y = 50.0, 40.0
    v = st16.unproject([x], [y])
    tr = star_tracks(st16, v, rate_rad_s=w)
    k = int(tr.n_segments[0])
    assert k > 1
    f = np.linspace(0, 1, 4001)
    tau = (f - 0.5) * st16.exposure_s
    rot = Rotation.from_rotvec(-tau[:, None] * w[None, :])
    px, py = st16.project(rot.apply(v[0]))
    seg = np.minimum((f * k).astype(int), k - 1)
    frac = f * k - seg
    vert = tr.vertices[0]
    lx = vert[seg, 0] + frac * (vert[seg + 1, 0] - vert[seg, 0])
    ly = vert[seg, 1] + frac * (vert[seg + 1, 1] - vert[seg, 1])
    assert np.hypot(px - lx, py - ly).max() < 0.001
    assert tr.max_deviation_px[0] < 0.001


def test_a_long_streaks_light_centres_on_its_time_average(st16) -> None:
    # Each segment carries an equal share of the light centred on its chord's midpoint, so the
    # polyline's light centre is the mean of the midpoints. The true light centre is the time
    # average of the exact motion (20,000 samples here, an independent quadrature). For an arc
    # the chord's midpoint sits two thirds of the sagitta from the arc's average, so with every
    # step within 0.001 px of the exact motion the centre is within 0.001 px: small beside a
    # bright streak's across-track noise (~0.004 px), which 0.01 px steps were not.
    rng = np.random.default_rng(5)
    det = st16.detector
    x, y = rng.uniform(0, det.columns, 200), rng.uniform(0, det.rows, 200)
    v = st16.unproject(x, y)
    for w in (np.array([8.0, 0.0, 0.0]) * DEG, np.array([4.0, 5.0, 3.0]) * DEG):
        tr = star_tracks(st16, v, rate_rad_s=w)
        tau = ((np.arange(20000) + 0.5) / 20000 - 0.5) * st16.exposure_s
        rot = Rotation.from_rotvec(-tau[:, None] * w[None, :]).as_matrix()
        px, py = st16.project(np.einsum("tij,nj->nti", rot, v))
        truth = np.stack([px.mean(axis=1), py.mean(axis=1)], axis=1)
        light = np.array([0.5 * (t[1:] + t[:-1]).mean(axis=0) for t in tr.vertices])
        assert np.hypot(*(light - truth).T).max() < 0.001


def test_tracks_validate_rate_and_exposure(st16) -> None:
    v = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(InputError, match="3 components"):
        star_tracks(st16, v, rate_rad_s=(0.1, 0.2))
    with pytest.raises(InputError, match="finite"):
        star_tracks(st16, v, rate_rad_s=(0.1, float("nan"), 0.0))
    with pytest.raises(InputError, match="exposure_s"):
        star_tracks(st16, v, rate_rad_s=(0.0, 0.0, 0.0), exposure_s=-0.1)
    with pytest.raises(InputError, match="method"):
        polyline_expected([0.0], [0.0], sigma_px=1.0, electrons=1.0, method="simpson")
