"""The faint, cluttered 8-bit camera class (tests/_support/camera_class.py), the field unknown.

Frames of a narrow science camera read at 8 bits with the dark level at 0-2 counts: a third to
two thirds of the pixels are 0, colour frames' luminance is off the integer lattice, and a
gradient, row banding, a blotchy fixed pattern and hot pixels lie on top. The MAD of such a
frame reads a fraction of its noise (0 where half the pixels are 0): the noise map fell to
~0 and every frame gave thousands of candidates. Judged over seeded draws against the truth:
every frame with the evidence of the class (``evident``: 10 stars at a matched-filter SNR of
8, decided from the truth) solved, and no frame wrong (more than 2 px across the boresight or
0.15 deg in roll: a wrong identification is off by degrees).
"""

from __future__ import annotations

import numpy as np
import pytest
from camera_class import class_frame, luminance

from starsense.catalog import load_catalog
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 206264.80624709636
SEEDS = range(100, 124)  # held out from the seeds 0-39 the fix was looked at on


def _wrong(frame, sol) -> bool:
    err = np.abs(small_rotation_angles(frame.attitude, sol.rotation)) * ARCSEC_PER_RAD
    pixel_arcsec = frame.params["fov_deg"] * 3600 / frame.image.shape[1]
    return bool(max(err[:2]) > 2 * pixel_arcsec or err[2] > 540)


@pytest.mark.slow
def test_faint_cluttered_frames_solve_with_the_field_unknown():
    catalog = load_catalog("hipparcos")
    solver = Solver()
    evident = solved = wrong = 0
    for seed in SEEDS:
        frame = class_frame(seed, catalog)
        sol = solver(luminance(frame.image))
        assert sol.status != "too_many_candidates", (seed, sol.message)
        if sol.solved:
            wrong += _wrong(frame, sol)
        if frame.evident:
            evident += 1
            solved += sol.solved and not _wrong(frame, sol)
    assert wrong == 0
    assert evident >= len(SEEDS) // 2  # the draw holds the class, not only empty frames
    assert solved >= 0.95 * evident, (solved, evident)


def test_the_class_is_clipped_and_coloured():
    # what the class is: more than a third of the pixels at 0 in some frames, colour and grey
    catalog = load_catalog("hipparcos")
    frames = [class_frame(seed, catalog) for seed in SEEDS[:8]]
    assert max(np.mean(f.image == 0) for f in frames) > 0.35
    assert {f.params["colour"] for f in frames} == {True, False}
    assert all(f.params["hot_pixels"] >= 20 for f in frames)
