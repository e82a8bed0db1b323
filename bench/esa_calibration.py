"""Camera calibration on the ESA frames, leave-one-out.

For each of the eight frames: fit the camera (focal length, principal point, k1, k2, p1, p2) on
the other seven, solve the eighth with the calibrated sensor, and compare with the nominal
(pinhole) sensor: residual rms of its matched stars and the direction of the image centre
against reference.json. Twice: with catalogue places (the frame of reference.json), and
with apparent places at the time in the frames' names (proper motion over the 28 years since
the Hipparcos epoch, parallax, aberration). Also prints the per-star centroid noise the sensor
model predicts for the matched stars (centre-of-gravity noise with the frame's measured
background noise, :func:`starsense.detect.centroid.cog_sigma_px`), the residuals' yardstick.

    PYTHONPATH=src .venv/bin/python bench/esa_calibration.py

writes bench/results/esa_calibration.json.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from starsense._io import atomic_write
from starsense.catalog import load_catalog
from starsense.detect import StarDetector
from starsense.detect.centroid import cog_sigma_px
from starsense.geometry.attitude import angular_separation, radec_to_vectors
from starsense.geometry.distortion import distort
from starsense.solve.calibration import _Problem, calibrate, frame_stars
from starsense.solve.frames import load_image
from starsense.solve.solver import Solver
from starsense.units import RAD_TO_ARCSEC

ESA = Path(__file__).resolve().parents[2] / "shared" / "data" / "images" / "esa"
OUT = Path(__file__).resolve().parent / "results" / "esa_calibration.json"
FRAME_TIME = "2019-07-29T20:47:26"


def centre_error_arcsec(sol, ref: dict) -> float:
    """Angle between the solved direction of the image centre and reference.json's, arcsec."""
    rows, cols = sol.image_shape
    cam = sol.sensor.unproject([(cols - 1) / 2.0], [(rows - 1) / 2.0])
    sky = sol.rotation.inv().apply(cam)[0]
    want = radec_to_vectors(math.radians(ref["ra_deg"]), math.radians(ref["dec_deg"]))
    return float(angular_separation(sky, want)) * RAD_TO_ARCSEC


def predicted_sigma_px(solver: Solver, path: Path, sol) -> np.ndarray:
    """Per-axis centroid noise of each matched star the sensor model predicts, px."""
    detector = StarDetector(solver.logic, "cog", background="auto", threshold_sigma=5.0)
    det = detector(load_image(path))
    idx = np.array([d for d, _ in sol.matches])
    gain = solver.sensor.detector.gain_counts_per_e
    model = dataclasses.replace(solver.sensor.detector, read_noise_e=det.noise_counts / gain)
    return cog_sigma_px(det, idx, detector=model, margin_px=detector.margin_px)


def predicted_noise_arcsec(solver: Solver, path: Path, sol) -> float:
    """Rms total (two-axis) centroid noise of the matched stars the sensor model predicts."""
    sigma = predicted_sigma_px(solver, path, sol)
    return float(np.sqrt(2 * np.mean(sigma**2)) / solver.sensor.focal_length_px * RAD_TO_ARCSEC)


def noise_check(fit, stars, sigmas) -> dict:
    """Residual rms after the joint fit in quartiles of the predicted per-star noise, px."""
    res, sig = [], []
    for f, rot, s in zip(stars, fit.rotations, sigmas, strict=True):
        x, y = fit.sensor.project(rot.apply(f.vectors))
        res.append(np.column_stack([f.centroids_px[:, 0] - x, f.centroids_px[:, 1] - y]))
        sig.append(s)
    r, s = np.concatenate(res), np.concatenate(sig)
    edges = np.quantile(s, [0, 0.25, 0.5, 0.75, 1.0])
    rows = []
    for lo, hi in itertools.pairwise(edges):
        m = (s >= lo) & (s <= hi) & (np.linalg.norm(r, axis=1) < 5 * np.std(r) * math.sqrt(2))
        rows.append(
            {
                "predicted_rms_px": float(np.sqrt(np.mean(s[m] ** 2))),
                "residual_rms_px": float(np.sqrt(np.mean(r[m] ** 2))),
            }
        )
    return {"quartiles": rows}


