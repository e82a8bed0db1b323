"""Helpers of the identification tests: a synthetic sensor and synthetic frames."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.sensor import Sensor, load_sensor

SYNTH_FOV_RAD = math.radians(15.0)
"""Horizontal field of the synthetic sensor (the ESA camera with a shorter lens)."""


def sensor_with_fov(fov_rad: float) -> Sensor:
    """The ESA Blackfly detector behind a pinhole lens giving `fov_rad` across its width."""
    base = load_sensor("esa_blackfly")
    width_m = base.detector.columns * base.detector.pixel_pitch_m
    focal = width_m / 2.0 / math.tan(fov_rad / 2.0)
    return base.with_(optics=dataclasses.replace(base.optics, focal_length_m=focal))


def synthetic_frame(
    catalog,
    sensor: Sensor,
    rotation: Rotation,
    rng: np.random.Generator,
    *,
    n_stars: int = 20,
    noise_px: float = 0.3,
    n_false: int = 2,
    mag_limit: float = 9.0,
):
    """Detections of the `n_stars` brightest catalogue stars in the field, brightest first,
    with Gaussian centroid noise and `n_false` false stars at random places and ranks.

    Returns (vectors_cam (N, 3), true HIP id per detection (-1 for false stars)).
    """
    mags = catalog.mags["V"]
    ok = np.flatnonzero(np.isfinite(mags) & (mags <= mag_limit))
    ok = ok[np.argsort(mags[ok], kind="stable")]
    cam = rotation.apply(catalog.vectors[ok])
    x, y = sensor.project(cam)
    cols, rows = sensor.detector.columns, sensor.detector.rows
    inside = (cam[:, 2] > 0) & (x >= 0) & (x <= cols - 1) & (y >= 0) & (y <= rows - 1)
    idx = np.flatnonzero(inside)[:n_stars]
    xs = x[idx] + rng.normal(0.0, noise_px, len(idx))
    ys = y[idx] + rng.normal(0.0, noise_px, len(idx))
    ids = np.asarray(catalog.ids)[ok[idx]].astype(np.int64)
    for _ in range(n_false):
        pos = int(rng.integers(0, len(xs) + 1))
        xs = np.insert(xs, pos, rng.uniform(0, cols - 1))
        ys = np.insert(ys, pos, rng.uniform(0, rows - 1))
        ids = np.insert(ids, pos, -1)
    return sensor.unproject(xs, ys), ids
