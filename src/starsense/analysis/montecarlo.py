"""Monte Carlo of the whole tracker: random attitudes -> render -> detect -> identify -> attitude.

Each trial draws a uniformly random attitude (and, optionally, a body rate of a given magnitude in a
random cross-axis direction), renders the frame with noise, solves it with the pipeline (the
sensor's own detection logic on the known bias), and scores the answer against the truth at
mid-exposure:

* solved / wrong: a solution is wrong when its boresight is more than ``wrong_arcsec`` (default
  60) from the truth;
* the error rotation vector in the camera frame (:func:`starsense.geometry.attitude.
  small_rotation_angles`): x, y cross-boresight and z roll, against the covariance the
  estimator predicts from each star's photon noise (Fialho & Mortari eq. 21 with per-star sigma).

Seeds: one root seed, a child stream per trial (``numpy.random.SeedSequence.spawn``), so a run is
reproducible bit for bit and any trial can be replayed alone.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError

ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0


@dataclass(frozen=True)
class MonteCarloResult:
    """Outcome of N trials.

    Attributes
    ----------
    n_trials, n_solved, n_wrong : int
    errors_arcsec : array (n_solved_right, 3)
        Camera-frame error (x, y cross-boresight, z roll) of the right solutions.
    predicted_sigma_arcsec : array (n_solved_right, 3)
        The estimator's own 1-sigma per axis for the same trials.
    time_ms : dict
        Mean time per frame of rendering and of solving.
    statuses : dict
        Count of each pipeline status.
    """

    sensor: str
    n_trials: int
    n_solved: int
    n_wrong: int
    errors_arcsec: np.ndarray
    predicted_sigma_arcsec: np.ndarray
    time_ms: dict
    statuses: dict
    rate_deg_s: float
    model: str
    seed: int

    @property
    def solve_rate(self) -> float:
        return (self.n_solved - self.n_wrong) / self.n_trials

    @property
    def wrong_rate(self) -> float:
        return self.n_wrong / self.n_trials

    @property
    def rms_error_arcsec(self) -> np.ndarray:
        e = self.errors_arcsec
        return np.sqrt(np.mean(e**2, axis=0)) if len(e) else np.full(3, np.nan)

    @property
    def rms_predicted_arcsec(self) -> np.ndarray:
        p = self.predicted_sigma_arcsec
        return np.sqrt(np.mean(p**2, axis=0)) if len(p) else np.full(3, np.nan)

    def to_dict(self) -> dict:
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


def run_montecarlo(sensor, n_trials: int = 100, *, rate_deg_s: float = 0.0, model: str = "reed",
                   catalog=None, max_mag: float | None = None, seed: int = 0,
                   wrong_arcsec: float = 60.0, progress=None) -> MonteCarloResult:  # fmt: skip
    """Run the tracker ``n_trials`` times at random attitudes (see the module docstring)."""
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
        raise InputError(f"n_trials must be an integer >= 1, got {n_trials!r}")
    if not np.isfinite(rate_deg_s) or rate_deg_s < 0:
        raise InputError(f"rate_deg_s must be >= 0, got {rate_deg_s!r}")
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
        rate = math.radians(rate_deg_s) * np.array([math.cos(phi), math.sin(phi), 0.0])
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
            if miss * ARCSEC_PER_RAD > wrong_arcsec:
                n_wrong += 1
            else:
                errors.append(small_rotation_angles(truth, sol.rotation) * ARCSEC_PER_RAD)
                predicted.append(np.asarray(sol.sigma_arcsec))
        if progress is not None:
            progress(k + 1, n_trials)
    timed = max(1, n_trials - 1)
    return MonteCarloResult(
        sensor=solver.sensor.name,
        n_trials=int(n_trials),
        n_solved=n_solved,
        n_wrong=n_wrong,
        errors_arcsec=np.array(errors).reshape(-1, 3),
        predicted_sigma_arcsec=np.array(predicted).reshape(-1, 3),
        time_ms={"render": t_render / timed * 1e3, "solve": t_solve / timed * 1e3},
        statuses=statuses,
        rate_deg_s=float(rate_deg_s),
        model=model,
        seed=int(seed),
    )
