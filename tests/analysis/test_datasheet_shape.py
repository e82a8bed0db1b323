"""A PSF that is not round: the datasheet's sums with each star's 2 x 2 position information.

A lens with astigmatism or coma images a star as an ellipse, located better across its long axis
than along it: each star's information is ``w (I + D)``, ``D = [[a, c], [c, -a]]``, and the
attitude axes that move stars along the long axis are the less certain. The sums are checked
against a star's move under small rotations (scipy's), in its tangent plane, and the
prediction against the full 2 x 2 information of every star (the forward model's Fisher,
:func:`starsense.model.fisher.position_information`, summed through the projection).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from elongated_psf import elongated
from scipy.spatial.transform import Rotation

from starsense.analysis.availability.pointings import sky_attitudes
from starsense.analysis.datasheet.field import (
    FieldStarsCam,
    axis_sigmas,
    field_stars_cam,
    fisher_per_pointing,
    sandwich_terms,
)
from starsense.analysis.datasheet.predict import StarModel, nea_at
from starsense.catalog import load_catalog
from starsense.model.fisher import attitude_information, position_information
from starsense.sensor import load_sensor


def _pairs(rng, n=40, half_deg=8.0):
    """One pointing's stars: camera directions within ``half_deg`` of the boresight."""
    xy = np.tan(np.radians(rng.uniform(-half_deg, half_deg, (n, 2))))
    v = np.column_stack([xy, np.ones(n)])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return FieldStarsCam(np.zeros(n, dtype=int), np.arange(n), v, n_pointings=1)


def _tangent_moves_fd(v, h=1e-6):
    """A rotation's move of each star in its tangent plane, along the pixel axes seen there.

    ``(R(theta) v - R(-theta) v) / (2 h)`` by scipy's rotations, on ``e1`` (the camera x axis
    made normal to the star) and ``e2 = v x e1`` (2 x 3 per star).
    """
    e1 = np.zeros_like(v)
    e1[:, 0] = 1.0
    e1 -= v[:, :1] * v
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(v, e1)
    out = np.zeros((len(v), 2, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        move = (Rotation.from_rotvec(step).apply(v) - Rotation.from_rotvec(-step).apply(v)) / (
            2 * h
        )
        out[:, 0, k] = np.sum(move * e1, axis=1)
        out[:, 1, k] = np.sum(move * e2, axis=1)
    return out


def _d(a, c):
    d = np.empty((len(a), 2, 2))
    d[:, 0, 0], d[:, 1, 1], d[:, 0, 1], d[:, 1, 0] = a, -a, c, c
    return d


def test_shape_adds_the_anisotropic_information_of_each_stars_move():
    rng = np.random.default_rng(5)
    pairs = _pairs(rng)
    w = rng.uniform(0.5, 2.0, 40) * 1e10
    a, c = rng.uniform(-0.4, 0.4, 40), rng.uniform(-0.4, 0.4, 40)
    added = fisher_per_pointing(pairs, w, (a, c)) - fisher_per_pointing(pairs, w)
    j = _tangent_moves_fd(pairs.v_cam)
    want = np.einsum("p,pai,pab,pbj->ij", w, j, _d(a, c), j)
    # central differences at h = 1e-6 rad: ~1e-10 relative, far below the 1e-6 asked
    np.testing.assert_allclose(added[0], want, rtol=1e-6, atol=1e-6 * np.abs(want).max())


def test_a_round_error_through_elongated_weights():
    # G = sum w^2 e^2 J^T (I + D)^2 J: its round part is eq. 21's at w^2 e^2 (1 + a^2 + c^2)
    rng = np.random.default_rng(6)
    pairs = _pairs(rng)
    w, e2 = rng.uniform(0.5, 2.0, 40) * 1e10, rng.uniform(0.5, 2.0, 40) * 1e-11
    a, c = rng.uniform(-0.4, 0.4, 40), rng.uniform(-0.4, 0.4, 40)
    _, g = sandwich_terms(pairs, w, np.sqrt(e2), shape=(a, c))
    k = 1.0 + a * a + c * c
    round_part = fisher_per_pointing(pairs, w * w * e2 * k)
    j = _tangent_moves_fd(pairs.v_cam)
    want = np.einsum("p,pai,pab,pbj->ij", w * w * e2, j, 2.0 * _d(a, c), j)
    np.testing.assert_allclose(
        g[0] - round_part[0], want, rtol=1e-6, atol=1e-6 * np.abs(want).max()
    )
    # the noise of the fit that weighs (its covariance the inverse of its information): G = F
    f, g = sandwich_terms(pairs, w, 1.0 / np.sqrt(w), shape=(a, c), efficient=True)
    np.testing.assert_array_equal(f, g)


def test_prediction_of_an_elongated_psf_is_each_stars_full_information():
    """nea_at with the table's shape against J^T I J summed with each star's own 2 x 2."""
    sensor = elongated(load_sensor("st16"), 1.6, 0.9, np.radians(30.0))
    cat = load_catalog("hipparcos")
    v_mag = np.asarray(cat.mags["V"])
    keep = np.isfinite(v_mag) & (v_mag < 5.5)
    vec, mag = np.asarray(cat.vectors)[keep], v_mag[keep]
    mats = sky_attitudes(40, None, 3)[1].as_matrix()
    model = StarModel.build(sensor, model="reed", bright_mag=float(mag.min()), faint_mag=5.5)
    assert model.shape is not None  # an elongated PSF is not round
    cross, roll = nea_at(model, sensor.fov(), mats, vectors=vec, magnitudes=mag)[0]["nea"]
    pairs = field_stars_cam(sensor.fov(), mats, vec)
    log_e = np.round(np.log(model.sensitivity.electrons(mag[pairs.star])), 2)  # 1 % in e
    grid, at = np.unique(log_e, return_inverse=True)
    info = position_information(sensor, np.exp(grid), n_phase=4)[at]
    fisher = np.zeros((len(mats), 3, 3))
    np.add.at(fisher, pairs.point, attitude_information(sensor, pairs.v_cam, info))
    c_full, r_full = axis_sigmas(fisher)
    # 2 %: eq. 21's (I - r r^T) for the round part against the projection's J^T J (off-axis
    # stars of a 15 deg field: < 1 %), the table's interpolation on electrons, the 1 % rounding
    assert np.nanmedian(cross / c_full) == pytest.approx(1.0, abs=0.02)
    assert np.nanmedian(roll / r_full) == pytest.approx(1.0, abs=0.02)
    # the round model's mean information (what the prediction used) is off by more than 5 %
    round_model = dataclasses.replace(model, shape=None)
    c0 = nea_at(round_model, sensor.fov(), mats, vectors=vec, magnitudes=mag)[0]["nea"][0]
    assert np.nanmedian(c0 / c_full) < 0.95, np.nanmedian(c0 / c_full)
