"""A sequence of frames tracked: the rate from consecutive attitudes.

:class:`Tracker` runs a sequence: the first frame lost-in-space (unless a prior is given), each
later one tracked from the last solved attitude (:func:`~starsense.solve.tracking.track.
track_frame`), and the body rate from consecutive attitudes with its covariance
(:func:`starsense.attitude.rate.rate_from_attitudes`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from starsense._validate import check_scalar, positive_float, show
from starsense.attitude.rate import rate_from_attitudes
from starsense.detect.windows import streak_px
from starsense.errors import InputError, StarsenseError
from starsense.solve.frames import load_image
from starsense.solve.solution import Solution
from starsense.solve.solver import Solver
from starsense.solve.tracking.streak_rate import rate_from_streaks, streak_axes
from starsense.solve.tracking.track import N_SIGMA_SEARCH, Prior, TrackSolution, track_frame
from starsense.units import DEG

__all__ = ["MIN_INTERVAL_S", "Tracker"]


#: shortest time between frames a rate is measured over, s (no star camera frames faster
#: than a microsecond; below it the rate's covariance, ~ sigma^2 / dt^2, overflows)
MIN_INTERVAL_S = 1e-6


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
        if not isinstance(solver, Solver):
            raise InputError(
                "Tracker needs a Solver with a sensor, e.g. Tracker(Solver('st16')); got "
                f"{type(solver).__name__} {show(solver)}"
            )
        if solver.sensor is None:
            raise InputError("tracking needs a sensor (known optics)")
        self.solver = solver
        if interval_s is not None:
            interval_s = check_scalar(interval_s, "interval_s", MIN_INTERVAL_S, None)
        self.interval_s = interval_s
        if prior is not None and not isinstance(prior, Prior):
            raise InputError(
                f"prior must be a Prior (Prior.from_radec_roll(ra, dec, roll, sigma_rad=...)), "
                f"got {type(prior).__name__} {show(prior)}"
            )
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
                if dt >= MIN_INTERVAL_S:  # shorter: no rate worth the name (it overflows)
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
        solver, sensor = self.solver, self.solver.sensor
        index = sorted(d for d, _ in sol.matches)[:5]
        if len(index) < 3 or sol.centroids_px is None:
            return None
        xy = sol.centroids_px[index]
        reach = 0.5 * streak_px(sensor, [self.max_rate_rad_s, 0.0, 0.0])
        half = math.ceil(reach + 3.0 * sensor.detector.psf_sigma_px + 4.0)
        known = solver.settings.background == "known"
        axes = streak_axes(
            image,
            xy[:, 0],
            xy[:, 1],
            half_px=half,
            threshold=solver.logic.lit_pixel_counts,
            level=float(sensor.detector.bias_counts) if known else None,
            threshold_sigma=None if known else solver.settings.threshold_sigma,
        )
        try:
            return rate_from_streaks(sensor, xy[:, 0], xy[:, 1], axes_px2=axes)
        except InputError:
            return None

    def track_file(self, path, time_s: float | None = None) -> TrackSolution:
        """Track a frame read from ``path``; an unreadable frame gets status "unreadable"."""
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
