"""Tracking mode: a frame and a prior attitude in, an attitude (and over a sequence a rate) out.

:func:`track_frame` (``Solver.track``) predicts where the database stars fall from the prior
(propagated by its rate, :func:`starsense.attitude.rate.predict_attitude`), detects stars only in
windows around the brightest of them (:mod:`starsense.solve.windows`), matches and verifies with
:class:`~starsense.identify.tracking.TrackingIdentifier`, and estimates the attitude with its
covariance from every matched star (SVD, Fialho & Mortari 2019 eq. 21). When the match fails or
is ambiguous it falls back to lost-in-space (the Solver itself) and says so in the message.

:class:`Tracker` runs a sequence: the first frame lost-in-space (unless a prior is given), each
later one tracked from the last solved attitude, and the body rate from consecutive attitudes
with its covariance (:func:`starsense.attitude.rate.rate_from_attitudes`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.errors import InputError, StarsenseError
from starsense.solve.solver import Solution
from starsense.solve.streak_centroid import columns
from starsense.solve.track_field import _half_turn, _predicted_field, _setup, _unblended
from starsense.units import DEG, RAD_TO_DEG

__all__ = ["Prior", "TrackSolution", "Tracker", "track_frame"]

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
        False for a rate from one frame's streaks (:mod:`starsense.solve.streak_rate`), which
        fix the rate up to its sign: both signs are tried.
    """

    rotation: Rotation
    cov_rad2: np.ndarray
    rate_rad_s: np.ndarray | None = None
    rate_cov_rad2_s2: np.ndarray | None = None
    dt_s: float = 0.0
    rate_sign_known: bool = True

    @classmethod
    def from_radec_roll(
        cls, ra_rad: float, dec_rad: float, roll_rad: float, sigma_rad: float
    ) -> Prior:
        """Return a prior at (RA, Dec, roll), rad, with an isotropic 1-sigma ``sigma_rad``."""
        from starsense._validate import positive_float
        from starsense.geometry.attitude import attitude_from_radec_roll

        s = positive_float(sigma_rad, "sigma_rad")
        return cls(attitude_from_radec_roll(ra_rad, dec_rad, roll_rad), np.eye(3) * s * s)

    def predicted(self) -> tuple[Rotation, np.ndarray]:
        """Return the attitude and covariance at the frame (:func:`predict_attitude`)."""
        from starsense.attitude.rate import predict_attitude

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
    mode : str
        "tracking" or "lost_in_space" (for an unreadable frame, the mode it would have been
        processed in).
    covariance_rad2 : ndarray, shape (3, 3) or None
        Camera-frame attitude covariance, rad^2.
    rate_rad_s, rate_cov_rad2_s2 : ndarray or None
        Body rate (3,), rad/s, and its covariance (3, 3), from this frame and the last solved.
    time_s : float or None
        The frame's time in the sequence, s.
    image : str
        The frame's file, when read from one.
    """

    solution: Solution
    mode: str
    covariance_rad2: np.ndarray | None = field(default=None, repr=False)
    rate_rad_s: np.ndarray | None = None
    rate_cov_rad2_s2: np.ndarray | None = field(default=None, repr=False)
    time_s: float | None = None
    image: str = ""

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


def _search_radius(cov: np.ndarray, field_radius: float) -> float:
    """Return a star's possible displacement at the field edge, N_SIGMA_SEARCH sigma, rad."""
    cross = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    roll = math.sqrt(max(cov[2, 2], 0.0)) * math.sin(field_radius)
    return N_SIGMA_SEARCH * (cross + roll)


