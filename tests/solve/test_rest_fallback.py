"""A frame whose streaks' rate draws more than a fit may hold is fitted at rest.

In a crowded field at rest the brightest stars' lit discs touch their neighbours' and can
measure as streaks; at the rate they give, the stars' and neighbours' tracks pass the model
fit's work, and the frame kept the centroids' attitude (sigmas several times larger). Fitted
at rest with that rate as the hint, the likelihood says whether the frame moved.
"""

from __future__ import annotations

import numpy as np
import pytest
from field_stars import catalog_of
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
