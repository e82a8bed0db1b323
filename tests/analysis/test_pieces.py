"""A faint streak lit in pieces: the datasheet's draw of its nearest detection against the
detector's own, on rendered noisy streaks."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from starsense.analysis.datasheet.pieces import WHOLE_RIDGE, piece_offsets_px, ridge_counts
from starsense.render.noise import apply_noise
from starsense.render.smear import streak_stamp_expected
from starsense.sensor import load_sensor
from starsense.solve.solver import Solver

#: radii (px) within which the nearest detection is counted: the solver's match radius under
#: slew lies between its own few sigma and the verification's, 1-6 px on these streaks
RADII = (1.5, 3.0, 6.0)


def _case(rng):
    """A seeded faint streak's sensor, electrons and streak: PSF 0.55-1.5 px (undersampled
    included), 10-40 px at any angle, its ridge 0.6-2 times the lit-pixel threshold."""
    base = load_sensor("st16")
    psf = rng.uniform(0.55, 1.5)
    length = rng.uniform(10.0, 40.0)
    ang = rng.uniform(0.0, math.pi)
    n = int(length + 40)
    det = dataclasses.replace(base.detector, psf_sigma_px=psf, columns=n, rows=n)
    sensor = dataclasses.replace(base, detector=det)
    ratio = rng.uniform(0.6, 2.0)
    electrons = ratio * sensor.detection.lit_pixel_counts / float(ridge_counts(sensor, 1.0, length))
    return sensor, electrons, length * np.array([math.cos(ang), math.sin(ang)])


def _measured(sensor, electrons, streak, rng, frames):
    """Distance of the detection nearest the streak's middle, px, on noisy renders (inf: none)."""
    n = sensor.detector.columns
    mid = np.array([n / 2 + rng.uniform(-0.5, 0.5), n / 2 + rng.uniform(-0.5, 0.5)])
    (x0, y0), (x1, y1) = mid - 0.5 * streak, mid + 0.5 * streak
    st, r0, c0 = streak_stamp_expected(sensor, x0=x0, y0=y0, x1=x1, y1=y1, electrons=electrons)
    img = np.zeros((n, n))
    img[r0 : r0 + st.shape[0], c0 : c0 + st.shape[1]] += st
    detector = Solver(sensor=sensor, background="known").detector
    out = []
    for frame in apply_noise(np.repeat(img[None], frames, axis=0), sensor, rng=rng):
        found = detector(frame)
        d = np.hypot(found.x - mid[0], found.y - mid[1])
        out.append(d.min() if len(d) else np.inf)
    return np.array(out)


def test_a_faint_streaks_nearest_detection_against_the_detector():
    # independent: the detector (the sensor's own logic, known background) on 40 noisy renders
    # of each of 24 seeded faint streaks; the fraction whose nearest detection lies within
    # 1.5, 3 and 6 px of the middle against the model's 256 draws. A fraction of 40 frames
    # has a binomial sd of at most 0.08: each case is held to 0.3 (3.8 sd), and the mean
    # difference over the 72 comparisons to 0.08 (its own sd is ~0.01; the model's column
    # approximation of a slanted streak's pixels is what the rest allows)
    rng = np.random.default_rng(5)
    diffs = []
    for _ in range(24):
        sensor, electrons, streak = _case(rng)
        measured = _measured(sensor, electrons, streak, rng, 40)
        drawn = piece_offsets_px(
            sensor, [electrons], streak[None], rng=rng, samples=256
        ).offsets_px[0]
        for r in RADII:
            diffs.append(np.mean(drawn <= r) - np.mean(measured <= r))
    diffs = np.array(diffs)
    assert np.abs(diffs).max() <= 0.3
    assert abs(diffs.mean()) <= 0.08


def test_a_bright_streak_is_lit_whole_and_a_dark_one_not_detected():
    sensor, _, streak = _case(np.random.default_rng(1))
    per = float(ridge_counts(sensor, 1.0, float(np.hypot(*streak))))
    lit = sensor.detection.lit_pixel_counts
    electrons = [1.01 * WHOLE_RIDGE * lit / per, 0.05 * lit / per]
    drawn = piece_offsets_px(
        sensor, electrons, streak[None].repeat(2, 0), rng=np.random.default_rng(2)
    ).offsets_px
    # past 4 times the threshold: one piece, centred (0 by construction); at 1/20 of it no pixel
    # reaches the threshold but by 19 thresholds of noise or more: nothing is detected
    assert np.all(drawn[0] == 0.0)
    assert np.all(np.isinf(drawn[1]))
