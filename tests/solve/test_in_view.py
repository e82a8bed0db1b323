"""The model fit's stars: every catalogue star the model predicts above the noise, detected or
not, each at its own apparent place; the datasheet counts the same stars; and the centroids'
attitude as sure as its residuals allow."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.attitude.robust import residual_scaled, robust_attitude
from starsense.catalog import load_catalog
from starsense.geometry.attitude import attitude_from_radec_roll, small_rotation_angles
from starsense.geometry.sampling import random_attitudes
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve import Solver
from starsense.solve import neighbours as neighbours_module
from starsense.solve import refine as refine_module
from starsense.solve.in_view import IN_VIEW_PIXELS, room_for


@pytest.fixture(scope="module")
def st16_frame():
    sensor = load_sensor("st16")
    att = attitude_from_radec_roll(1.2, 0.4, 0.3)  # a field of the Milky Way's edge
    return sensor, render_frame(sensor, att, load_catalog("hipparcos"), rng=11)


def test_the_stars_added_to_the_fit_are_rendered_stars(st16_frame, monkeypatch):
    """Each star the fit adds is a star the frame holds, near where the renderer put it, and
    the fit holds stars the detector did not find: the model chooses them."""
    sensor, frame = st16_frame
    seen = {}

    def spy(*args, **kwargs):
        got = original(*args, **kwargs)
        seen["added"] = got
        return got

    original = refine_module.stars_in_view
    monkeypatch.setattr(refine_module, "stars_in_view", spy)
    sol = Solver(sensor, background="known")(frame.image)
    assert sol.solved and sol.notes[0].startswith("model fit")
    _, ref, mags = seen["added"]
    assert len(mags) > 0  # the identification pairs only its brightest detections
    truth = frame.truth.stars
    x, y = sensor.project(frame.truth.attitude.apply(ref))
    # each added star within 0.05 px of a rendered star's mid-exposure place (the catalogue
    # places the renderer drew: the same stars, no frame time, so no apparent-place shift)
    d = np.hypot(x[:, None] - truth.x_mid[None, :], y[:, None] - truth.y_mid[None, :])
    assert np.all(d.min(axis=1) < 0.05), d.min(axis=1)
    matched = {c for _, c in sol.matches}
    nearest = truth.ids[np.argmin(d, axis=1)]
    assert not matched & set(nearest.tolist())  # never an identified star twice
    # more stars than the detector found: the fit's stars do not depend on the extraction
    assert len(mags) + sol.n_matched > sol.n_detections


def test_stars_in_view_past_the_fits_work_are_halved_not_dropped(st16_frame, monkeypatch):
    """Where the fit with every star in view passes a fit's work (long streaks crossing a
    crowded field), the brightest half of them is fitted, and again, rather than none.

    The work budget is simulated: any fit of more than the identified stars and a third of
    those in view is refused as make_windows refuses one (InputError)."""
    from starsense.errors import InputError

    sensor, frame = st16_frame
    seen = {}
    in_view, fit_windows = refine_module.stars_in_view, neighbours_module.fit_windows

    def added(*args, **kwargs):
        seen["added"] = got = in_view(*args, **kwargs)
        return got

    def budget(image, sensor_, rotation, *, vectors, **kwargs):
        seen.setdefault("sizes", []).append(len(vectors))
        if "added" in seen and len(vectors) > seen.get("limit", np.inf):
            raise InputError("the stars' tracks cover more pixel-nodes than a fit may evaluate")
        return fit_windows(image, sensor_, rotation, vectors=vectors, **kwargs)

    monkeypatch.setattr(refine_module, "stars_in_view", added)
    monkeypatch.setattr(neighbours_module, "fit_windows", budget)
    whole = Solver(sensor, background="known")(frame.image)
    n_view = len(seen["added"][2])
    n_id = whole.n_matched
    seen.clear()
    seen["limit"] = n_id + n_view // 3
    sol = Solver(sensor, background="known")(frame.image)
    assert sol.solved and sol.notes[0].startswith("model fit")
    kept = n_view // 4  # halved twice: n, n // 2 (refused), n // 4 (within a third)
    assert f"the {kept} brightest of the {n_view} other stars in view" in sol.notes[0]
    assert seen["sizes"][-1] == n_id + kept  # the last fit: the identified and the brightest
    # the stars fitted: more than the identified ones, as the note's counts say
    assert f"{n_id + kept} stars" in sol.notes[0]


def test_the_datasheet_counts_the_stars_the_solver_fits(st16_frame, monkeypatch):
    """The solver's fitted stars (the identified ones and those it adds) and the datasheet's
    (:meth:`FittedStars.presence` at rest) in the frame's true attitude are the same stars but
    for those near the floor: the frame's zero point is measured from its stars (a few per
    cent), the datasheet's predicted, so a star within a tenth of a magnitude of the floor may
    fall either side."""
    from starsense.analysis.datasheet.field import field_stars_cam
    from starsense.analysis.datasheet.stars import fitted_stars
    from starsense.analysis.slew import slew_tolerance
    from starsense.model.selection import fitted_min_electrons
    from starsense.photometry.sensitivity import Sensitivity

    sensor, frame = st16_frame
    seen = {}

    def spy(*args, **kwargs):
        seen["added"] = original(*args, **kwargs)
        return seen["added"]

    original = refine_module.stars_in_view
    monkeypatch.setattr(refine_module, "stars_in_view", spy)
    sol = Solver(sensor, background="known")(frame.image)
    assert sol.solved and sol.notes[0].startswith("model fit")
    solver_n = sol.n_matched + len(seen["added"][2])
    slew = slew_tolerance(sensor, magnitudes=[4.0, 6.0], rates_rad_s=[0.0], n_trials=4, rng=1)
    stars = fitted_stars(load_catalog("hipparcos"), sensor, slew=slew, limit_mag=6.0)
    v, mags, _, _ = stars.at(0.0)
    pairs = field_stars_cam(sensor.fov(), frame.truth.attitude.as_matrix()[None], v)
    predicted = mags[pairs.star]
    floor = fitted_min_electrons(sensor)
    zero = float(Sensitivity.for_sensor(sensor).electrons(0.0))
    near = np.abs(predicted - 2.5 * np.log10(zero / floor)) < 0.1
    assert len(predicted) > 20
    assert abs(solver_n - len(predicted)) <= max(2, int(near.sum())), (solver_n, len(predicted))


def test_the_fit_is_bounded_on_long_streaks():
    """At rest a star's window is a few PSF widths; a streak's grows with its length, and the
    stars added shrink to keep the windows within the budget."""
    sensor = load_sensor("st16")
    half = 4.0
    at_rest = room_for(sensor, 0, half_px=half)
    assert at_rest == int(IN_VIEW_PIXELS / (2 * half + 1) ** 2)
    rate = np.array([0.0, np.radians(3.0), 0.0])  # 3 deg/s across the columns
    streak = sensor.focal_length_px * sensor.exposure_s * rate[1]
    fast = room_for(sensor, 10, half_px=half, rate_rad_s=rate)
    assert fast == int(IN_VIEW_PIXELS / ((2 * half + 1 + streak) * (2 * half + 1))) - 10
    assert fast < at_rest


@pytest.mark.parametrize("inflation", [1.0, 3.0])
def test_residual_scaled_sigma_matches_the_scatter_of_the_attitude(inflation):
    """Stars whose real noise is ``inflation`` times their stated sigma: the scaled covariance
    is the attitude's real scatter (a Monte Carlo of 400 fits). Below the stated one only where
    the residuals' chi-square falls under its 5 % quantile: in ~5 % of right fits (at most 8 %
    of 400, 3 binomial sd above), never when the stars scatter three times their sigma."""
    rng = np.random.default_rng(7)
    truth = random_attitudes(1, rng)[0]
    stated = 1e-5  # rad, per axis
    n, trials = 12, 400
    cam = rng.normal(size=(n, 3)) * [0.1, 0.1, 0.0] + [0.0, 0.0, 1.0]
    cam /= np.linalg.norm(cam, axis=1)[:, None]
    ref = truth.inv().apply(cam)
    errors, sigmas, raw = [], [], []
    for _ in range(trials):
        noisy = cam + rng.normal(scale=inflation * stated, size=cam.shape)
        noisy /= np.linalg.norm(noisy, axis=1)[:, None]
        att, _ = robust_attitude(noisy, ref, np.full(n, stated), max_drop=0)
        scaled = residual_scaled(att)
        errors.append(small_rotation_angles(truth, scaled.rotation))
        sigmas.append(scaled.sigma_axes_rad)
        raw.append(att.sigma_axes_rad)
    e, s, r = np.array(errors), np.array(sigmas), np.array(raw)
    lowered = np.any(s < r * (1 - 1e-12), axis=1)
    assert np.mean(lowered) <= (0.08 if inflation == 1.0 else 0.0)
    ratio = np.sqrt(np.mean(e**2, axis=0) / np.mean(s**2, axis=0))
    # 400 fits know an rms to ~3.5 % (1 / sqrt(2 x 400)); the Birge ratio of 21 degrees of
    # freedom scatters by ~30 % per fit, and max(1, .) lifts the right model's sigma by ~10 %:
    # the rms over fits lies within 0.8-1.25 of the truth either way
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def test_a_sky_without_the_databases_band_keeps_its_stars():
    """Hipparcos (V, no G) as the sky of a Gaia database (band G): every star with a V is in
    the model fit's sky, at G from its V and B - V; none is left out for lacking G (a narrow
    field's bright neighbours and stars in view would be missing from the model)."""
    from starsense.photometry.colour import magnitudes_in

    hip = load_catalog("hipparcos")
    assert "G" not in hip.mags or not np.isfinite(hip.mags["G"]).all()
    sky = Solver(load_sensor("st16"), sky=hip).sky_stars("G")
    with_v = np.isfinite(np.asarray(hip.mags["V"], float))
    assert len(sky.mags) == int(with_v.sum())
    np.testing.assert_allclose(sky.mags, magnitudes_in(hip, "G")[with_v])
    # G - V of Evans et al. 2018's cubic: -0.03 at B - V = -0.05 falling to -1.55 at 2.5
    gv = sky.mags - np.asarray(hip.mags["V"], float)[with_v]
    assert gv.min() > -1.56 and gv.max() < -0.02
