"""Near misses checked against the frame's fainter stars (starsense.solve.near_miss).

The class: frames with few bright detections (the faint 8-bit camera of
tests/_support/camera_class.py, seeded), where the right hypothesis matches 6-8 detections and
its false-match probability stays above the 1e-9 accepted. The threshold is not loosened; the
frame's fainter catalogue stars are read where the hypothesis puts them, against control places.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from camera_class import class_frame, luminance
from scipy.spatial.transform import Rotation

from starsense.catalog import load_catalog
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.near_miss import NEAR_MISS_CEILING, FrameEvidence, fisher_combined
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 206264.80624709636
#: seeds of the class not looked at while the near-miss step was written (200-259 were)
HELD_OUT = range(400, 430)


@pytest.fixture(scope="module")
def catalog():
    return load_catalog("hipparcos")


@pytest.fixture(scope="module")
def solver():
    return Solver()


def _wrong(frame, rotation) -> bool:
    err = np.abs(small_rotation_angles(frame.attitude, rotation)) * ARCSEC_PER_RAD
    pixel_arcsec = frame.params["fov_deg"] * 3600 / frame.image.shape[1]
    return bool(max(err[:2]) > 2 * pixel_arcsec or err[2] > 540)


def test_fisher_combination_is_the_product_tail_of_two_uniforms():
    # P[U1 U2 <= t] by a seeded draw of a million pairs against the closed form
    u = np.random.default_rng(1).random((1_000_000, 2)).prod(axis=1)
    for t in (1e-4, 1e-3, 1e-2, 0.1):
        measured = float(np.mean(u <= t))
        # binomial standard error of a fraction near P over 1e6 draws, 5 of them
        p = t * (1 - math.log(t))
        assert abs(fisher_combined(math.sqrt(t), math.sqrt(t)) - p) < 1e-15
        assert abs(measured - p) < 5 * math.sqrt(p / 1e6)
    assert fisher_combined(1.0, 1.0) == 1.0
    assert fisher_combined(0.0, 0.5) == 0.0


@pytest.mark.slow
def test_wrong_attitudes_read_as_chance(catalog, solver):
    # Under a wrong attitude the predicted places are unrelated to the frame: p2 is a p-value
    # (at most alpha of them below alpha). At the truth the faint stars are there.
    band = solver.identifier(None).database.params.band
    stars = solver.sky_stars(band)
    rng = np.random.default_rng(7)
    wrong_p, true_p = [], []
    for seed in HELD_OUT[:12]:
        frame = class_frame(seed, catalog)
        image = np.asarray(luminance(frame.image))
        det = solver.detector(image)
        evidence = FrameEvidence(image, det.x, det.y, det.integrated_counts, solver.sky_stars)
        rows, cols = image.shape
        pinhole = ((cols - 1) / 2, (rows - 1) / 2, cols / 2 / math.tan(frame.fov_rad / 2))
        if frame.evident:
            true_p.append(
                evidence.read(
                    frame.attitude.as_matrix(), pinhole, reach=1.5, stars=stars, mag_limit=9.5
                )[0]
            )
        for _ in range(10):
            axis = rng.standard_normal(3)
            angle = math.radians(rng.uniform(0.3, 20.0))
            turn = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis))
            p2, _ = evidence.read(
                (turn * frame.attitude).as_matrix(), pinhole, reach=1.5, stars=stars, mag_limit=9.5
            )
            wrong_p.append(p2)
    wrong_p = np.array(wrong_p)
    # 120 wrong attitudes: a p-value puts ~1.2 below 0.01 (at most 5 allowed: binomial tail
    # P[X >= 6] ~ 1e-3), none below 1e-4 (P ~ 1e-2 for a true p-value)
    assert np.count_nonzero(wrong_p < 0.01) <= 5, np.sort(wrong_p)[:8]
    assert wrong_p.min() > 1e-4
    assert len(true_p) >= 4 and max(true_p) < 1e-6, true_p


@pytest.mark.slow
def test_near_misses_of_the_class_solve_right(catalog, solver):
    # The same detections as a centroid list (no frame: no fainter evidence) fall short of the
    # threshold; with the frame most solve, at the truth. No frame solves wrong. (Measured on
    # seeds 400-459: 6 near misses, 4 solved; the two left had their right hypothesis at
    # P_false 1e-4 with 8 and 11 faint stars seen of 29 and 51 predicted: p2 ~1e-6, too little.)
    near = solved = 0
    for seed in HELD_OUT:
        frame = class_frame(seed, catalog)
        image = luminance(frame.image)
        sol = solver(image)
        if sol.solved:
            assert not _wrong(frame, sol.rotation), seed
        det = solver.detector(np.asarray(image))
        alone = solver.solve_centroids(
            np.column_stack([det.x, det.y]), image.shape[::-1], brightness=det.integrated_counts
        )
        best = alone.counts.get("best_false_match_probability", 1.0)
        if not alone.solved and 1e-9 < best <= NEAR_MISS_CEILING:
            near += 1
            solved += sol.solved
    assert near >= 3, near  # the draw holds the class
    assert solved >= near / 2, (solved, near)
