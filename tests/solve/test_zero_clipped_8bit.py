"""Faint 8-bit frames with the background at 0-2 counts, the read noise clipped at zero.

The class of frames 8-bit machine-vision cameras write at short exposures: bias 0-2 counts,
read noise about 1.5 counts (30 e- at 0.05 counts/e-), so that up to two thirds of the pixels
are exactly 0, stored as an RGBA PNG of grey or as a tinted colour PNG (a colour camera's
output, whose luminance is not a whole number of counts). A noise estimate from the median
absolute deviation reads 0 or 1 count whatever the noise, and the luminance of a tinted frame
is not on the integer lattice: such frames gave thousands of candidates and no solution.

Rendered by starsense.render through tests/_support/camera8.py (6 x 4.5 deg on 1024 x 768
pixels, 21 arcsec/px) at 20 seeded random pointings, solved from the file knowing the field.
"Wrong" is judged against the truth: more than 1 px (21 arcsec) across the boresight or
0.15 deg in roll (a wrong identification is off by degrees; tests/solve/test_solve_any_camera.py
says why these tolerances).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from camera8 import FOV_RAD, camera8, frame8

from starsense.catalog import load_catalog
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 180 / math.pi * 3600
#: read noise of the class, electrons (1.5 counts at the camera's 0.05 counts/e-)
READ_NOISE_E = 30.0


def _write(image, path, tinted):
    from PIL import Image

    if tinted:  # blue at 80 %: the luminance is 0.977 of the counts, off the integer lattice
        rgb = np.stack([image, image, (0.8 * image).round()], axis=-1).astype(np.uint8)
        Image.fromarray(rgb).save(path)
    else:
        Image.fromarray(image).convert("RGBA").save(path)


@pytest.mark.slow
def test_zero_clipped_8bit_frames_solve_and_none_is_wrong(tmp_path):
    catalog = load_catalog("hipparcos")
    solver = Solver(fov_rad=FOV_RAD)
    rng = np.random.default_rng(2024)
    solved = wrong = 0
    zeros = []
    for k in range(20):
        ra = rng.uniform(0.0, 360.0)
        dec = math.degrees(math.asin(rng.uniform(-1.0, 1.0)))
        roll = rng.uniform(0.0, 360.0)
        sensor = camera8(bias_counts=float(rng.uniform(0.0, 2.0)), read_noise_e=READ_NOISE_E)
        image, att, _ = frame8(sensor, catalog, ra, dec, roll, seed=k)
        zeros.append(float(np.mean(image == 0)))
        path = tmp_path / f"frame{k}.png"
        _write(image, path, tinted=k % 2 == 1)
        sol = solver.solve_file(path)
        assert sol.counts["candidates"] < 500  # candidates are stars, not noise
        if sol.solved:
            err = np.abs(small_rotation_angles(att, sol.rotation)) * ARCSEC_PER_RAD
            bad = max(err[:2]) > 21 or err[2] > 540
            wrong += bad
            solved += not bad
    assert max(zeros) > 0.5  # the class: more than half the pixels exactly 0 in some frames
    assert wrong == 0
    assert solved >= 19


@pytest.mark.parametrize("tinted", [False, True])
def test_pure_noise_8bit_frames_give_few_candidates(tmp_path, tinted):
    # no stars at all: the noise model must not light the clipped background
    rng = np.random.default_rng(7)
    image = np.clip(np.round(0.5 + 1.5 * rng.standard_normal((768, 1024))), 0, 255)
    path = tmp_path / "noise.png"
    _write(image.astype(np.uint8), path, tinted)
    sol = Solver(fov_rad=FOV_RAD).solve_file(path)
    assert not sol.solved
    # a 5 sigma matched-filter threshold over 786,432 pixels: a handful of chance candidates
    assert sol.counts.get("candidates", 0) < 50
