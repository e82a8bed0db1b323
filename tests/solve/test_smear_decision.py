"""A frame is smeared when the streaks its fitted rate draws are long, not its lit pixels."""

from __future__ import annotations

import numpy as np
import pytest
from elongated_psf import elongated
from zoo_trials import zoo, zoo_trial

from starsense.geometry.attitude import small_rotation_angles
from starsense.geometry.sampling import random_attitudes
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve import Solver
from starsense.solve.streaks import (
    MIN_STREAK_SIGMAS,
    ShortStreaks,
    StreakCentroids,
    streak_centroids_of,
)
from starsense.units import DEG


def test_faint_streaks_measuring_short_are_still_recentroided():
    """Trial 27 of a 3667-frame Monte Carlo of a 25.6 deg design (864 x 640 px, PSF sigma
    1.93 px, 0.31 s) at 1 deg/s: its streaks are ~8.5 px, past the 7.9 px (2 PSF sigmas plus
    the 2 px margins) from which the solver centroids over the streaks, but its nine stars are
    faint (V <= 3.6) and their lit pixels measured short of it: the frame kept the detector's
    boxes and the attitude was off by 6.1, 4.6 and 7.4 of its own sigma. Decided on the
    streaks its fitted rate draws, it is centroided over the streaks, and the attitude lies
    within 3 of its sigma on every axis (a right solution's error is Gaussian in its sigma:
    3 sigma on any of three axes is exceeded by chance in 0.8 % of frames)."""
    sensor, solver, truth, frame = zoo_trial(
        35, seed=23, n_trials=3667, trial=27, rate_deg_s=1.0, model="reed"
    )
    sol = solver(frame.image)
    assert sol.solved
    z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
    assert np.all(np.abs(z) < 3.0), np.round(z, 2)

    # the decision itself: the matched detections are centroided over their streaks, whose
    # drawn length is past the shortest re-centroided
    got = _streaks_of(sensor, solver, frame.image, sol)
    assert isinstance(got, StreakCentroids)
    shortest = MIN_STREAK_SIGMAS * float(sensor.detector.psf_sigma_px) + 4.0
    assert np.max(np.hypot(*got.streaks_px.T)) >= shortest


@pytest.mark.slow
def test_a_blend_measuring_long_does_not_stretch_every_capsule():
    """Trial 1020 of 1320 of a 3.5 deg design (800 px, PSF sigma 1.04 px, 6.9 px streaks at
    1 deg/s; drawn with the zoo's seed 99): two stars 9 px apart light one region that measures
    as a 12.9 px streak, and fewer than three streaks agree with it. Drawn at every star, that
    streak made each capsule twice the true one and the attitude 12.3 of its own sigma off
    across the boresight. A rate so weakly confirmed does not overrule the brightest stars'
    measured streaks: the frame keeps its boxes and lies within 3 sigma on every axis (the
    Gaussian bound of the test above)."""
    _, solver, truth, frame = zoo_trial(25, seed=99, n_trials=1320, trial=1020, rate_deg_s=1.0)
    sol = solver(frame.image)
    assert sol.solved
    z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
    assert np.all(np.abs(z) < 3.0), np.round(z, 2)


def _streaks_of(sensor, solver, image, sol=None):
    """What the solver's smear decision makes of the frame's matched detections."""
    sol = sol or solver(image)
    assert sol.solved
    det = np.array(sol.matches)[:, 0]
    found = solver.detector(image)
    box = found.bbox[det]
    return streak_centroids_of(
        sensor,
        image,
        np.column_stack([found.x[det], found.y[det]]),
        counts=found.integrated_counts[det],
        extent_px=np.maximum(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]),
        level=float(sensor.detector.bias_counts),
        threshold=sensor.detection.lit_pixel_counts,
    )


@pytest.mark.slow
def test_a_psf_elongated_at_rest_is_not_read_as_a_streak():
    """The ST-16 with a PSF of 3.0 x 0.8 px sigmas (turned 0.5 rad), given in its [psf] table.

    At rest its stars' lit pixels measure as streaks of ~7 px, past the shortest the solver
    re-centroids (2 PSF sigmas plus the margins): read as smeared, a frame's rate was fitted
    and its fit did not converge (sigmas 5 to 7 times the rest fit's). The PSF's own
    elongation, drawn by the forward model at each star's light and measured as the frame's
    stars are, is taken out: at rest no frame is smeared; at 1 deg/s (streaks of ~20 px) every
    frame still is.
    """
    sensor = elongated(load_sensor("st16"), 3.0, 0.8, 0.5)
    solver = Solver(sensor)
    rng = np.random.default_rng(5)
    for truth in random_attitudes(2, rng):
        rest = render_frame(sensor, truth, solver.catalog, rng=rng)
        assert not isinstance(_streaks_of(sensor, solver, rest.image), StreakCentroids)
        rate = np.radians([0.8, -0.6, 0.0])  # 1 deg/s across the boresight
        moving = render_frame(sensor, truth, solver.catalog, rate_rad_s=rate, rng=rng)
        assert isinstance(_streaks_of(sensor, solver, moving.image), StreakCentroids)


