"""The fit with the catalogue's neighbours is repeated at its own zero point only when it converged.

A fit whose fluxes move the frame's zero point (a lit sum misses a PSF's wings) draws the
neighbours again and is repeated; a fit the model stopped (it does not place the stars: a
camera whose gain is not the sensor's) measured no flux, and is not repeated.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from field_stars import catalog_of
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import starsense.solve.neighbours as neighbours
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.identifiers import SkyStars
from starsense.solve.refine import refine_attitude


def _field(sensor, rng, n=14):
    """Stars spread over the frame, some close pairs (neighbours), camera = ICRS."""
    det = sensor.detector
    x, y = rng.uniform(60, det.columns - 60, n), rng.uniform(60, det.rows - 60, n)
    x[n // 2 :], y[n // 2 :] = x[: n - n // 2] + 6.0, y[: n - n // 2] + 4.0  # a companion each
    v = sensor.unproject(x, y)
    mags = rng.uniform(3.0, 5.5, n)
    mags[n // 2 :] += 1.5  # the companions fainter: drawn as neighbours, not fitted
    cat = catalog_of(v, mags)
    return cat, v, mags


def _fits(monkeypatch):
    """Record every fit the neighbours' module makes (converged or not)."""
    made = []
    real = neighbours.fit_windows

    def spy(*args, **kwargs):
        fit = real(*args, **kwargs)
        made.append(fit)
        return fit

    monkeypatch.setattr(neighbours, "fit_windows", spy)
    return made


def _light(frame, n):
    """The first ``n`` stars' electrons as the frame was drawn with (its truth)."""
    stars = frame.truth.stars
    by_id = dict(zip(stars.ids.tolist(), stars.electrons.tolist(), strict=True))
    return np.array([by_id[i] for i in range(n)])


def _refine(frame, sensor, v, mags, sky, electrons):
    half = len(v) // 2
    return refine_attitude(
        frame.image, sensor, Rotation.from_rotvec([2e-5, -1e-5, 3e-5]), ref=v[:half],
        plain=v[:half], mags=mags[:half], sky=sky, cog_sigma_rad=np.full(3, 5e-5),
        electrons=electrons,
    )  # fmt: skip


def test_a_fit_that_converged_is_repeated_where_its_zero_point_moved(monkeypatch):
    # the detections' sums given at half the light: the zero point the fit measures is twice
    # theirs (far past the 5 % that repeats it); the model is the frame's own, so it converges
    sensor = load_sensor("esa_blackfly")
    cat, v, mags = _field(sensor, np.random.default_rng(11))
    sky = SkyStars(v, mags, cKDTree(v), np.arange(len(v)), cat)
    frame = render_frame(sensor, Rotation.identity(), cat, rng=3)
    made = _fits(monkeypatch)
    done = _refine(frame, sensor, v, mags, sky, electrons=0.5 * _light(frame, len(v) // 2))
    assert done.used, done.note
    assert len(made) == 2 and made[0].converged  # repeated at the zero point it measured


def test_a_fit_the_model_stopped_is_not_repeated(monkeypatch):
    # drawn by a camera of 6 times the sensor's gain (the esa_blackfly preset assumes 1
    # count/e; its real camera measures ~6): the pixels' chi-square is tens of times the
    # model's, the fit stops after its first step; its fluxes, 6 times the light, would move
    # the zero point, but they measure nothing: one fit, not used
    sensor = load_sensor("esa_blackfly")
    det = sensor.detector
    camera = sensor.with_(
        detector=dataclasses.replace(det, gain_counts_per_e=6.0 * det.gain_counts_per_e)
    )
    cat, v, mags = _field(sensor, np.random.default_rng(12))
    sky = SkyStars(v, mags, cKDTree(v), np.arange(len(v)), cat)
    frame = render_frame(camera, Rotation.identity(), cat, rng=4)
    made = _fits(monkeypatch)
    done = _refine(frame, sensor, v, mags, sky, electrons=_light(frame, len(v) // 2))
    assert not made[0].converged and len(made) == 1
    assert not done.used
