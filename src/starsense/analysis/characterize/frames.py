"""The frames to characterise a camera from: loaded, solved, their matched stars listed.

Each frame is solved with the base sensor when one is given (through
:class:`~starsense.solve.calibration.FrameSolver`, which falls back to the unknown-optics solver
for a frame the sensor's lens model does not identify), else with the optics unknown
(:class:`~starsense.solve.Solver` without a sensor: the field searched, a radial distortion
fitted). Without a base sensor the camera is described by a nominal one
(:func:`nominal_sensor`) whose pixel pitch, aperture and detector constants are placeholders
the frames cannot tell: the report and the TOML say so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from starsense.errors import InputError
from starsense.sensor import Sensor
from starsense.sensor.detector import Detector
from starsense.sensor.optics import Optics
from starsense.sensor.sensor import DetectionThresholds
from starsense.solve import Solver
from starsense.solve.calibration import FrameSolver, FrameStars, frame_stars
from starsense.solve.frames import load_image
from starsense.solve.solution import Solution

__all__ = [
    "NOMINAL_PITCH_M",
    "SolvedFrame",
    "corner_radius_px",
    "frame_name",
    "nominal_sensor",
    "solve_frames",
]

#: pixel pitch assumed for a camera given by nothing but its frames, m (a focal length in
#: pixels is what the frames tell; in metres it needs the pitch)
NOMINAL_PITCH_M = 5e-6
#: focal ratio assumed for such a camera (sets the aperture, which frames cannot tell)
NOMINAL_F_NUMBER = 2.0


@dataclass(frozen=True, eq=False)
class SolvedFrame:
    """One solved frame and its matched stars.

    Attributes
    ----------
    name : str
        The file (or ``frame k``).
    image : ndarray (rows, columns)
        The pixels, counts.
    solution : Solution
    stars : FrameStars
        The matched stars: centroids (px), ICRS directions (apparent places when used).
    mags_v : ndarray (N,)
        Their catalogue V magnitudes (NaN where the catalogue has none).
    """

    name: str
    image: np.ndarray
    solution: Solution
    stars: FrameStars
    mags_v: np.ndarray


def frame_name(frame, k: int) -> str:
    """Return a frame's name: its path, or ``frame k`` for an array (the k-th given)."""
    return str(frame) if isinstance(frame, str | Path) else f"frame {k}"


def _as_image(frame, k: int) -> tuple[str, np.ndarray]:
    if isinstance(frame, str | Path):
        return frame_name(frame, k), np.asarray(load_image(frame))
    a = np.asarray(frame)
    if a.ndim != 2 or a.size == 0 or not np.issubdtype(a.dtype, np.number):
        raise InputError(f"frame {k}: need a 2-D array of counts, got shape {a.shape} {a.dtype}")
    return f"frame {k}", a


def solve_frames(frames, sensor: Sensor | None, *, catalog="hipparcos", obs_time=None):
    """Load and solve the frames; return the solved ones and why the others did not solve.

    Parameters
    ----------
    frames : sequence of path or ndarray
        The frames (image files, or 2-D arrays of counts).
    sensor : Sensor or None
        The base sensor (None: optics unknown).
    catalog : Catalog or str
        The catalogue to identify with.
    obs_time : str, optional
        UTC time of the frames (else from each file's header, where it has one).

    Returns
    -------
    solved : list of SolvedFrame
    skipped : dict
        Frame name -> status, for the frames that did not solve.

    Raises
    ------
    InputError
        No frames, a frame that cannot be read, frames of different sizes, or a frame whose
        size differs from the base sensor's detector.
    """
    frames = list(frames)
    if not frames:
        raise InputError("characterize needs at least one frame")
    solver = FrameSolver(sensor, catalog=catalog) if sensor is not None else None
    unknown = Solver(catalog=catalog) if sensor is None else None
    solved, skipped, shape = [], {}, None
    for k, frame in enumerate(frames):
        name, image = _as_image(frame, k)
        if shape is not None and image.shape != shape:
            raise InputError(f"{name}: {image.shape} pixels, the first frame has {shape}")
        shape = image.shape
        if sensor is not None and shape != (sensor.detector.rows, sensor.detector.columns):
            det = sensor.detector
            raise InputError(
                f"{name}: {shape[1]} x {shape[0]} pixels, but sensor {sensor.name!r} has "
                f"{det.columns} x {det.rows}"
            )
        sol = solver(image, obs_time) if solver is not None else unknown(image, obs_time)
        if not sol.solved:
            skipped[name] = sol.status
            continue
        cat = solver.catalog if solver is not None else unknown.catalog
        stars = frame_stars(sol, cat, name)
        ids = np.array([c for _, c in sol.matches], dtype=np.int64)
        mags = cat.mags.get("V")
        mags_v = (
            np.full(len(ids), np.nan)
            if mags is None
            else np.asarray(mags, dtype=float)[cat.index_of(ids)]
        )
        solved.append(SolvedFrame(name, image, sol, stars, mags_v))
    return solved, skipped


def nominal_sensor(solved: list[SolvedFrame]) -> Sensor:
    """Return a sensor for a camera known only by its frames: the field solved, placeholders.

    The focal length in pixels is the median of the solutions'; the pixel pitch is
    :data:`NOMINAL_PITCH_M` and the aperture that of f/:data:`NOMINAL_F_NUMBER` (neither can be
    told from frames); the radial distortion found by the solver starts the calibration.
    """
    rows, columns = solved[0].image.shape
    f_px = float(np.median([s.solution.focal_px for s in solved]))
    k1 = [s.solution.distortion.get("k1") or 0.0 for s in solved if s.solution.distortion]
    k2 = [s.solution.distortion.get("k2") or 0.0 for s in solved if s.solution.distortion]
    focal_m = f_px * NOMINAL_PITCH_M
    bits = 8 if solved[0].image.dtype == np.uint8 else 16
    optics = Optics(
        focal_length_m=focal_m,
        aperture_m=focal_m / NOMINAL_F_NUMBER,
        distortion_k1=float(np.median(k1)) if k1 else 0.0,
        distortion_k2=float(np.median(k2)) if k2 else 0.0,
    )
    detector = Detector(
        columns=columns,
        rows=rows,
        pixel_pitch_m=NOMINAL_PITCH_M,
        gain_counts_per_e=1.0,
        read_noise_e=1.0,
        bit_depth=bits,
        psf_sigma_px=1.0,
    )
    logic = DetectionThresholds(lit_pixel_counts=1.0, min_pixels=3, min_integrated_counts=1.0)
    return Sensor(
        name="camera",
        optics=optics,
        detector=detector,
        exposure_s=1.0,
        detection=logic,
        description="a camera characterised from its frames (no base sensor given)",
    )


def corner_radius_px(sensor: Sensor) -> float:
    """Distance from the detector centre to a corner pixel's centre, px."""
    det = sensor.detector
    return math.hypot(0.5 * (det.columns - 1), 0.5 * (det.rows - 1))
