"""Camera calibration on the ESA frames, leave-one-out (issue 14, part 3).

For each of the eight frames: fit the camera (focal length, principal point, k1, k2, p1, p2) on
the other seven, solve the eighth with the calibrated sensor, and compare with the nominal
(pinhole) sensor: residual rms of its matched stars and the direction of the image centre
against reference.json. Also prints the per-star centroid noise the sensor model predicts for
the matched stars (centre-of-gravity noise with the frame's measured background noise,
:func:`starsense.solve.solver._cog_sigma_px`), the yardstick of the residuals.

    PYTHONPATH=src .venv/bin/python bench/esa_calibration.py

writes bench/results/esa_calibration.json.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np

from starsense._io import atomic_write
from starsense.catalog import load_catalog
from starsense.detect import StarDetector
from starsense.geometry.attitude import angular_separation, radec_to_vectors
from starsense.solve.calibration import calibrate, frame_stars
from starsense.solve.frames import load_image
from starsense.solve.solver import Solver, _cog_sigma_px
from starsense.units import RAD_TO_ARCSEC

ESA = Path(__file__).resolve().parents[2] / "shared" / "data" / "images" / "esa"
OUT = Path(__file__).resolve().parent / "results" / "esa_calibration.json"


def centre_error_arcsec(sol, ref: dict) -> float:
    """Angle between the solved direction of the image centre and reference.json's, arcsec."""
    rows, cols = sol.image_shape
    cam = sol.sensor.unproject([(cols - 1) / 2.0], [(rows - 1) / 2.0])
    sky = sol.rotation.inv().apply(cam)[0]
    want = radec_to_vectors(math.radians(ref["ra_deg"]), math.radians(ref["dec_deg"]))
    return float(angular_separation(sky, want)) * RAD_TO_ARCSEC


def predicted_noise_arcsec(solver: Solver, path: Path, sol) -> float:
    """Rms total (two-axis) centroid noise of the matched stars the sensor model predicts."""
    detector = StarDetector(solver.logic, "cog", background="auto", threshold_sigma=5.0)
    det = detector(load_image(path))
    idx = np.array([d for d, _ in sol.matches])
    gain = solver.sensor.detector.gain_counts_per_e
    model = dataclasses.replace(solver.sensor.detector, read_noise_e=det.noise_counts / gain)
    sigma = _cog_sigma_px(det, idx, model, detector.margin_px)
    return float(np.sqrt(2 * np.mean(sigma**2)) / solver.sensor.focal_length_px * RAD_TO_ARCSEC)


def main() -> int:
    if not ESA.is_dir():
        print(f"ESA frames not found at {ESA}")
        return 1
    reference = json.loads((ESA / "reference.json").read_text())["frames"]
    cat = load_catalog("hipparcos")
    nominal = Solver("esa_blackfly")
    names = sorted(reference)
    sols = {n: nominal.solve_file(ESA / n) for n in names}
    stars = {n: frame_stars(sols[n], cat, n) for n in names}
    rows = []
    for held in names:
        fit = calibrate([stars[n] for n in names if n != held], nominal.sensor)
        after = Solver(fit.sensor).solve_file(ESA / held)
        before = sols[held]
        row = {
            "frame": held,
            "fit_stars": fit.n_stars,
            "rms_arcsec_before": before.rmse_arcsec,
            "rms_arcsec_after": after.rmse_arcsec,
            "centre_error_arcsec_before": centre_error_arcsec(before, reference[held]),
            "centre_error_arcsec_after": centre_error_arcsec(after, reference[held]),
            "n_matched_before": before.n_matched,
            "n_matched_after": after.n_matched,
            "predicted_noise_arcsec": predicted_noise_arcsec(nominal, ESA / held, before),
            "reference_rmse_arcsec": reference[held]["rmse_arcsec"],
        }
        rows.append(row)
        print(
            f"{held}: rms {row['rms_arcsec_before']:.2f} -> {row['rms_arcsec_after']:.2f} "
            f"arcsec (predicted noise {row['predicted_noise_arcsec']:.2f}); image centre vs "
            f"reference {row['centre_error_arcsec_before']:.2f} -> "
            f"{row['centre_error_arcsec_after']:.2f} arcsec",
            flush=True,
        )
    joint = calibrate(list(stars.values()), nominal.sensor)
    summary = {
        key: float(np.sqrt(np.mean([r[key] ** 2 for r in rows])))
        for key in (
            "rms_arcsec_before",
            "rms_arcsec_after",
            "centre_error_arcsec_before",
            "centre_error_arcsec_after",
            "predicted_noise_arcsec",
        )
    }
    record = {"leave_one_out": rows, "rms_over_frames": summary, "all_eight": joint.to_dict()}
    print(json.dumps(summary, indent=1))
    with atomic_write(OUT) as fh:
        json.dump(record, fh, indent=1)
        fh.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
