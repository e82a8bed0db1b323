"""Streaks that run into each other: the datasheet's pull of a star's detection by its
neighbours' streaks against the detector's own centroid, on rendered noisy pairs."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from starsense.analysis.datasheet.merges import (
    edge_pull_px,
    match_radius_px,
    pulled_px,
)
from starsense.render.noise import apply_noise
from starsense.render.smear import streak_stamp_expected
from starsense.sensor import load_sensor
from starsense.solve.rematch import MATCH_SIGMAS
from starsense.solve.solver import Solver


def _pair(rng):
    """A seeded pair of parallel streaks on a frame of their own: sensor, frame, truth."""
    base = load_sensor("st16")
    psf = rng.uniform(0.7, 2.5)
    length = rng.uniform(15.0, 80.0)
    ang = rng.uniform(0.0, math.pi)
    u = np.array([math.cos(ang), math.sin(ang)])
    e_a = 10 ** rng.uniform(4.3, 5.3)
    e_b = e_a * 10 ** (-0.4 * rng.uniform(0.0, 2.5))
    along, across = rng.uniform(-length, length), rng.uniform(-10.0, 10.0)
    n = int(2 * length + 60)
    a = np.array([n / 2, n / 2])
    b = a + along * u + across * np.array([-u[1], u[0]])
    det = dataclasses.replace(base.detector, psf_sigma_px=psf, columns=n, rows=n)
    sensor = dataclasses.replace(base, detector=det)
    img = np.zeros((n, n))
    for p, e in ((a, e_a), (b, e_b)):
        x0, y0 = p - 0.5 * length * u
        x1, y1 = p + 0.5 * length * u
        st, r0, c0 = streak_stamp_expected(sensor, x0=x0, y0=y0, x1=x1, y1=y1, electrons=e)
        r1, c1 = max(r0, 0), max(c0, 0)
        r2, c2 = min(r0 + st.shape[0], n), min(c0 + st.shape[1], n)
        img[r1:r2, c1:c2] += st[r1 - r0 : r2 - r0, c1 - c0 : c2 - c0]
    frame = apply_noise(img[None], sensor, rng=rng)[0]
    return sensor, frame, (a, b, e_a, e_b, length * u)


def test_a_streaks_pull_by_its_neighbour_against_the_detector():
    # independent: the detector (the sensor's own logic, known background) on a noisy render
    # of two parallel streaks; the detection nearest the brighter star, its distance from it
    # against pulled_px. 40 seeded pairs across PSF 0.7-2.5 px, streaks 15-80 px, 0-2.5 mag
    # apart, side by side to end to end. The detector's centroid noise is a few hundredths of
    # a pixel here; the model takes a joined neighbour's light whole and the window as the
    # streak's box, so it is held to 0.3 px or 25 % in three pairs of four, and to the
    # matching's scale (pulled past 1 px or not) in nine of ten
    rng = np.random.default_rng(11)
    close, same_side = [], []
    for _ in range(40):
        sensor, frame, (a, b, e_a, e_b, streak) = _pair(rng)
        solver = Solver(sensor=sensor, background="known")
        found = solver.detector(frame)
        k = int(np.argmin(np.hypot(found.x - a[0], found.y - a[1])))
        measured = math.hypot(found.x[k] - a[0], found.y[k] - a[1])
        predicted = pulled_px(
            sensor,
            np.array([0]),
            centres_px=a[None],
            streaks_px=streak[None],
            electrons=np.array([e_a]),
            others=(np.zeros(2, dtype=int), np.vstack([a, b]), np.array([e_a, e_b])),
            margin_px=solver.detector.margin_px,
        )[0]
        close.append(abs(measured - predicted) <= max(0.3, 0.25 * predicted))
        same_side.append((measured > 1.0) == (predicted > 1.0))
    assert np.mean(close) >= 0.75
    assert np.mean(same_side) >= 0.9


def test_the_match_radius_is_the_verifications_or_a_stars_own():
    sensor = load_sensor("st16")
    frames = np.array([0, 0, 0, 1, 1, 1])
    sigma = np.array([0.01, 0.1, 0.5, 0.02, 0.02, 0.02])
    # frame 0: no pull, the median residual is that of sigma 0.1 (Rayleigh); frame 1: two of
    # three detections pulled 3 px, the median residual 3 px
    pull = np.array([0.0, 0.0, 0.0, 3.0, 3.0, 0.0])
    got = match_radius_px(sensor, frames, sigma_px=sigma, pull_px=pull)
    four = MATCH_SIGMAS * np.hypot(pull, math.sqrt(2 * math.log(2)) * sigma)
    assert np.allclose(got[:3], np.maximum(MATCH_SIGMAS * 0.1, MATCH_SIGMAS * sigma[:3]))
    assert np.allclose(got[3:], np.median(four[3:]) / math.sqrt(2 * math.log(2)))


def test_a_streak_cut_by_the_frames_edge_is_detected_by_the_part_left():
    sensor = load_sensor("st16")
    cols, rows = sensor.detector.columns, sensor.detector.rows
    centres = np.array([[10.0, 100.0], [cols / 2, rows / 2], [-30.0, 100.0], [100.0, rows - 6.5]])
    streaks = np.array([[40.0, 0.0], [40.0, 0.0], [40.0, 0.0], [0.0, 20.0]])
    got = edge_pull_px(sensor, centres, streaks)
    # geometry: the frame spans -0.5 .. columns - 0.5; a 40 px streak centred 10 px from the
    # left edge keeps -0.5 .. 30, whose middle is 4.75 px from the star's; one whole on the
    # frame is not moved; one wholly off it is not detected; one along the rows, centred 6 px
    # inside the bottom edge, keeps 10 px below its middle and 6 above it: moved 2 px up
    assert np.allclose(got[[0, 1, 3]], [4.75, 0.0, 2.0])
    assert np.isinf(got[2])
