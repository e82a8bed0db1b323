"""A star cut by the frame's edge: its centroid's pull is in its sigma, not in the attitude."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.special import erf

from starsense.catalog import load_catalog
from starsense.detect.centroid import edge_bias_px
from starsense.geometry.attitude import small_rotation_angles
from starsense.render.scene import render_frame
from starsense.solve import Solver


def _pull_of_cut_gaussian(x0: float, sigma: float, n: int = 80) -> float:
    """CoG minus centre of a Gaussian integrated over pixels 0..n-1 (the frame starts at -0.5)."""
    edges = np.arange(n + 1) - 0.5
    w = np.diff(0.5 * (1.0 + erf((edges - x0) / (np.sqrt(2.0) * sigma))))
    return float(w @ np.arange(n) / w.sum() - x0)


@pytest.mark.parametrize("sigma", [0.8, 1.5, 2.5])
def test_edge_pull_is_that_of_the_pixel_integrated_gaussian(sigma):
    # the model widens the PSF by the pixel (variance 1/12) and solves the centre from the
    # pulled centroid; against the exact pixel integral it is within -15 % / +25 % wherever
    # the pull is over 0.05 px (the approximation of the pixel by a Gaussian: the largest
    # departures are for a centre past the edge, and for the undersampled case, over-estimated)
    for x0 in np.linspace(-0.3, 4.0, 18):
        true = _pull_of_cut_gaussian(x0, sigma)
        got = edge_bias_px([x0 + true], [40.0], (81, 80), psf_sigma_px=sigma)[0]
        if true > 0.05:
            assert 0.85 * true <= got <= 1.25 * true, (x0, true, got)
        else:
            assert got < 0.1, (x0, true, got)
    # both edges of both axes, symmetric; nothing well inside
    far = edge_bias_px([40.0, 79.0 - 0.3, 40.0], [40.0, 40.0, 0.3], (81, 80), psf_sigma_px=sigma)
    assert far[0] < 1e-6 and far[1] == pytest.approx(far[2], rel=1e-12)


#: a design of the sensor zoo where the defect showed (6.4 deg, 608 x 448 px of 4.1 um, PSF
#: sigma 0.86 px, 0.86 s): its brightest star centred 0.6 px inside the edge, pulled 0.2 px,
#: close enough to be matched and weighted as a V = 3.8 star, moved the attitude by 13 sigma
_ZOO_DESIGN = {
    "fov_deg": 6.39,
    "columns": 608,
    "rows": 448,
    "pitch_um": 4.14,
    "psf_sigma_px": 0.86,
    "exposure_s": 0.86,
    "bit_depth": 14,
    "read_noise_e": 1.34,
    "qe": 0.59,
    "f_number": 3.85,
}


@pytest.fixture(scope="module")
def design():
    path = Path(__file__).resolve().parents[2] / "bench" / "zoo.py"
    spec = importlib.util.spec_from_file_location("starsense_bench_zoo_edge", path)
    zoo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(zoo)
    return zoo.make_sensor("edge", **_ZOO_DESIGN)


@pytest.mark.parametrize("rank", [600, 800, 1000])
def test_a_bright_star_on_the_edge_does_not_pull_the_attitude(design, rank):
    # a V 4.4-4.9 star centred 0.6 px inside the frame's left edge loses a quarter of its light
    # and its centroid moves 0.2 px inwards; weighted as if exact, it pulled the attitude by 4
    # to 6.5 of the solver's sigmas. With the edge's pull in its sigma every axis stays within
    # 4 sigmas (p < 1e-4 per axis for a right covariance)
    cat = load_catalog("hipparcos")
    star = np.argsort(np.asarray(cat.mags["V"], dtype=float))[rank]
    target = design.unproject(np.array([0.6]), np.array([0.5 * design.detector.rows]))[0]
    truth, _ = Rotation.align_vectors([target], [np.asarray(cat.vectors)[star]])
    frame = render_frame(design, truth, cat, rng=rank)
    sol = Solver(design, background="known", centroid_sigma_px="snr")(frame.image)
    assert sol.solved, sol.message
    xy = np.asarray(sol.centroids_px)[[d for d, _ in sol.matches]]
    assert np.any(xy[:, 0] < 1.0)  # the edge star is matched (else there is nothing to test)
    z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
    assert np.all(np.abs(z) < 4.0), z
