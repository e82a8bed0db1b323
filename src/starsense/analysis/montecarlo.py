"""Monte Carlo of the whole tracker: random attitudes -> render -> detect -> identify -> attitude.

Each trial draws a uniformly random attitude (and, optionally, a body rate of a given magnitude in a
random cross-axis direction), renders the frame with noise, solves it with the pipeline (the
sensor's own detection logic on the known bias), and scores the answer against the truth at
mid-exposure:

* solved / wrong: a solution is wrong when its boresight is more than ``wrong_rad`` (default
  60 arcsec) from the truth;
* the error rotation vector in the camera frame (:func:`starsense.geometry.attitude.
  small_rotation_angles`): x, y cross-boresight and z roll, against the covariance the
  estimator predicts from each star's photon noise (Fialho & Mortari eq. 21 with per-star sigma).

Seeds: one root seed, a child stream per trial (``numpy.random.SeedSequence.spawn``), so a run is
reproducible bit for bit and any trial can be replayed alone.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from starsense._validate import finite_float, show
from starsense.errors import InputError
from starsense.units import ARCSEC, RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = ["MonteCarloResult", "run_montecarlo"]


@dataclass(frozen=True)
class MonteCarloResult:
    """Outcome of N trials; angles in radians, with arcsecond views for the edges.

    Attributes
    ----------
    sensor : str
        The sensor's name.
    n_trials, n_solved, n_wrong : int
        Trials run, solved (right or wrong) and solved wrongly.
    errors_rad : ndarray, shape (n_solved_right, 3)
        Camera-frame error (x, y cross-boresight, z roll) of the right solutions, rad.
    predicted_sigma_rad : ndarray, shape (n_solved_right, 3)
        The estimator's own 1-sigma per axis for the same trials, rad.
    time_ms : dict
        Mean time per frame of rendering and of solving, ms.
    statuses : dict
        Count of each pipeline status.
    rate_rad_s : float
        Cross-axis body rate of every trial, rad/s.
    model : str
        Sensitivity model of the rendering.
    seed : int
        Root seed.
    """

    sensor: str
    n_trials: int
    n_solved: int
    n_wrong: int
    errors_rad: np.ndarray
    predicted_sigma_rad: np.ndarray
    time_ms: dict
    statuses: dict
    rate_rad_s: float
    model: str
    seed: int

    @property
    def solve_rate(self) -> float:
        """Fraction of trials solved right."""
        return (self.n_solved - self.n_wrong) / self.n_trials

    @property
    def wrong_rate(self) -> float:
        """Fraction of trials solved wrongly."""
        return self.n_wrong / self.n_trials

    @property
    def errors_arcsec(self) -> np.ndarray:
        """Camera-frame errors of the right solutions, arcsec, shape (n_solved_right, 3)."""
        return self.errors_rad * RAD_TO_ARCSEC

    @property
    def predicted_sigma_arcsec(self) -> np.ndarray:
        """Predicted 1-sigma per axis of the right solutions, arcsec, shape (n_solved_right, 3)."""
        return self.predicted_sigma_rad * RAD_TO_ARCSEC

    @property
    def rate_deg_s(self) -> float:
        """Cross-axis body rate of every trial, deg/s."""
        return float(self.rate_rad_s * RAD_TO_DEG)

    @property
    def rms_error_arcsec(self) -> np.ndarray:
        """Rms error per axis (x, y, roll) of the right solutions, arcsec; NaN without any."""
        e = self.errors_arcsec
        return np.sqrt(np.mean(e**2, axis=0)) if len(e) else np.full(3, np.nan)

    @property
    def rms_predicted_arcsec(self) -> np.ndarray:
        """Rms of the predicted 1-sigma per axis, arcsec; NaN without any right solution."""
        p = self.predicted_sigma_arcsec
        return np.sqrt(np.mean(p**2, axis=0)) if len(p) else np.full(3, np.nan)

    def to_dict(self) -> dict:
        """Return the summary as JSON-ready values (arcsec and deg/s, as the CLI prints)."""
        return {
            "sensor": self.sensor,
            "n_trials": self.n_trials,
            "solve_rate": self.solve_rate,
            "wrong_rate": self.wrong_rate,
            "rms_error_arcsec": [float(v) for v in self.rms_error_arcsec],
            "rms_predicted_arcsec": [float(v) for v in self.rms_predicted_arcsec],
            "time_ms": self.time_ms,
            "statuses": self.statuses,
            "rate_deg_s": self.rate_deg_s,
            "model": self.model,
            "seed": self.seed,
        }


def run_montecarlo(
    sensor,
    n_trials: int = 100,
    *,
    rate_rad_s: float = 0.0,
    model: str = "reed",
    catalog=None,
    max_mag: float | None = None,
    seed: int = 0,
    wrong_rad: float = 60.0 * ARCSEC,
    progress: Callable[[int, int], None] | None = None,
) -> MonteCarloResult:
    """Run the tracker ``n_trials`` times at random attitudes (see the module docstring).

    Parameters
    ----------
    sensor : str, Path or Sensor
        Sensor preset, TOML file or object.
    n_trials : int
        Random attitudes to render and solve, >= 1.
    rate_rad_s : float
        Magnitude of the body rate of every trial, rad/s (>= 0), about a random cross-boresight
        axis.
    model : str
        Sensitivity model of the rendering ("reed", "liebe", "blackbody").
    catalog : Catalog, optional
        Stars to render and identify (default: the bundled Hipparcos).
    max_mag : float, optional
        Render only stars brighter than this.
    seed : int
        Root seed; trial k uses the k-th child of ``numpy.random.SeedSequence(seed)``.
    wrong_rad : float
        A solution whose boresight is farther than this from the truth is wrong, rad
        (default 60 arcsec).
    progress : callable(done, total), optional
        Called after each trial.

    Returns
    -------
    MonteCarloResult
    """
    from starsense.catalog import load_catalog
    from starsense.geometry.attitude import (
        angular_separation,
        boresight,
        small_rotation_angles,
    )
    from starsense.geometry.sampling import random_attitudes
    from starsense.render.scene import render_frame
    from starsense.solve.solver import Solver

    if int(n_trials) != n_trials or n_trials < 1:
        raise InputError(f"n_trials must be an integer >= 1, got {show(n_trials)}")
    rate_rad_s = finite_float(rate_rad_s, "rate_rad_s")
    if rate_rad_s < 0:
        raise InputError(f"rate_rad_s must be >= 0, got {show(rate_rad_s)}")
    cat = load_catalog("hipparcos") if catalog is None else catalog
    solver = Solver(sensor=sensor, background="known", centroid_sigma_px="snr")
    children = np.random.SeedSequence(seed).spawn(int(n_trials))
    errors, predicted, statuses = [], [], {}
    n_solved = n_wrong = 0
    t_render = t_solve = 0.0
    for k, child in enumerate(children):
        rng = np.random.default_rng(child)
        truth = random_attitudes(1, rng)[0]
        phi = rng.uniform(0, 2 * np.pi)
        rate = rate_rad_s * np.array([math.cos(phi), math.sin(phi), 0.0])
        t0 = time.perf_counter()
        frame = render_frame(solver.sensor, truth, cat, rate_rad_s=rate, model=model,
                             max_mag=max_mag, rng=rng, keep_expected=False)  # fmt: skip
        t1 = time.perf_counter()
        sol = solver(frame.image)
        t2 = time.perf_counter()
        if k > 0:  # the first solve includes the database build or cache load
            t_render += t1 - t0
            t_solve += t2 - t1
        statuses[sol.status] = statuses.get(sol.status, 0) + 1
        if sol.solved:
            n_solved += 1
            miss = float(angular_separation(boresight(truth), boresight(sol.rotation)))
            if miss > wrong_rad:
                n_wrong += 1
            else:
                errors.append(small_rotation_angles(truth, sol.rotation))
                predicted.append(np.asarray(sol.sigma_rad))
        if progress is not None:
            progress(k + 1, n_trials)
    timed = max(1, n_trials - 1)
    return MonteCarloResult(
        sensor=solver.sensor.name,
        n_trials=int(n_trials),
        n_solved=n_solved,
        n_wrong=n_wrong,
        errors_rad=np.array(errors).reshape(-1, 3),
        predicted_sigma_rad=np.array(predicted).reshape(-1, 3),
        time_ms={"render": t_render / timed * 1e3, "solve": t_solve / timed * 1e3},
        statuses=statuses,
        rate_rad_s=float(rate_rad_s),
        model=model,
        seed=int(seed),
    )