def _track_core(solver, image, rot_pred, cov_pred, rate, t0):
    """Window detection, matching and the attitude fit; (Solution, covariance) or a failure."""
    from starsense.geometry.attitude import radec_roll_from_attitude
    from starsense.solve.star_noise import fit_robust, star_noise
    from starsense.solve.windows import detect_in_windows, streak_px

    sensor = solver.sensor
    setup = _setup(solver)
    db, field_r, f = setup.db, setup.field_r, sensor.focal_length_px
    r_s = max(_search_radius(cov_pred, field_r), MIN_SEARCH_PX / f)
    if r_s > MAX_SEARCH_RAD:
        return None, f"prior uncertainty {r_s * RAD_TO_DEG:.2f} deg exceeds tracking's reach"
    half_turn = _half_turn(sensor, rate)
    near, x, y, margin_on, streaks = _predicted_field(sensor, db, rot_pred, r_s, field_r, half_turn)
    on = (x >= 0) & (x <= sensor.detector.columns - 1) & (y >= 0)
    on &= y <= sensor.detector.rows - 1
    # the longest streak: at a field corner (streak_px's default, corners computed once)
    longest = 0.0 if half_turn is None else float(streak_px(sensor, rate, setup.corners).max())
    reach_px = r_s * f + 0.5 * longest + 4 * sensor.detector.psf_sigma_px
    centres = columns(x[on], y[on])[:MAX_WINDOWS]
    found = detect_in_windows(
        solver,
        np.asarray(image),
        centres,
        math.ceil(reach_px + 4),
        None if streaks is None else streaks[on][:MAX_WINDOWS],
    )
    det = found.detections
    stages = {"detect_ms": (time.perf_counter() - t0) * 1e3}
    if len(det) < 2:
        return None, f"{len(det)} star(s) found where the prior puts them"
    vectors = sensor.unproject(det.x, det.y)
    # the brightest stars that may be on the detector: a frame showing N stars shows about
    # the N brightest, and fewer candidates leave fewer ambiguous pairs
    cand = np.flatnonzero(margin_on)[: max(3 * len(det), 10)]
    n_in = found.count_inside(x[cand], y[cand])
    region = None if n_in < 0 else (found.region_px / f**2, max(n_in, 1))
    match = setup.identifier(vectors, rot_pred, r_s, field_r, region=region, candidates=near[cand])
    if not match.solved:
        return None, f"tracking {match.status}: {match.message}"
    matched, cat_index, cat_ids = match.detection_index, match.catalog_index, match.catalog_id
    blend_px = 2.0 * (2.5 * sensor.detector.psf_sigma_px + 1.0) + longest
    alone = _unblended(cat_index, near, x, y, blend_px)
    if alone.sum() >= 2:
        matched, cat_index, cat_ids = matched[alone], cat_index[alone], cat_ids[alone]
    noise = star_noise(
        solver,
        det,
        matched,
        rate,
        vectors=vectors[matched],
        half_turn=half_turn,
        margin_px=setup.margin_px,
    )
    att, keep = fit_robust(vectors[matched], db.vectors[cat_index], noise.sigma_rad)
    matched, cat_ids = matched[keep], cat_ids[keep]
    covariance = noise.subset(keep).attitude_covariance(vectors[matched], att.covariance_rad2)
    stages["match_ms"] = match.time_ms
    ra, dec, roll = radec_roll_from_attitude(att.rotation)
    where = f"{found.n_windows} windows" if found.n_windows else "the whole frame"
    sol = Solution(
        "solved" if match.status == "verified" else "unverified",
        f"tracked: {len(matched)} of {len(det)} detections ({where}) matched, "
        f"P_false {match.false_match_probability:.1e}",
        ra_rad=float(ra),
        dec_rad=float(dec),
        roll_rad=float(roll),
        fov_rad=2.0 * sensor.half_fov_rad[0],
        n_detections=len(det),
        n_matched=len(matched),
        rmse_rad=float(att.residual_rms_rad),
        false_match_probability=float(match.false_match_probability),
        sigma_rad=tuple(np.sqrt(covariance.diagonal()).tolist()),
        time_ms=(time.perf_counter() - t0) * 1e3,
        stage_ms=stages,
        rotation=att.rotation,
        matches=tuple(zip(matched.tolist(), cat_ids.tolist(), strict=True)),
        centroids_px=columns(det.x, det.y),
        image_shape=image.shape,
        focal_px=f,
    )
    return (sol, covariance), ""


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
        msg = f"{reason}; lost-in-space: {lis.message}"
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


