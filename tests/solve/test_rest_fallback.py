"""A frame whose streaks' rate draws more than a fit may hold is fitted at rest, if it is at rest.

In a crowded field at rest the brightest stars' lit discs touch their neighbours' and can
measure as streaks; at the rate they give, the stars' and neighbours' tracks pass the model
fit's work, and the frame kept the centroids' attitude (sigmas several times larger). Fitted
at rest with that rate as the hint, the likelihood says whether the frame moved.
"""

from __future__ import annotations

import numpy as np
import pytest
from field_stars import catalog_of
from narrow_camera import narrow_camera
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.geometry.attitude import small_rotation_angles
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.identifiers import SkyStars
from starsense.solve.refine import refine_attitude


def _sky(sensor, rng, n=12):
    det = sensor.detector
    x, y = rng.uniform(60, det.columns - 60, n), rng.uniform(60, det.rows - 60, n)
    v = sensor.unproject(x, y)  # camera = ICRS at the identity attitude
    mags = rng.uniform(3.0, 5.5, n)
    cat = catalog_of(v, mags)
    return cat, v, mags


@pytest.mark.parametrize("streak_px", [150.0, 5000.0])
def test_a_frame_at_rest_given_a_wrong_rate_is_fitted_at_rest(streak_px):
    """Fitted at a rate drawing 150 px streaks, the frame (at rest) rejects the model; at one
    drawing 5000 px streaks, the tracks pass a fit's work. Fitted at rest, the fit is used, and
    each of 3 frames lies within 4 of its sigmas on every axis (a right solution's error is
    Gaussian in its sigma; 4 sigma on any of 9 axis-frames is exceeded by chance in 0.06 %).
    Before, no fit was used."""
    sensor = load_sensor("esa_blackfly")
    cat, v, mags = _sky(sensor, np.random.default_rng(7))
    sky = SkyStars(v, mags, cKDTree(v), np.arange(len(v)), cat)
    truth = Rotation.identity()
    start = Rotation.from_rotvec([2e-5, -1e-5, 4e-5])  # a centroid solution's few arcsec
    # the rate across the boresight whose streaks are streak_px long
    rate = streak_px / (sensor.focal_length_px * sensor.exposure_s) * np.array([1.0, 0.0, 0.0])
    for seed in range(3):
        frame = render_frame(sensor, truth, cat, rng=seed)
        done = refine_attitude(
            frame.image, sensor, start, ref=v, plain=v, mags=mags, sky=sky,
            cog_sigma_rad=np.full(3, 5e-5), rate_rad_s=rate,
        )  # fmt: skip
        assert done.used, done.note
        assert "fitted at rest" in done.note
        np.testing.assert_array_equal(done.fit.rate_rad_s, 0.0)  # the pixels say: at rest
        z = small_rotation_angles(done.fit.rotation, truth) / done.fit.sigma_axes_rad
        assert np.all(np.abs(z) < 4.0), z


def test_real_streaks_too_long_for_a_fit_are_not_fitted_at_rest():
    """Streaks of 400 px across the diagonal: at their rate the stars' windows pass what a fit
    may hold. Fitted at rest, windows cut a stretch of each streak and the pixels are far from
    the model (reduced chi-square over 100), yet where the clipped pixels (left out of the
    sums) leave a misfit symmetric about the stars it need not pull the attitude: such a fit
    was used, 7-8 of its sigmas off (one frame of these six). The refusal stands for all six:
    the likelihood says the frame is not at rest, and the centroids' attitude is kept."""
    sensor = narrow_camera(bit_depth=8)
    det = sensor.detector
    truth = Rotation.identity()
    start = Rotation.from_rotvec([2e-5, -1e-5, 4e-5])
    turn = 400.0 / (sensor.focal_length_px * sensor.exposure_s)  # rad/s: 400 px streaks
    rate = turn * np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    for seed in range(6):
        rng = np.random.default_rng(11 + seed)
        x, y = rng.uniform(60, det.columns - 60, 14), rng.uniform(60, det.rows - 60, 14)
        v = sensor.unproject(x, y)  # camera = ICRS at the identity attitude
        mags = rng.uniform(4.0, 7.0, 14)
        cat = catalog_of(v, mags)
        sky = SkyStars(v, mags, cKDTree(v), np.arange(len(v)), cat)
        frame = render_frame(sensor, truth, cat, rate_rad_s=rate, rng=seed)
        done = refine_attitude(
            frame.image,
            sensor,
            start,
            ref=v,
            plain=v,
            mags=mags,
            sky=sky,
            cog_sigma_rad=np.full(3, 5e-5),
            rate_rad_s=rate,
        )
        assert not done.used, (seed, done.note)
        assert "a fit may hold" in done.note
