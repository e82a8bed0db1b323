"""Tracking mode: a frame and a prior attitude in, an attitude (and over a sequence a rate) out.

:func:`track_frame` predicts where the database stars fall from the prior
(propagated by its rate, :func:`starsense.attitude.rate.predict_attitude`), detects stars only in
windows around the brightest of them (:mod:`starsense.detect.windows`), matches and verifies with
:class:`~starsense.identify.tracking.TrackingIdentifier`, and estimates the attitude with its
covariance from every matched star (SVD, Fialho & Mortari 2019 eq. 21). When the match fails or
is ambiguous it falls back to lost-in-space (the Solver itself) and says so in the message.

:class:`~starsense.solve.tracking.tracker.Tracker` runs a sequence of frames.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Literal, TypeAlias

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import positive_float
from starsense.attitude.rate import predict_attitude
from starsense.detect.streak import columns
from starsense.detect.windows import streak_px
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll, radec_roll_from_matrix
from starsense.solve.solution import Deferred, Solution, SolveStatus, allow_deferred
from starsense.solve.tracking.field import half_turn, predicted_field, tracking_setup, unblended
from starsense.solve.tracking.star_noise import fit_robust_matrix, rms_angle, star_noise
from starsense.units import DEG, RAD_TO_DEG

__all__ = ["Prior", "TrackMode", "TrackSolution", "track_frame"]

#: How a tracked frame was solved: from the prior, or lost-in-space (the prior failed or none).
TrackMode: TypeAlias = Literal["tracking", "lost_in_space"]

#: Prior uncertainty above which no windows are used (the whole frame is searched), rad.
N_SIGMA_SEARCH = 5.0
#: Smallest search radius, px: a prior is never trusted to better than this.
MIN_SEARCH_PX = 3.0
#: Largest search radius of tracking, rad (a worse prior goes to lost-in-space directly).
MAX_SEARCH_RAD = 2.0 * DEG
#: Windows around at most this many predicted stars.
MAX_WINDOWS = 30


@dataclass(frozen=True)
class Prior:
    """What is known before a frame: an attitude with its uncertainty, and optionally a rate.

    Attributes
    ----------
    rotation : Rotation
        Attitude (ICRS -> camera) at ``dt_s`` before the frame's mid-exposure.
    cov_rad2 : ndarray, shape (3, 3)
        Its camera-frame covariance, rad^2.
    rate_rad_s : ndarray, shape (3,) or None
        Body rate, camera frame, rad/s.
    rate_cov_rad2_s2 : ndarray, shape (3, 3) or None
        Its covariance, (rad/s)^2.
    dt_s : float
        Time from the prior to the frame, s.
    rate_sign_known : bool
        False for a rate from one frame's streaks
        (:mod:`starsense.solve.tracking.streak_rate`), which fix the rate up to its sign: both
        signs are tried.
    """

    rotation: Rotation
    cov_rad2: np.ndarray
    rate_rad_s: np.ndarray | None = None
    rate_cov_rad2_s2: np.ndarray | None = None
    dt_s: float = 0.0
    rate_sign_known: bool = True

    @classmethod
    def from_radec_roll(
        cls, ra_rad: float, dec_rad: float, roll_rad: float, *, sigma_rad: float
    ) -> Prior:
        """Return a prior at (RA, Dec, roll), rad, with an isotropic 1-sigma ``sigma_rad``."""
        s = positive_float(sigma_rad, "sigma_rad")
        return cls(attitude_from_radec_roll(ra_rad, dec_rad, roll_rad), np.eye(3) * s * s)

    def predicted(self) -> tuple[Rotation, np.ndarray]:
        """Return the attitude and covariance at the frame (:func:`predict_attitude`)."""
        return predict_attitude(
            self.rotation,
            self.dt_s,
            rate_rad_s=self.rate_rad_s,
            cov_rad2=self.cov_rad2,
            rate_cov_rad2_s2=self.rate_cov_rad2_s2,
        )


@dataclass(frozen=True)
class TrackSolution:
    """One frame of tracking: the :class:`Solution`, how it was found, the rate.

    Attributes
    ----------
    solution : Solution
        Attitude, matches, residuals (``status`` "solved" when verified, "unverified" for a
        two-star or unverified track, else why not).
    mode : TrackMode
        "tracking" or "lost_in_space" (for an unreadable frame, the mode it would have been
        processed in).
    covariance_rad2 : ndarray, shape (3, 3) or None
        Camera-frame attitude covariance, rad^2 (of a tracked frame: computed when first read,
        as the solution's RA/Dec/roll, ``sigma_rad`` and ``rotation``).
    rate_rad_s, rate_cov_rad2_s2 : ndarray or None
        Body rate (3,), rad/s, and its covariance (3, 3), from this frame and the last solved.
    time_s : float or None
        The frame's time in the sequence, s.
    image : str
        The frame's file, when read from one.
    """

    solution: Solution
    mode: TrackMode
    covariance_rad2: np.ndarray | None = field(default=None, repr=False)
    rate_rad_s: np.ndarray | None = None
    rate_cov_rad2_s2: np.ndarray | None = field(default=None, repr=False)
    time_s: float | None = None
    image: str = ""

    @property
    def status(self) -> SolveStatus:
        """The solution's status ("solved", "unverified", or why not)."""
        return self.solution.status

    @property
    def has_attitude(self) -> bool:
        """Whether the frame has an attitude (verified or not)."""
        return self.solution.rotation is not None

    def to_dict(self) -> dict:
        """JSON-ready: the CLI's line (degrees, deg/s, arcsec)."""
        s = self.solution
        rate = None if self.rate_rad_s is None else [float(v * RAD_TO_DEG) for v in self.rate_rad_s]
        rate_sigma = None
        if self.rate_cov_rad2_s2 is not None:
            var = np.maximum(np.diag(self.rate_cov_rad2_s2), 0.0)
            rate_sigma = [float(v) for v in np.sqrt(var) * RAD_TO_DEG]
        sigma = s.sigma_arcsec
        return {
            "image": self.image,
            "status": s.status,
            "mode": self.mode,
            "ra_deg": s.ra_deg,
            "dec_deg": s.dec_deg,
            "roll_deg": s.roll_deg,
            "rate_deg_s": rate,
            "rate_sigma_deg_s": rate_sigma,
            "sigma_arcsec": None if sigma is None else list(sigma),
            "n_detections": s.n_detections,
            "n_matched": s.n_matched,
            "false_match_probability": s.false_match_probability,
            "time_s": self.time_s,
            "time_ms": s.time_ms,
            "message": s.message,
        }


allow_deferred(TrackSolution, "covariance_rad2")


def _search_radius(cov: np.ndarray, field_radius: float) -> float:
    """Return a star's possible displacement at the field edge, N_SIGMA_SEARCH sigma, rad."""
    cross = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    roll = math.sqrt(max(cov[2, 2], 0.0)) * math.sin(field_radius)
    return N_SIGMA_SEARCH * (cross + roll)


def _track_core(solver, image, rot_pred, cov_pred, rate, t0):
    """Window detection, matching and the attitude fit; (Solution, covariance) or a failure."""
    sensor = solver.sensor
    setup = tracking_setup(solver)
    db, field_r, f = setup.db, setup.field_r, sensor.focal_length_px
    r_s = max(_search_radius(cov_pred, field_r), MIN_SEARCH_PX / f)
    if r_s > MAX_SEARCH_RAD:
        return None, f"prior uncertainty {r_s * RAD_TO_DEG:.2f} deg exceeds tracking's reach"
    turn = half_turn(sensor, rate)
    prior_matrix = rot_pred.as_matrix()
    near, x, y, margin_on, streaks = predicted_field(
        sensor, db, prior_matrix, r_s=r_s, field_r=field_r, half_turn_matrix=turn
    )
    on = (x >= 0) & (x <= sensor.detector.columns - 1) & (y >= 0)
    on &= y <= sensor.detector.rows - 1
    # the longest streak: at a field corner (streak_px's default, corners computed once)
    longest = 0.0 if turn is None else float(streak_px(sensor, rate, setup.corners).max())
    reach_px = r_s * f + 0.5 * longest + 4 * sensor.detector.psf_sigma_px
    centres = columns(x[on], y[on])[:MAX_WINDOWS]
    found = setup.windows(
        np.asarray(image),
        centres,
        half_px=math.ceil(reach_px + 4),
        streaks_px=None if streaks is None else streaks[on][:MAX_WINDOWS],
    )
    det = found.detections
    stages = {"detect_ms": (time.perf_counter() - t0) * 1e3}
    if len(det) < 2:
        return None, f"{len(det)} star(s) found where the prior puts them"
    vectors = sensor.unproject(det.x, det.y)
    # the brightest stars that may be on the detector: a frame showing N stars shows about
    # the N brightest, and fewer candidates leave fewer ambiguous pairs
    cand = margin_on.nonzero()[0][: max(3 * len(det), 10)]
    n_in = found.count_inside(x[cand], y[cand])
    region = None if n_in < 0 else (found.region_px / f**2, max(n_in, 1))
    # unit, finite, in front of the camera (the sensor's unprojection): normalised as the
    # identifier's own check does, its other checks skipped
    unit = vectors / np.sqrt(np.add.reduce(vectors * vectors, axis=1))[:, None]
    match = setup.identifier.match_checked(
        unit,
        prior_matrix,
        search_radius_rad=r_s,
        field_radius_rad=field_r,
        region=region,
        candidates=near[cand],
    )
    if not match.solved:
        return None, f"tracking {match.status}: {match.message}"
    matched, cat_index, cat_ids = match.detection_index, match.catalog_index, match.catalog_id
    blend_px = 2.0 * (2.5 * sensor.detector.psf_sigma_px + 1.0) + longest
    alone = unblended(cat_index, near, x=x, y=y, blend_px=blend_px)
    if alone.sum() >= 2:
        matched, cat_index, cat_ids = matched[alone], cat_index[alone], cat_ids[alone]
    body = vectors[matched]
    noise = star_noise(
        solver,
        det,
        matched,
        rate_rad_s=rate,
        vectors=body,
        half_turn=turn,
        margin_px=setup.margin_px,
    )
    c, fisher_inv, resid, _, keep = fit_robust_matrix(body, db.vectors[cat_index], noise.sigma_rad)
    matched, cat_ids = matched[keep], cat_ids[keep]
    covariance = _Once(_covariance, noise, keep, body[keep], fisher_inv)
    stages["match_ms"] = match.time_ms
    rotation = _Once(Rotation.from_matrix, c, assume_valid=True)  # c: an SVD's U V^T
    angles = _Once(_radec_roll, rotation)
    where = f"{found.n_windows} windows" if found.n_windows else "the whole frame"
    sol = Solution(
        "solved" if match.status == "verified" else "unverified",
        f"tracked: {len(matched)} of {len(det)} detections ({where}) matched, "
        f"P_false {match.false_match_probability:.1e}",
        ra_rad=Deferred(angles, index=0),
        dec_rad=Deferred(angles, index=1),
        roll_rad=Deferred(angles, index=2),
        fov_rad=setup.fov_rad,
        n_detections=len(det),
        n_matched=len(matched),
        rmse_rad=rms_angle(resid),
        false_match_probability=float(match.false_match_probability),
        sigma_rad=Deferred(_Once(_sigmas, covariance)),
        time_ms=(time.perf_counter() - t0) * 1e3,
        stage_ms=stages,
        rotation=Deferred(rotation),
        matches=Deferred(_Once(_pairs, matched, cat_ids)),
        centroids_px=Deferred(_Once(columns, det.x, det.y)),
        image_shape=image.shape,
        focal_px=f,
    )
    return (sol, Deferred(covariance)), ""


class _Once:
    """``fn(*args, **kw)``, called on the first call of this object only (then its value)."""

    __slots__ = ("call", "value")

    def __init__(self, fn, *args, **kw) -> None:
        self.call = (fn, args, kw)

    def __call__(self):
        if self.call is not None:
            fn, args, kw = self.call
            self.value, self.call = fn(*args, **kw), None
        return self.value


def _radec_roll(rotation: _Once) -> tuple[float, float, float]:
    # radec_roll_from_attitude(rotation()), bit for bit
    return radec_roll_from_matrix(rotation().as_matrix())


def _covariance(noise, keep, body, fisher_inv) -> np.ndarray:
    return noise.subset(keep).attitude_covariance(body, fisher_inv)


def _pairs(matched: np.ndarray, cat_ids: np.ndarray) -> tuple[tuple[int, int], ...]:
    return tuple(zip(matched.tolist(), cat_ids.tolist(), strict=True))


def _sigmas(covariance: _Once) -> tuple[float, float, float]:
    return tuple(np.sqrt(covariance().diagonal()).tolist())


def _done(sol: Solution, t0: float) -> Solution:
    return dataclasses.replace(sol, time_ms=(time.perf_counter() - t0) * 1e3)


def track_frame(solver, image, prior: Prior | None) -> TrackSolution:
    """Track one frame from a prior; fall back to lost-in-space when the match fails.

    Parameters
    ----------
    solver : Solver
        Configured with a sensor (known optics).
    image : array_like, shape (rows, columns)
        The frame, counts.
    prior : Prior or None
        None: lost-in-space.

    Returns
    -------
    TrackSolution
        ``mode`` "tracking" when the prior's match stood, else "lost_in_space" with the reason
        tracking failed at the head of the message.
    """
    if solver.sensor is None:
        raise InputError("tracking needs a sensor (known optics): give Solver(sensor=...)")
    t0 = time.perf_counter()
    image = np.asarray(image)
    reason = "no prior"
    if prior is not None:
        priors = [prior]
        if not prior.rate_sign_known and prior.rate_rad_s is not None:
            priors.append(dataclasses.replace(prior, rate_rad_s=-np.asarray(prior.rate_rad_s)))
        for candidate in priors:
            rot_pred, cov_pred = candidate.predicted()
            rate = candidate.rate_rad_s
            out, reason = _track_core(solver, image, rot_pred, cov_pred, rate, t0)
            if out is not None and out[0].status == "solved":
                return TrackSolution(out[0], "tracking", out[1])  # timed from t0 in the core
        unverified = out
        reason = reason or "tracking unverified: " + out[0].message
    else:
        unverified, rate = None, None
    lis = solver(image)
    if lis.solved:
        # the attitude covariance of the same estimator and star set as tracking
        cov = np.diag(np.square(lis.sigma_rad)) * 9.0
        refined, _ = _track_core(solver, image, lis.rotation, cov, rate, time.perf_counter())
        if refined is not None and refined[0].status == "solved":
            sol, covariance = refined
        else:
            sol, covariance = lis, np.diag(np.square(lis.sigma_rad))
        # the message of the solution kept: its counts are the ones n_matched / n_detections hold
        msg = f"{reason}; lost-in-space: {sol.message}"
        return TrackSolution(
            _done(dataclasses.replace(sol, message=msg), t0), "lost_in_space", covariance
        )
    if unverified is not None:  # keep the unverified track rather than nothing
        sol = dataclasses.replace(
            unverified[0], message=unverified[0].message + f"; lost-in-space failed ({lis.status})"
        )
        return TrackSolution(_done(sol, t0), "tracking", unverified[1])
    msg = f"{reason}; lost-in-space: {lis.status}: {lis.message}"
    return TrackSolution(_done(dataclasses.replace(lis, message=msg), t0), "lost_in_space")
