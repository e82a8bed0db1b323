"""A close companion of a fitted star: drawn where the sky puts it, not merged into the star."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.catalog.table import Catalog
from starsense.geometry.attitude import small_rotation_angles
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.identifiers import SkyStars
from starsense.solve.refine import refine_attitude


def _scene(sensor, rng):
    """Twelve stars over the field, the first with a companion 0.25 px east, 1 mag fainter."""
    det = sensor.detector
    x = np.r_[det.columns / 2 + 180.0, rng.uniform(60, det.columns - 60, 11)]
    y = np.r_[det.rows / 2 - 120.0, rng.uniform(60, det.rows - 60, 11)]
    x, y = np.r_[x, x[0] + 0.25], np.r_[y, y[0]]
    v = sensor.unproject(x, y)  # camera = ICRS at the identity attitude
    mags = np.r_[2.5, rng.uniform(4.0, 6.0, 11), 3.5]
    cat = Catalog.from_columns(
        name="pair", source="test", epoch_yr=2016.0, ids=np.arange(13),
        ra_deg=np.degrees(np.arctan2(v[:, 1], v[:, 0])) % 360.0,
        dec_deg=np.degrees(np.arcsin(v[:, 2])), mags={"V": mags},
        colours={"B-V": np.full(13, 0.6)},
    )  # fmt: skip
    return cat, v, mags


def test_a_companion_the_detection_does_not_split_does_not_pull_the_attitude():
    """The attitude is unbiased beside a double 0.25 px apart (flux ratio 0.4).

    The identified twelve include the double's brighter star; the companion is in the sky
    only. Merged into its star, its light would move that star's fitted position by about
    f d / (1 + f) = 0.07 px (f = 0.4, d = 0.25 px), many times the position's sigma at this
    brightness (V 2.5 at rest), the same way in every frame: measured, 2.2-2.8 sigmas of the
    attitude's on one axis in each of the 8 frames. Drawn where it is, at the catalogue's flux
    ratio, the error over 8 frames (each in units of its reported sigma) averages within
    3 / sqrt(8) of zero on every axis (a 3-sigma bound on the mean of 8 unit normals; by chance
    it fails with probability ~1 % over the three axes).
    """
    sensor = load_sensor("esa_blackfly")
    cat, v, mags = _scene(sensor, np.random.default_rng(4))
    sky = SkyStars(v, mags, cKDTree(v), np.arange(13), cat)
    truth = Rotation.identity()
    start = Rotation.from_rotvec([2e-5, -1e-5, 4e-5])  # a centroid solution's few arcsec
    pulls = []
    for seed in range(8):
        frame = render_frame(sensor, truth, cat, rng=seed)
        done = refine_attitude(
            frame.image, sensor, start, ref=v[:12], plain=v[:12], mags=mags[:12], sky=sky,
            cog_sigma_rad=np.full(3, 5e-5),
        )  # fmt: skip
        assert done.used, done.note
        err = small_rotation_angles(done.fit.rotation, truth)
        pulls.append(err / np.sqrt(np.diag(done.fit.covariance)[:3]))
    assert np.all(np.abs(np.mean(pulls, axis=0)) < 3.0 / np.sqrt(8.0)), np.mean(pulls, axis=0)
