"""Camera calibration from star fields: focal length, principal point and lens distortion.

The matched stars of one or several solved frames are fitted jointly
(``scipy.optimize.least_squares``): the camera model is shared, each frame's attitude is a
nuisance parameter. A star's predicted pixel is

``(x, y) = c + f D(A v)``,  ``D`` the gnomonic projection followed by Brown-Conrady
distortion (:mod:`starsense.geometry.distortion`)

with ``v`` its catalogue (or apparent) direction, ``A = R(delta_k) A0_k`` frame k's attitude
(``A0_k`` from the solver, ``delta_k`` a small rotation vector), ``f`` the focal length in pixels
and ``c`` the principal point. The residuals are measured minus predicted pixels; the
parameters' covariance is ``s^2 (J^T J)^-1`` at the solution, ``s^2`` the residual variance per
degree of freedom. Stars more than ``clip_sigma`` times the rms off are dropped and the fit
repeated (a mismatched or blended star would otherwise pull it).

A parameter the stars cannot constrain raises :class:`~starsense.errors.InputError` naming it:
when the design is rank-deficient (too few stars, or a distribution that leaves it free, such
as all stars near the centre for the radial terms), or when its 1-sigma effect at the detector
corner exceeds ``edge_tolerance_px``. Fix it (leave it out of ``fit``) to fit the others.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import show
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.geometry.distortion import distort
from starsense.sensor import Sensor, load_sensor
from starsense.solve.calibration_frames import (
    FrameSolver,
    FrameStars,
    frame_list,
    frame_stars,
    matched_stars,
)
from starsense.units import RAD_TO_ARCSEC

__all__ = ["PARAMETERS", "Calibration", "FrameSolver", "FrameStars", "calibrate", "frame_stars"]

#: the camera parameters that can be fitted, by the names ``fit`` takes
PARAMETERS = ("focal_length", "principal_point", "k1", "k2", "p1", "p2")
#: the scalar unknowns behind each name: index into (f_px, dx_px, dy_px, k1, k2, p1, p2)
_SCALARS = {
    "focal_length": (0,),
    "principal_point": (1, 2),
    "k1": (3,),
    "k2": (4,),
    "p1": (5,),
    "p2": (6,),
}
_SCALAR_NAMES = ("focal_length_px", "principal_x_px", "principal_y_px", "k1", "k2", "p1", "p2")


@dataclass(frozen=True, eq=False)
class Calibration:
    """A fitted camera model with its uncertainty.

    Attributes
    ----------
    sensor : Sensor
        The input sensor with the fitted optics.
    fitted : tuple of str
        The parameters fitted (names from :data:`PARAMETERS`).
    values, sigmas : dict
        Value and 1-sigma uncertainty of every scalar unknown (``focal_length_px``,
        ``principal_x_px`` / ``principal_y_px`` (offsets from the detector centre), ``k1``,
        ``k2``, ``p1``, ``p2``); sigma 0 for those held fixed.
    covariance : ndarray, shape (P, P)
        Covariance of the fitted scalars, in the order of ``scalar_names``.
    scalar_names : tuple of str
    rotations : list of Rotation
        Each frame's fitted attitude.
    n_frames, n_stars, n_rejected : int
        Frames and stars used; stars dropped as outliers.
    rms_px_before, rms_px_after : float
        Rms residual per axis of the stars used, px, with the input sensor (attitudes re-fitted)
        and with the fitted one.
    rms_arcsec_before, rms_arcsec_after : float
        The same as angles (total, both axes), arcsec.
    """

    sensor: object
    fitted: tuple[str, ...]
    values: dict
    sigmas: dict
    covariance: np.ndarray
    scalar_names: tuple[str, ...]
    rotations: list
    n_frames: int
    n_stars: int
    n_rejected: int
    rms_px_before: float
    rms_px_after: float
    rms_arcsec_before: float
    rms_arcsec_after: float

    def to_dict(self) -> dict:
        """JSON-ready summary (the CLI's output)."""
        o = self.sensor.optics
        dist = {k: self.values[k] for k in ("k1", "k2", "p1", "p2")}
        return {
            "frames": self.n_frames,
            "stars": self.n_stars,
            "rejected": self.n_rejected,
            "fitted": list(self.fitted),
            "focal_length_m": o.focal_length_m,
            "focal_length_sigma_m": self.sigmas["focal_length_px"]
            * self.sensor.detector.pixel_pitch_m,
            "principal_point_px": list(self.sensor.principal_point_px),
            "principal_point_sigma_px": [
                self.sigmas["principal_x_px"],
                self.sigmas["principal_y_px"],
            ],
            "distortion": dist,
            "distortion_sigma": {k: self.sigmas[k] for k in dist},
            "residual_rms_px_before": self.rms_px_before,
            "residual_rms_px_after": self.rms_px_after,
            "residual_rms_arcsec_before": self.rms_arcsec_before,
            "residual_rms_arcsec_after": self.rms_arcsec_after,
        }


def _initial(sensor) -> np.ndarray:
    o = sensor.optics
    return np.array(
        [
            sensor.focal_length_px,
            o.principal_offset_x_px,
            o.principal_offset_y_px,
            o.distortion_k1,
            o.distortion_k2,
            o.distortion_p1,
            o.distortion_p2,
        ]
    )


def _sensor_with(sensor, cam: np.ndarray):
    """Return the sensor with camera scalars ``cam`` (f_px, dx, dy, k1, k2, p1, p2)."""
    optics = dataclasses.replace(
        sensor.optics,
        focal_length_m=float(cam[0] * sensor.detector.pixel_pitch_m),
        principal_offset_x_px=float(cam[1]),
        principal_offset_y_px=float(cam[2]),
        distortion_k1=float(cam[3]),
        distortion_k2=float(cam[4]),
        distortion_p1=float(cam[5]),
        distortion_p2=float(cam[6]),
    )
    return sensor.with_(optics=optics)


class _Problem:
    """The stacked stars of all frames and the residual function of the joint fit."""

    def __init__(self, frames: Sequence[FrameStars], sensor, free: np.ndarray) -> None:
        self.frame_of = np.concatenate(
            [np.full(len(f.vectors), k, dtype=np.intp) for k, f in enumerate(frames)]
        )
        self.xy = np.concatenate([f.centroids_px for f in frames]).astype(float)
        self.v = np.concatenate([f.vectors for f in frames]).astype(float)
        self.r0 = Rotation.concatenate([f.rotation for f in frames])
        self.n_frames = len(frames)
        det = sensor.detector
        self.centre = np.array([(det.columns - 1) / 2.0, (det.rows - 1) / 2.0])
        self.cam0 = _initial(sensor)
        self.free = free  # indices of the fitted camera scalars
        self.keep = np.ones(len(self.v), dtype=bool)

    def unpack(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cam = self.cam0.copy()
        cam[self.free] = theta[: self.free.size]
        return cam, theta[self.free.size :].reshape(self.n_frames, 3)

    def predict(self, theta: np.ndarray, keep=None) -> np.ndarray:
        """Predicted pixels (N, 2) of the stars ``keep`` (all kept stars by default)."""
        keep = self.keep if keep is None else keep
        cam, deltas = self.unpack(theta)
        k = self.frame_of[keep]
        rot = Rotation.from_rotvec(deltas[k]) * self.r0[k]
        c = rot.apply(self.v[keep])
        xd, yd = distort(c[:, 0] / c[:, 2], c[:, 1] / c[:, 2], cam[3:])
        return np.column_stack([xd, yd]) * cam[0] + self.centre + cam[1:3]

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        return (self.xy[self.keep] - self.predict(theta)).ravel()


def _check_rank(jac: np.ndarray, names: list[str], n_free: int) -> None:
    """Raise naming the parameter a rank-deficient design leaves free."""
    norms = np.linalg.norm(jac, axis=0)
    if np.any(norms == 0):
        j = int(np.argmin(norms))
        raise InputError(f"{names[j]} cannot be fitted: the stars do not depend on it")
    _, s, vt = np.linalg.svd(jac / norms, full_matrices=True)
    rank = int(np.sum(s > s[0] * 1e-9))
    if rank < jac.shape[1]:
        null = vt[-1]
        j = int(np.argmax(np.abs(null[:n_free]))) if n_free else 0
        m, n = jac.shape
        why = (
            f"{m // 2} stars give {m} residuals for {n} unknowns"
            if m < n
            else "the stars' distribution leaves it free"
        )
        raise InputError(f"{names[j]} cannot be fitted: {why}; hold it fixed (fit=...)")


def _edge_effect(sensor, cam: np.ndarray) -> np.ndarray:
    """Pixel displacement at the detector corner per unit of each camera scalar.

    A principal-point shift is taken up by the attitude to first order; what is left is the
    perspective term, about ``2 r^2`` per pixel of shift (r the corner's tangent).
    """
    det = sensor.detector
    f = cam[0]
    r = math.hypot(det.columns / 2.0, det.rows / 2.0) / f  # tan of the corner's angle
    return np.array([r, 2 * r**2, 2 * r**2, f * r**3, f * r**5, 3 * f * r**2, 3 * f * r**2])


def _rms(res: np.ndarray) -> float:
    return float(np.sqrt(np.mean(res**2))) if res.size else float("nan")


def _fit_attitudes_only(problem: _Problem) -> np.ndarray:
    """Residuals with the input camera, attitudes re-fitted (the 'before' numbers)."""
    from scipy.optimize import least_squares

    saved = problem.free
    problem.free = np.zeros(0, dtype=np.intp)
    res = least_squares(problem.residuals, np.zeros(3 * problem.n_frames), x_scale="jac")
    problem.free = saved
    return res.fun


def calibrate(
    frames: Sequence,
    sensor,
    *,
    catalog: Catalog | str = "hipparcos",
    fit: Sequence[str] = PARAMETERS,
    clip_sigma: float = 5.0,
    edge_tolerance_px: float = 2.0,
) -> Calibration:
    """Fit the camera model to the matched stars of solved frames, jointly (module docstring).

    Parameters
    ----------
    frames : sequence of FrameStars, Solution, ndarray or path
        One or more frames: their matched stars (:func:`frame_stars`), their solutions, or the
        frames themselves (images or image files, solved here with :class:`FrameSolver`: the
        sensor, else nothing known). A frame that is not solved raises :class:`InputError`
        naming it.
    sensor : Sensor, str or Path
        The starting camera model, a preset name or a TOML file (its fixed parameters stay as
        they are).
    catalog : Catalog or str
        The catalogue the solutions' matches refer to (default: the bundled Hipparcos).
    fit : sequence of str
        Parameters to fit, from :data:`PARAMETERS`.
    clip_sigma : float
        Stars whose residual exceeds this many rms (per axis) are dropped and the fit repeated.
    edge_tolerance_px : float
        A fitted parameter whose 1-sigma effect at the detector corner exceeds this, px, is
        refused as not determined by the stars.

    Returns
    -------
    Calibration

    Raises
    ------
    InputError
        Unknown parameter names; no frames; a parameter the stars cannot constrain (named).
    """
    fit = (fit,) if isinstance(fit, str) else fit
    if not isinstance(fit, Iterable):
        raise InputError(f"fit must name some of {', '.join(PARAMETERS)}, got {show(fit)}")
    fit = tuple(fit)
    frames = frame_list(frames)
    unknown = [p for p in fit if p not in PARAMETERS]
    if unknown or not fit:
        raise InputError(f"fit must name some of {', '.join(PARAMETERS)}, got {list(fit)!r}")
    twice = sorted({p for p in fit if fit.count(p) > 1})
    if twice:
        raise InputError(f"fit lists {', '.join(twice)} twice: name each parameter once")
    if not frames:
        raise InputError("calibrate needs at least one solved frame")
    if not isinstance(sensor, Sensor):
        sensor = load_sensor(sensor)
    if not all(isinstance(f, FrameStars) for f in frames):
        frames = matched_stars(frames, sensor, catalog)
    free = np.array(sorted(i for p in fit for i in _SCALARS[p]), dtype=np.intp)
    names = [_SCALAR_NAMES[i] for i in free] + [
        f"attitude of {f.name or f'frame {k}'}" for k, f in enumerate(frames) for _ in range(3)
    ]
    problem = _Problem(frames, sensor, free)
    n_unknowns = free.size + 3 * len(frames)
    if 2 * len(problem.v) <= n_unknowns:
        m = 2 * len(problem.v)
        raise InputError(
            f"{names[free.size - 1]} cannot be fitted: {len(problem.v)} stars give {m} "
            f"residuals for {n_unknowns} unknowns ({free.size} camera, 3 per frame)"
        )
    from scipy.optimize import least_squares

    theta = np.concatenate([problem.cam0[free], np.zeros(3 * len(frames))])
    rejected = 0
    for attempt in range(4):
        res = least_squares(problem.residuals, theta, x_scale="jac", method="trf")
        _check_rank(res.jac, names, free.size)
        theta = res.x
        r = res.fun.reshape(-1, 2)
        rms = _rms(r)
        bad = np.linalg.norm(r, axis=1) > clip_sigma * rms * math.sqrt(2.0)
        if not bad.any() or attempt == 3:
            break
        idx = np.flatnonzero(problem.keep)
        problem.keep[idx[bad]] = False
        rejected += int(bad.sum())
    dof = max(res.fun.size - theta.size, 1)
    s2 = float(res.fun @ res.fun) / dof
    cov_all = np.linalg.pinv(res.jac.T @ res.jac) * s2
    cov = cov_all[: free.size, : free.size]
    cam, deltas = problem.unpack(theta)
    sig = np.zeros(7)
    sig[free] = np.sqrt(np.diag(cov))
    edge = sig * _edge_effect(sensor, cam)
    if np.any(edge > edge_tolerance_px):
        j = int(np.argmax(edge))
        raise InputError(
            f"{_SCALAR_NAMES[j]} cannot be fitted from these stars: its 1-sigma effect at the "
            f"detector corner is {edge[j]:.2g} px (> {edge_tolerance_px:g}); hold it fixed"
        )
    before = _fit_attitudes_only(problem).reshape(-1, 2)
    new = _sensor_with(sensor, cam)
    rots = [Rotation.from_rotvec(deltas[k]) * f.rotation for k, f in enumerate(frames)]
    f_px = float(cam[0])
    return Calibration(
        sensor=new,
        fitted=fit,
        values=dict(zip(_SCALAR_NAMES, (float(c) for c in cam), strict=True)),
        sigmas=dict(zip(_SCALAR_NAMES, (float(s) for s in sig), strict=True)),
        covariance=cov,
        scalar_names=tuple(_SCALAR_NAMES[i] for i in free),
        rotations=rots,
        n_frames=len(frames),
        n_stars=int(problem.keep.sum()),
        n_rejected=rejected,
        rms_px_before=_rms(before),
        rms_px_after=_rms(res.fun),
        rms_arcsec_before=_rms(before) * math.sqrt(2.0) / sensor.focal_length_px * RAD_TO_ARCSEC,
        rms_arcsec_after=_rms(res.fun) * math.sqrt(2.0) / f_px * RAD_TO_ARCSEC,
    )