class _ShearProblem(_Problem):
    """The joint fit plus a per-frame traceless linear map of the tangent plane.

    ``(x, y) -> (1 + [[a, b], [b, -a]]) (x, y)``: an anisotropic scale, what differential
    refraction does to a field (it compresses along the vertical by R0 / sin^2(alt) per rad).
    Its amplitude ``hypot(a, b)`` is half the difference of the scales along and across the
    axis.
    """

    def unpack_shear(self, theta):
        n = self.free.size + 3 * self.n_frames
        return theta[n:].reshape(self.n_frames, 2)

    def predict(self, theta, keep=None):
        keep = self.keep if keep is None else keep
        cam, deltas = self.unpack(theta[: self.free.size + 3 * self.n_frames])
        shear = self.unpack_shear(theta)
        k = self.frame_of[keep]
        c = (Rotation.from_rotvec(deltas[k]) * self.r0[k]).apply(self.v[keep])
        x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
        a, b = shear[k, 0], shear[k, 1]
        x, y = x + a * x + b * y, y + b * x - a * y
        xd, yd = distort(x, y, cam[3:])
        return np.column_stack([xd, yd]) * cam[0] + self.centre + cam[1:3]


def refraction_check(frames, sensor) -> dict:
    """Fit the camera plus a per-frame anisotropic scale; compare it with refraction."""
    free = np.arange(7)
    problem = _ShearProblem(frames, sensor, free)
    n = len(frames)
    theta = np.concatenate([problem.cam0, np.zeros(5 * n)])
    for _ in range(3):  # the same 5-sigma clipping as calibrate()
        res = least_squares(problem.residuals, theta, x_scale="jac")
        r = np.linalg.norm(res.fun.reshape(-1, 2), axis=1)
        bad = r > 5 * np.sqrt(np.mean(res.fun**2)) * math.sqrt(2)
        if not bad.any():
            break
        problem.keep[np.flatnonzero(problem.keep)[bad]] = False
    # the same stars without the shear (held at zero): the fair comparison
    plain = least_squares(
        lambda t: problem.residuals(np.concatenate([t, np.zeros(2 * n)])),
        res.x[: 7 + 3 * n],
        x_scale="jac",
    )
    shear = problem.unpack_shear(res.x)
    amp = np.hypot(shear[:, 0], shear[:, 1])
    alt = np.array([40.0 if "Alt40" in f.name else 60.0 for f in frames])
    # Bennett / Saemundsson: R = R0 cot(alt), R0 = 58 arcsec at sea level; dR/dalt = R0 / sin^2
    expected = 0.5 * 58.0 / RAD_TO_ARCSEC / np.sin(np.radians(alt)) ** 2
    f_px = res.x[0]
    rms = float(np.sqrt(np.mean(res.fun**2)) * math.sqrt(2) / f_px * RAD_TO_ARCSEC)
    rms0 = float(np.sqrt(np.mean(plain.fun**2)) * math.sqrt(2) / f_px * RAD_TO_ARCSEC)
    return {
        "stars": int(problem.keep.sum()),
        "rms_arcsec_without_shear": rms0,
        "rms_arcsec_with_shear": rms,
        "shear_amplitude": {f.name: float(a) for f, a in zip(frames, amp, strict=True)},
        "refraction_expected_amplitude_sea_level": {
            f.name: float(e) for f, e in zip(frames, expected, strict=True)
        },
        "mean_amplitude_alt40": float(np.mean(amp[alt == 40])),
        "mean_amplitude_alt60": float(np.mean(amp[alt == 60])),
    }


def run(names, reference, cat, obs_time) -> dict:
    """Leave-one-out over the frames, catalogue places (obs_time None) or apparent places."""
    nominal = Solver("esa_blackfly")
    sols = {n: nominal.solve_file(ESA / n, obs_time) for n in names}
    stars = {n: frame_stars(sols[n], cat, n) for n in names}
    rows = []
    for held in names:
        fit = calibrate([stars[n] for n in names if n != held], nominal.sensor)
        after = Solver(fit.sensor).solve_file(ESA / held, obs_time)
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
    sigmas = [predicted_sigma_px(nominal, ESA / n, sols[n]) for n in names]
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
    print(json.dumps(summary, indent=1))
    return {
        "obs_time": None if obs_time is None else str(obs_time),
        "leave_one_out": rows,
        "rms_over_frames": summary,
        "all_eight": joint.to_dict(),
        "noise_check": noise_check(joint, [stars[n] for n in names], sigmas),
        "refraction_check": refraction_check(list(stars.values()), nominal.sensor),
    }


def main() -> int:
    if not ESA.is_dir():
        print(f"ESA frames not found at {ESA}")
        return 1
    reference = json.loads((ESA / "reference.json").read_text())["frames"]
    cat = load_catalog("hipparcos")
    names = sorted(reference)
    # the frames carry no time in their headers; their names do (2019-07-29T204726), taken as UTC
    # (12 h either way moves the annual aberration by < 0.2 arcsec)
    record = {
        "catalogue_places": run(names, reference, cat, None),
        "apparent_places": run(names, reference, cat, FRAME_TIME),
    }
    with atomic_write(OUT) as fh:
        json.dump(record, fh, indent=1)
        fh.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