def test_short_streaks_are_fitted_with_the_body_rate():
    """The ST-16 at 0.5 deg/s: streaks of 6.4 px, shorter than the 9 px (2 PSF sigmas plus the
    margins) from which the solver centroids over streaks. Fitted as a frame at rest, the
    pixels rejected the model (reduced chi-square 1.3-4.7 over ~3,000 pixels, whose spread
    is 0.03) and the errors were 1.3 times the sandwich's sigmas across the boresight. The
    rate the short streaks suggest starts a fit with the rate free, kept on the likelihood
    ratio: every frame is fitted so, and lies within 3.5 of its sigma on each axis (a right
    fit's error is Gaussian in its sigma: 3.5 sigma on one of 9 draws has chance 0.4 %).
    At rest the renderer draws the fit's own model: no frame has its rate fitted (the model
    at rest is rejected by chance in 0.13 % of frames)."""
    sensor = load_sensor("st16")
    solver = Solver(sensor)
    rng = np.random.default_rng(11)
    for truth in random_attitudes(3, rng):
        turn = rng.uniform(0.0, 2.0 * np.pi)
        rate = np.radians(0.5) * np.array([np.cos(turn), np.sin(turn), 0.0])
        frame = render_frame(sensor, truth, solver.catalog, rate_rad_s=rate, rng=rng)
        sol = solver(frame.image)
        assert sol.solved
        assert any("short streaks fitted with the body rate" in n for n in sol.notes), sol.notes
        z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
        assert np.all(np.abs(z) < 3.5), np.round(z, 2)
    for truth in random_attitudes(2, rng):
        sol = solver(render_frame(sensor, truth, solver.catalog, rng=rng).image)
        assert sol.solved
        assert not any("short streaks" in n for n in sol.notes), sol.notes


#: a wide field of faint stars: 36 deg on 640 x 480 px (209 arcsec/px), PSF sigma 2.5 px,
#: f/2.8, 12 e- of read noise, 0.5 s: at 1 deg/s a streak of 8.6 px (3.4 PSF sigmas) that
#: doubles a star's variance along it, on stars whose brightest pixels stand 2-6 sigma above
#: the noise (too few lit to measure their streaks)
FAINT_WIDE = {
    "fov_deg": 36.0, "columns": 640, "rows": 480, "pitch_um": 10.0, "psf_sigma_px": 2.5,
    "exposure_s": 0.5, "bit_depth": 12, "read_noise_e": 12.0, "qe": 0.5, "f_number": 2.8,
}  # fmt: skip


@pytest.mark.slow
def test_faint_streaks_that_light_too_few_pixels_still_have_the_rate_fitted():
    """Fitted at rest, a frame of faint stars smeared over 3.4 PSF sigmas was not rejected by
    its chi-square (the faint pixels barely see the smear) and its stars' lit pixels measured
    no streak, so the rate was never tried: the fit's sigmas assumed the narrower image. The
    brightest stars' adaptive moments suggest the rate, and a smear that long is put to the
    likelihood ratio: most solved frames are fitted with the rate, within 3.5 of their sigma on
    each axis (the Gaussian bound of the tests above)."""
    sensor = zoo.make_sensor("faint_wide", **FAINT_WIDE)
    solver = Solver(sensor)
    rng = np.random.default_rng(20261207)
    fitted, solved = 0, 0
    for truth in random_attitudes(12, rng):
        turn = rng.uniform(0.0, 2.0 * np.pi)
        rate = DEG * np.array([np.cos(turn), np.sin(turn), 0.0])
        frame = render_frame(sensor, truth, solver.catalog, rate_rad_s=rate, rng=rng)
        sol = solver(frame.image)
        if not sol.solved:  # some fields hold too few stars this bright
            continue
        solved += 1
        fitted += any("short streaks fitted with the body rate" in n for n in sol.notes)
        z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
        assert np.all(np.abs(z) < 3.5), np.round(z, 2)
    assert solved >= 5  # 7 of these 12 fields solve (5 have too few stars this bright)
    assert fitted >= 0.75 * solved, (fitted, solved)


def test_faint_stars_that_light_no_streak_suggest_the_rate_by_their_weighted_moments():
    """On the faint wide field above, the brightest matched stars light too few pixels to
    measure their streaks; their adaptive moments give the rate, up to its sign, within 20 deg
    of the true one's direction (8.6 px streaks on a 2.5 px PSF)."""
    sensor = zoo.make_sensor("faint_wide", **FAINT_WIDE)
    solver = Solver(sensor)
    rng = np.random.default_rng(3)
    truth = random_attitudes(1, rng)[0]
    rate = DEG * np.array([0.6, -0.8, 0.0])
    frame = render_frame(sensor, truth, solver.catalog, rate_rad_s=rate, rng=rng)
    got = _streaks_of(sensor, solver, frame.image)
    assert isinstance(got, ShortStreaks)
    hint = got.rate_rad_s[:2] / np.linalg.norm(got.rate_rad_s[:2])
    assert abs(hint @ rate[:2]) / np.linalg.norm(rate[:2]) > np.cos(np.radians(20.0))
