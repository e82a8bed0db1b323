"""Frames of a camera starsense was not tuned for: the 8-bit sweep.

Renders the 6 x 4.5 deg 8-bit camera of ``tests/_support/camera8.py`` (background at 0-2
counts, noise clipped at zero) at 5 pointings x 3 biases for each kind of defect, solves every
frame knowing only its field (6 deg; ``--sensor``: the camera's model), the background
estimated, and scores each solution
against the truth (wrong: more than 1 px across the boresight or 0.15 deg in roll). Run it
with another checkout's ``src`` on PYTHONPATH to compare before and after. Writes
``bench/results/any_camera.json``.

    PYTHONPATH=src python bench/any_camera.py [--sensor] [--no-record]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "_support"))

from camera8 import FOV_RAD, camera8, frame8  # noqa: E402

from starsense._io import atomic_write  # noqa: E402
from starsense.catalog import load_catalog  # noqa: E402
from starsense.geometry.attitude import small_rotation_angles  # noqa: E402
from starsense.solve.solver import Solver  # noqa: E402

ARCSEC_PER_RAD = 206264.80624709636
POINTINGS = [(180, 60, 10), (10, -70, 100), (140, -20, 250), (250, 30, 40), (300, -45, 200)]
CASES = {
    "plain": ({}, {}),
    "read noise 0.6 counts": ({"read_noise_e": 12.0}, {}),
    "200 hot pixels": ({}, {"hot_pixels": 200}),
    "glow gradient": ({}, {"sky_e": 20.0, "gradient_e": 60.0}),
    "50 % vignetting": ({}, {"sky_e": 40.0, "vignetting": 0.5}),
    "JPEG 80": ({}, {"jpeg_quality": 80}),
    "JPEG 60 over a gradient": ({}, {"jpeg_quality": 60, "gradient_e": 40.0}),
    "JPEG 90 after 50 hot pixels": ({}, {"jpeg_quality": 90, "hot_pixels": 50}),
}


def main() -> None:
    """Run the sweep, print one line per case and write the JSON record."""

    catalog = load_catalog("hipparcos")
    # a user of such a camera knows the field, not the camera: --sensor gives the solver its model
    solver = Solver(sensor=camera8()) if "--sensor" in sys.argv else Solver(fov_rad=FOV_RAD)
    record = {}
    for name, (sensor_kw, frame_kw) in CASES.items():
        solved = wrong = 0
        detections = []
        for bias in (0.0, 1.0, 2.0):
            sensor = camera8(bias_counts=bias, **sensor_kw)
            for k, (ra, dec, roll) in enumerate(POINTINGS):
                image, att, _ = frame8(sensor, catalog, ra, dec, roll, seed=k, **frame_kw)
                sol = solver(image)
                detections.append(sol.n_detections)
                if sol.solved:
                    err = np.abs(small_rotation_angles(att, sol.rotation)) * ARCSEC_PER_RAD
                    bad = max(err[:2]) > 21 or err[2] > 540
                    wrong += bad
                    solved += not bad
        n = 3 * len(POINTINGS)
        record[name] = {
            "frames": n,
            "solved": int(solved),
            "wrong": int(wrong),
            "detections": [int(min(detections)), int(max(detections))],
        }
        print(
            f"{name}: {solved}/{n} solved, {wrong} wrong, "
            f"{min(detections)}-{max(detections)} detections"
        )
    if "--no-record" not in sys.argv:
        name = "any_camera_sensor.json" if "--sensor" in sys.argv else "any_camera.json"
        with atomic_write(HERE / "results" / name) as f:
            json.dump(record, f, indent=2)


if __name__ == "__main__":
    main()
