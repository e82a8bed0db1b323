"""The fast prediction's evaluation: each shortcut gives what the long way gives.

* the slew run stopped at the rate where each magnitude is lost (``full_grid=False``) has the
  whole grid's tolerance, limit and ``m_t(w)`` bit for bit;
* the batched row-streak stamps are the renderer's streaks (within the renderer's quadrature
  error) and conserve flux;
* the field pairs and their camera vectors are those of the brute-force field test;
* the segment sums of the Fisher matrices equal the scattered sums;
* a trade over two worker processes gives the rows of one process.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.analysis.availability.field import field_pairs_cam, inside_camera
from starsense.analysis.datasheet.field import FieldStarsCam, fisher_per_pointing
from starsense.analysis.sensor_detection import sensor_detection
from starsense.analysis.slew import simulate_slew
from starsense.analysis.trade import (
    base_document,
    designs,
    parse_vary,
    prediction_settings,
    run_trade,
)
from starsense.geometry.fov import CircularFov, RectangularFov
from starsense.render.psf import Box
from starsense.render.smear import polyline_expected, row_streaks_expected
from starsense.sensor import load_sensor
from starsense.units import DEG


@pytest.fixture(scope="module")
def st16():
    return load_sensor("st16")


def test_slew_stopped_where_lost_equals_the_whole_grid(st16):
    mags = np.arange(4.0, 6.51, 0.25)
    rates = np.linspace(0.0, 6.0, 13) * DEG
    kw = {"magnitudes": mags, "rates_rad_s": rates, "n_trials": 8, "rng": 11}
    full = simulate_slew(st16, **kw)
    short = simulate_slew(st16, full_grid=False, **kw)
    assert short.tolerable_rate_rad_s == full.tolerable_rate_rad_s
    np.testing.assert_array_equal(short.capped, full.capped)
    ran = np.isfinite(short.detected_fraction)
    assert ran[:, 0].all() and not ran.all()  # every magnitude at rest, not every cell
    np.testing.assert_array_equal(short.detected_fraction[ran], full.detected_fraction[ran])
    # a cell is skipped only after its magnitude fell below the criterion at a slower rate
    for i, j in zip(*np.nonzero(~ran), strict=True):
        assert np.any(full.detected_fraction[i, :j] < 0.5)


def test_sensor_detection_stopped_where_lost_is_the_same(st16):
    small = st16.with_(detector=dataclasses.replace(st16.detector, columns=640, rows=480))
    a = sensor_detection(small, n_trials=6, rng=2)
    b = sensor_detection(small, n_trials=6, rng=2, full_grid=False)
    assert a.limit_mag == b.limit_mag
    assert a.slew.tolerable_rate_rad_s == b.slew.tolerable_rate_rad_s
    w = np.linspace(0.0, 10.0, 41) * DEG
    np.testing.assert_array_equal(a.curve(w), b.curve(w))


@pytest.mark.parametrize("sigma", [0.5, 1.0, 2.5])
@pytest.mark.parametrize("length", [0.0, 0.4, 7.0, 130.0])
def test_row_streaks_are_the_renderers_streaks(sigma, length):
    rng = np.random.default_rng(4)
    x0, y0 = rng.random(3), rng.random(3)
    stamps, row0, col0 = row_streaks_expected(x0, y0, length, sigma_px=sigma)
    box = Box(row0, row0 + stamps.shape[1], col0, col0 + stamps.shape[2])
    for k in range(3):
        ref, _ = polyline_expected(
            [x0[k], x0[k] + length], [y0[k], y0[k]], sigma_px=sigma, electrons=1.0, box=box,
            pad_sigma=12.0,
        )  # fmt: skip
        # the "track" quadrature's documented error: < 6e-9 of the flux summed over pixels
        assert np.abs(stamps[k] - ref).sum() < 6e-9
    assert stamps.min() >= 0.0
    # flux conservation: the box holds all but the Gaussian tails beyond 5 sigma
    # (at most 4 P(X > 5 sigma) = 1.2e-6 of the flux)
    wide, _, _ = row_streaks_expected(x0, y0, length, sigma_px=sigma, pad_sigma=10.0)
    np.testing.assert_allclose(wide.sum(axis=(1, 2)), 1.0, atol=1e-12)
    assert np.all(1.0 - stamps.sum(axis=(1, 2)) < 1.2e-6)


@pytest.mark.parametrize(
    "fov",
    [
        RectangularFov(8.0 * DEG, 6.0 * DEG),
        RectangularFov(30.0 * DEG, 3.0 * DEG),
        CircularFov(10.0 * DEG),
    ],
    ids=["rect", "slit", "circle"],
)
def test_field_pairs_cam_equal_brute_force(fov):
    rng = np.random.default_rng(9)
    v = rng.normal(size=(4000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    mats = Rotation.random(150, random_state=3).as_matrix()
    point, star, v_cam = field_pairs_cam(fov, mats, v)
    assert np.all(np.diff(point) >= 0)  # grouped by pointing
    cam = np.einsum("mij,nj->mni", mats, v)  # every (pointing, star)
    inside = inside_camera(fov, cam)
    got = np.zeros_like(inside)
    got[point, star] = True
    np.testing.assert_array_equal(got, inside)
    assert len(point) == inside.sum()  # no pair twice
    np.testing.assert_allclose(v_cam, cam[point, star], atol=1e-15)


def test_fisher_segment_sums_equal_scattered_sums():
    rng = np.random.default_rng(1)
    n_pointings, n_pairs = 40, 900
    point = np.sort(rng.integers(0, n_pointings, n_pairs))
    point = point[point != 7]  # a pointing without stars
    v = rng.normal(size=(len(point), 3))
    v[:, 2] += 8.0
    v /= np.linalg.norm(v, axis=1)[:, None]
    w = rng.random(len(point))
    grouped = FieldStarsCam(point, point, v, n_pointings=n_pointings)
    perm = rng.permutation(len(point))
    shuffled = FieldStarsCam(point[perm], point[perm], v[perm], n_pointings=n_pointings)
    a = fisher_per_pointing(grouped, w)
    b = fisher_per_pointing(shuffled, w[perm])  # not grouped: the scattered sums
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)
    assert np.all(a[7] == 0.0)


@pytest.mark.slow
def test_trade_in_two_workers_gives_the_rows_of_one():
    base = base_document("st16")
    grid = [
        parse_vary("optics.focal_length_m=0.02,0.03"),
        parse_vary("exposure_s=0.05,0.2"),
    ]
    todo = designs(base, grid)
    st = prediction_settings(n_orientations=150, n_slew_trials=4)
    one = run_trade(todo, settings=st, workers=1)
    two = run_trade(todo, settings=st, workers=2)
    assert [r.to_dict() for r in one.rows] == [r.to_dict() for r in two.rows]
    assert not math.isnan(one.rows[0].rows["nea_cross"]["value"])
