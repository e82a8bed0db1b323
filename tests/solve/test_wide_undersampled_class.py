"""Stars of one or two pixels on a wide imager (tests/_support/wide_class.py), the field unknown.

The robust extraction holds such stars aside as hot pixels and its 1 px matched filter loses
the faint ones; the spike-keeping retry (:mod:`starsense.solve.sharp`) detects them with a
filter of a one-pixel star and ranks the detections sharper than optics make (a defect's one
pixel) after those showing a PSF. Checked here: the neighbour share against the pixel integral
of a Gaussian, the ranking on a drawn frame with a star and a hot pixel, and seeded frames of the
class solved and right.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf
from wide_class import wide_frame

from starsense.catalog import load_catalog
from starsense.detect import constant_background
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.sharp import MIN_NEIGHBOUR_SHARE, SpikeDetector, neighbour_share
from starsense.solve.solver import Solver

SEEDS = range(200, 206)  # not among the tuning seeds (1000-1099) nor the bench's held-out runs


def _star(shape, x0, y0, sigma, total):
    """A Gaussian star integrated over the pixels (pixel centres at integers), counts."""
    rows, cols = shape
    ex, ey = np.arange(cols + 1) - 0.5, np.arange(rows + 1) - 0.5
    wx = np.diff(0.5 * (1 + erf((ex - x0) / (math.sqrt(2) * sigma))))
    wy = np.diff(0.5 * (1 + erf((ey - y0) / (math.sqrt(2) * sigma))))
    return total * np.outer(wy, wx)


def _centred_share(sigma: float) -> float:
    """The 8 neighbours' light over the peak pixel's, star centred on a pixel (independent)."""
    c = erf(0.5 / (math.sqrt(2) * sigma))  # the centre pixel's fraction along one axis
    e = 0.5 * (erf(1.5 / (math.sqrt(2) * sigma)) - c)  # one neighbour's
    return (4 * e * c + 4 * e * e) / (c * c)


@pytest.mark.parametrize("sigma", [0.3, 0.4, 0.5])
def test_neighbour_share_is_that_of_the_pixel_integrated_gaussian(sigma):
    image = 100.0 + _star((21, 21), 10.0, 10.0, sigma, 5000.0)
    share, noise = neighbour_share(image, constant_background(100.0, 1.0), x=[10.0], y=[10.0])
    # noiseless frame: the share is exact up to the light two pixels away (< 0.2 % a pixel
    # at sigma 0.5, subtracted as the local level) and float rounding
    assert share[0] == pytest.approx(_centred_share(sigma), rel=0.01)
    # noise 1 count a pixel: the 8 neighbours' sum less 8 medians of 16 (variance pi/2 / 16)
    peak = image[10, 10] - 100.0
    assert noise[0] == pytest.approx(math.sqrt(8 + 64 * math.pi / 2 / 16) / peak, rel=0.01)
    # the least share a star of sigma >= 0.26 px shows is above the one ranking spikes last
    assert _centred_share(0.26) > MIN_NEIGHBOUR_SHARE


def test_spike_detector_ranks_a_hot_pixel_after_a_fainter_star():
    rng = np.random.default_rng(3)
    shape = (64, 64)
    image = 50.0 + _star(shape, 20.3, 30.2, 0.35, 600.0) + rng.normal(0.0, 3.0, shape)
    image[40, 45] += 2000.0  # a hot pixel, three times the star's light, nothing around it
    detector = Solver().spike_detector  # the field unknown: no sensor, its PSF not known
    assert isinstance(detector, SpikeDetector)
    det = detector(image)
    hot = int(np.argmin(np.hypot(det.x - 45, det.y - 40)))
    star = int(np.argmin(np.hypot(det.x - 20.3, det.y - 30.2)))
    assert np.hypot(det.x[hot] - 45, det.y[hot] - 40) < 0.5
    assert np.hypot(det.x[star] - 20.3, det.y[star] - 30.2) < 0.5
    assert det.integrated_counts[hot] > det.integrated_counts[star]  # brighter, yet
    rank = det.extra["rank"]
    assert rank[star] > rank[hot]
    assert (rank[np.arange(len(det)) != hot] > rank[hot]).all()


def test_wide_undersampled_frames_solve_with_the_field_unknown():
    catalog = load_catalog("hipparcos")
    solver = Solver()
    for seed in SEEDS:
        frame = wide_frame(seed, catalog)
        sol = solver(frame.image)
        if not frame.evident:
            continue
        assert sol.solved, (seed, sol.status, sol.message)
        # wrong: more than 2 px across the boresight or at the frame's corner in roll
        err = np.abs(small_rotation_angles(frame.attitude, sol.rotation))
        rows, cols = frame.image.shape
        pixel = frame.fov_rad / cols
        assert max(err[:2]) <= 2 * pixel, seed
        assert err[2] * math.hypot(rows, cols) / 2 <= 2.0, seed
