"""A smeared star's pair holds only where its capsule lies on the star's streak."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from zoo_trials import zoo_sensor, zoo_trial

from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.rematch import MATCH_SIGMAS
from starsense.solve.streak_pairs import across_excess
from starsense.solve.streaks import (
    CAPSULE_PAD_PX,
    CAPSULE_SIGMAS,
    StreakCentroids,
    streak_centroids_of,
)
from starsense.units import ARCSEC


def _design(i: int):
    return zoo_sensor(i)


def test_the_limit_across_is_the_capsule_radius_and_four_sigma():
    sensor = _design(0)
    sigma_psf = float(sensor.detector.psf_sigma_px)
    radius = CAPSULE_SIGMAS * sigma_psf + CAPSULE_PAD_PX
    across_sigma = 0.05  # px, the centroid's own across the streak
    limit = radius + MATCH_SIGMAS * across_sigma
    # stars at (300, 200), streaks along x (40 px): centroids 15 px along and, across, just
    # inside and just outside the limit, and one 12 px off; the identity attitude
    x0, y0 = 300.0, 200.0
    ref = sensor.unproject(np.full(4, x0), np.full(4, y0))
    cx = np.full(4, x0 + 15.0)
    cy = y0 + np.array([0.0, limit - 1e-3, limit + 1e-3, 12.0])
    cov = np.zeros((4, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = 4.0, across_sigma**2
    streaks = StreakCentroids(cx, cy, cov, np.tile([40.0, 0.0], (4, 1)))
    got = across_excess(sensor, streaks, ref, rotation=Rotation.identity())
    assert np.all(got[:2] < 0.0) and np.all(got[2:] > 0.0)
    assert got[3] == pytest.approx(12.0 - limit, abs=1e-6)


def test_a_star_without_a_streak_is_never_off_it():
    sensor = _design(0)
    ref = sensor.unproject(np.array([100.0]), np.array([100.0]))
    streaks = StreakCentroids(
        np.array([150.0]), np.array([150.0]), np.eye(2)[None], np.zeros((1, 2))
    )
    assert across_excess(sensor, streaks, ref, rotation=Rotation.identity())[0] == -np.inf


def test_noise_beside_a_faint_streak_is_not_its_star():
    """Trial 56 of a 550-frame Monte Carlo of a 5 deg, 8-bit design (3344 x 2512 px, 635 px
    streaks) at 1 deg/s: nine faint stars (4,500 e- over 635 px) were paired with detections
    13-22 px across their streaks, noise or other stars' pieces, within a verification radius
    as wide as the streaks are long. Every pair the solution keeps now lies on its star's
    streak: its detection within the capsule's radius across the streak's line under the true
    attitude."""
    sensor, solver, truth, frame = zoo_trial(26, seed=23, n_trials=550, trial=56, rate_deg_s=1.0)
    sol = solver(frame.image)
    assert sol.solved
    err = small_rotation_angles(truth, sol.rotation)
    assert np.hypot(err[0], err[1]) < 60.0 * ARCSEC
    det, cat = np.array(sol.matches).T
    ref = solver.catalog.vectors[solver.catalog.index_of(cat)]
    x, y = sensor.project(truth.apply(ref))
    found = solver.detector(frame.image)  # the matched detections' capsule centroids
    box = found.bbox[det]
    got = streak_centroids_of(
        sensor,
        frame.image,
        np.column_stack([found.x[det], found.y[det]]),
        counts=found.integrated_counts[det],
        extent_px=np.maximum(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]),
        level=float(sensor.detector.bias_counts),
        threshold=sensor.detection.lit_pixel_counts,
    )
    seg = got.streaks_px / np.hypot(*got.streaks_px.T)[:, None]
    across = (got.x - x) * -seg[:, 1] + (got.y - y) * seg[:, 0]
    radius = CAPSULE_SIGMAS * float(sensor.detector.psf_sigma_px) + CAPSULE_PAD_PX
    assert np.all(np.abs(across) <= radius), np.round(across, 2)