class Tracker:
    """Track a sequence of frames; the rate from consecutive attitudes (module docstring).

    Parameters
    ----------
    solver : Solver
        With a sensor.
    interval_s : float, optional
        Time between frames, s, when the frames do not say (needed for the rate).
    prior : Prior, optional
        Prior of the first frame (else it is solved lost-in-space).
    max_rate_rad_s : float
        Largest body rate expected before one is measured, rad/s: it sets the search radius of
        the second frame (default 3 deg/s).
    """

    def __init__(
        self,
        solver,
        *,
        interval_s: float | None = None,
        prior: Prior | None = None,
        max_rate_rad_s: float = 3.0 * DEG,
    ) -> None:
        from starsense._validate import positive_float

        if solver.sensor is None:
            raise InputError("tracking needs a sensor (known optics)")
        self.solver = solver
        self.interval_s = None if interval_s is None else positive_float(interval_s, "interval_s")
        self.max_rate_rad_s = positive_float(max_rate_rad_s, "max_rate_rad_s")
        self._prior = prior
        self._last = None  # (time, rotation, covariance)
        self._rate = None  # (rate, covariance): the prior's (a gyro's) until one is measured
        if prior is not None and prior.rate_rad_s is not None:
            cov = prior.rate_cov_rad2_s2
            cov = np.zeros((3, 3)) if cov is None else np.asarray(cov, dtype=float)
            self._rate = (np.asarray(prior.rate_rad_s, dtype=float), cov)
        self._index = 0
        self._t_first = None
        self._streak_rate = None  # (rate, covariance) from one frame's streaks, sign unknown

    def _prior_at(self, t: float | None) -> Prior | None:
        if self._last is None:
            if self._prior is None:
                return None
            # the given prior holds at the first frame: carried to this one (first frame lost)
            if self._t_first is None:
                self._t_first = t
            if t is None or self._t_first is None:
                return self._prior
            return dataclasses.replace(self._prior, dt_s=self._prior.dt_s + t - self._t_first)
        t_last, rot, cov = self._last
        dt = 0.0 if t is None or t_last is None else t - t_last
        if self._rate is not None:
            return Prior(rot, cov, self._rate[0], self._rate[1], dt)
        if self._streak_rate is not None:  # from the last frame's streaks, sign unknown
            return Prior(rot, cov, *self._streak_rate, dt, rate_sign_known=False)
        # no rate yet: anything up to the largest expected rate
        span = self.max_rate_rad_s * (dt if dt > 0 else 1.0)
        return Prior(rot, cov + np.eye(3) * (span / N_SIGMA_SEARCH) ** 2)

    def __call__(self, image, time_s: float | None = None, name: str = "") -> TrackSolution:
        """Track the next frame (array); ``time_s`` default index x interval."""
        from starsense.attitude.rate import rate_from_attitudes

        t = time_s
        if t is None and self.interval_s is not None:
            t = self._index * self.interval_s
        self._index += 1
        result = track_frame(self.solver, image, self._prior_at(t))
        rate = rate_cov = None
        if result.has_attitude and result.covariance_rad2 is not None:
            sol, cov = result.solution, result.covariance_rad2
            if self._last is not None and t is not None and self._last[0] is not None:
                dt = t - self._last[0]
                if dt > 0:
                    rate, rate_cov = rate_from_attitudes(
                        self._last[1], sol.rotation, dt, cov0_rad2=self._last[2], cov1_rad2=cov
                    )
                    self._rate = (rate, rate_cov)
            self._last = (t, sol.rotation, cov)
            if self._rate is None:
                self._streak_rate = self._rate_from_streaks(np.asarray(image), sol)
        return dataclasses.replace(
            result, rate_rad_s=rate, rate_cov_rad2_s2=rate_cov, time_s=t, image=name
        )

    def _rate_from_streaks(self, image: np.ndarray, sol: Solution):
        """Rate (sign unknown) and covariance from the streaks of the 5 brightest matched stars."""
        from starsense.solve.streak_rate import rate_from_streaks, streak_axes
        from starsense.solve.windows import streak_px

        solver, sensor = self.solver, self.solver.sensor
        index = sorted(d for d, _ in sol.matches)[:5]
        if len(index) < 3 or sol.centroids_px is None:
            return None
        xy = sol.centroids_px[index]
        reach = 0.5 * streak_px(sensor, [self.max_rate_rad_s, 0.0, 0.0])
        half = math.ceil(reach + 3.0 * sensor.detector.psf_sigma_px + 4.0)
        known = solver.background == "known"
        axes = streak_axes(
            image,
            xy[:, 0],
            xy[:, 1],
            half,
            solver.logic.lit_pixel_counts,
            level=float(sensor.detector.bias_counts) if known else None,
            threshold_sigma=None if known else solver.threshold_sigma,
        )
        try:
            return rate_from_streaks(sensor, xy[:, 0], xy[:, 1], axes)
        except InputError:
            return None

    def track_file(self, path, time_s: float | None = None) -> TrackSolution:
        """Track a frame read from ``path``; an unreadable frame gets status "unreadable"."""
        from starsense.solve.frames import load_image

        try:
            image = load_image(path)
        except (StarsenseError, OSError) as exc:
            t = time_s
            if t is None and self.interval_s is not None:
                t = self._index * self.interval_s
            self._index += 1
            # the mode the frame would have been processed in
            mode = "lost_in_space" if self._prior_at(t) is None else "tracking"
            return TrackSolution(Solution("unreadable", str(exc)), mode, time_s=t, image=str(path))
        return self(image, time_s, str(path))
