"""Which attitudes' streaks the model fit can hold: the prediction asks the fit's own rule.

:func:`starsense.analysis.datasheet.model_noise.fit_holds_at_rate` lays the tracks of each
attitude's brightest stars out as the solver's first fit does and asks
:func:`starsense.model.boxes.window_capacity`, the rule :func:`starsense.model.windows.
make_windows` refuses by. Invariants checked here: the same geometry gets the same answer from
both, and a streak along a pixel axis costs a window the length of the streak while one along
the diagonal costs its square (the boxes' area), so that at one rate and length the first is
held and the second not.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from narrow_camera import narrow_camera
from scipy.spatial.transform import Rotation

from starsense.analysis.datasheet.field import field_stars_cam
from starsense.analysis.datasheet.model_noise import fit_holds_at_rate, streaks_px_of
from starsense.errors import InputError
from starsense.model.boxes import window_capacity
from starsense.model.psf import psf_of
from starsense.model.tracks import time_nodes
from starsense.model.windows import make_windows, window_half_px


def _stars(sensor, n, rng):
    det = sensor.detector
    x, y = rng.uniform(80, det.columns - 80, n), rng.uniform(80, det.rows - 80, n)
    return sensor.unproject(x, y), np.sort(rng.uniform(3.0, 7.0, n))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_prediction_and_the_fit_refuse_the_same_windows(seed):
    """For each attitude and rate, fit_holds_at_rate says False exactly where make_windows,
    given the same stars' tracks, raises (both ask one rule)."""
    sensor = narrow_camera()
    rng = np.random.default_rng(seed)
    v, mags = _stars(sensor, 16, rng)
    psf = psf_of(sensor)
    half = window_half_px(psf)
    det = sensor.detector
    for turn_deg in (0.2, 0.6, 1.0, 2.0):
        phi = rng.uniform(0, 2 * np.pi)
        rate = math.radians(turn_deg) * np.array([math.cos(phi), math.sin(phi), 0.0])
        held = fit_holds_at_rate(
            sensor,
            sensor.fov(),
            np.eye(3)[None],
            rates_rad_s=rate[None],
            vectors=v,
            magnitudes=mags,
            n_stars=[12],
        )[0]
        pairs = field_stars_cam(sensor.fov(), np.eye(3)[None], v)
        mine = pairs.star[np.argsort(mags[pairs.star], kind="stable")][:12]
        mids, streaks = streaks_px_of(sensor, v[mine], np.repeat(rate[None], len(mine), 0))
        frac, _ = time_nodes(float(np.max(np.hypot(*streaks.T))), psf.sigma_px)
        x = mids[:, 0, None] + frac[None, :] * streaks[:, 0, None]
        y = mids[:, 1, None] + frac[None, :] * streaks[:, 1, None]
        try:
            make_windows(x, y, half_px=half, shape=(det.rows, det.columns), free=np.ones(12, bool))
            refused = False
        except InputError:
            refused = True
        assert held == (not refused), (
            turn_deg,
            window_capacity(x, y, half_px=half, free=np.ones(12, bool)),
        )


def test_a_streak_along_an_axis_is_held_where_one_along_the_diagonal_is_not():
    """12 stars, 1 deg/s: streaks of ~410 px. Along a pixel axis each window is ~410 x 16 px
    (~80,000 px in all); along the diagonal ~300 x 300 px each (~1.1 million, past the
    1,000,000 a fit may hold)."""
    sensor = narrow_camera()
    v, mags = _stars(sensor, 12, np.random.default_rng(5))
    turn = math.radians(1.0)
    rates = np.array([[turn, 0.0, 0.0], [turn, turn, 0.0] / np.sqrt(2.0)])
    held = fit_holds_at_rate(
        sensor,
        sensor.fov(),
        np.repeat(np.eye(3)[None], 2, 0),
        rates_rad_s=rates,
        vectors=v,
        magnitudes=mags,
        n_stars=[12, 12],
    )
    assert held.tolist() == [True, False]
    # the same attitudes turned about the boresight by 45 deg swap the answers: the rule is the
    # pixel grid's, not the sky's
    turned = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    diagonal = fit_holds_at_rate(
        sensor,
        sensor.fov(),
        np.eye(3)[None],
        rates_rad_s=(turned @ rates[0])[None],
        vectors=v,
        magnitudes=mags,
        n_stars=[12],
    )
    assert not diagonal[0]
