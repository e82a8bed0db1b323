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

Frames are read out with :func:`starsense.render.readout.fast_read_out` (the statistics of the
default read-out within the bounds it states, in about half its time) where it applies.

Seeds: one root seed, a child stream per trial (``numpy.random.SeedSequence.spawn``), so a run is
reproducible bit for bit and any trial can be replayed alone.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from starsense._validate import check_count, finite_float, show
from starsense.analysis.inputs import (
    FRAME_COST,
    MAX_FRAMES,
    as_catalog,
    as_sensor,
    at_epoch,
    completed_sky,
    root_seed,
)
from starsense.errors import InputError
from starsense.geometry.attitude import angular_separation, boresight, small_rotation_angles
from starsense.geometry.sampling import random_attitudes
from starsense.render.scene import render_frame
from starsense.solve.solver import Solver
from starsense.units import ARCSEC, RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = ["MonteCarloResult", "montecarlo", "run_montecarlo"]


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
    truth_quat : ndarray, shape (n_solved_right, 4)
        True attitude (ICRS -> camera, scalar-last quaternion) of each right solution.
    solve_ms : ndarray, shape (n_trials,)
        Time of each solve (detection, identification, attitude; the database load excluded), ms.
    n_matched : ndarray, shape (n_solved_right,)
        Stars matched in each right solution.
    rates_rad_s : ndarray, shape (n_solved_right, 3)
        Body rate of each right solution's trial, camera frame, rad/s.
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
    truth_quat: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    solve_ms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_matched: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    rates_rad_s: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

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
            "solve_ms_median": _median(self.solve_ms),
            "solve_ms_p95": _median(self.solve_ms, 95),
            "statuses": self.statuses,
            "rate_deg_s": self.rate_deg_s,
            "model": self.model,
            "seed": self.seed,
        }


def _median(values: np.ndarray, q: float = 50) -> float | None:
    """Return a percentile of ``values``, None when there are none."""
    return float(np.percentile(values, q)) if len(values) else None


def _trials(
    sensor,
    catalog,
    seed: int,
    n_trials: int,
    indices,
    rate_rad_s: float,
    model: str,
    max_mag,
    wrong_rad: float,
    fast_noise: bool = True,
    refine: str = "model",
    progress=None,
) -> list[tuple]:
    """Run trials ``indices`` of a run of ``n_trials``; one record per trial (see below).

    A top-level function so that a Dask worker can run a chunk: trial k always uses the k-th
    child of ``SeedSequence(seed)``, wherever it runs. Record: (status, solved, wrong, error
    (3,) or None, predicted sigma (3,) or None, truth quaternion (4,), render ms, solve ms,
    matched stars, body rate (3,)).
    """
    solver = Solver(sensor=sensor, background="known", centroid_sigma_px="snr", refine=refine)
    catalog = at_epoch(catalog, solver.catalog.epoch_yr)  # the sky the database describes
    # the model fit draws the frames' own sky as the identified stars' neighbours
    solver = Solver(sensor=sensor, background="known", centroid_sigma_px="snr", refine=refine,
                    sky=catalog)  # fmt: skip
    children = np.random.SeedSequence(seed).spawn(int(n_trials))
    out = []
    for k in indices:
        rng = np.random.default_rng(children[k])
        truth = random_attitudes(1, rng)[0]
        phi = rng.uniform(0, 2 * np.pi)
        rate = rate_rad_s * np.array([math.cos(phi), math.sin(phi), 0.0])
        t0 = time.perf_counter()
        frame = render_frame(
            solver.sensor,
            truth,
            catalog,
            rate_rad_s=rate,
            model=model,
            max_mag=max_mag,
            rng=rng,
            keep_expected=False,
            fast_noise=fast_noise,
        )
        render_ms = (time.perf_counter() - t0) * 1e3
        sol = solver(frame.image)
        solve_ms = sol.time_ms - sol.stage_ms.get("database_ms", 0.0)
        err = sig = None
        wrong = False
        if sol.solved:
            miss = float(angular_separation(boresight(truth), boresight(sol.rotation)))
            wrong = miss > wrong_rad
            if not wrong:
                err = small_rotation_angles(truth, sol.rotation)
                sig = np.asarray(sol.sigma_rad)
        out.append(
            (
                sol.status,
                sol.solved,
                wrong,
                err,
                sig,
                truth.as_quat(),
                render_ms,
                solve_ms,
                sol.n_matched,
                rate,
            )
        )
        if progress is not None:
            progress(1)
    return out


def _dask_trials(client, args: tuple, n_trials: int, progress) -> list[tuple]:
    """Run the trials on a Dask cluster in chunks; records in trial order."""
    from dask.distributed import as_completed

    chunk = max(1, math.ceil(n_trials / (8 * max(1, len(client.scheduler_info()["workers"])))))
    starts = list(range(0, n_trials, chunk))
    # the sensor and the catalogue go to the workers once, not inside every task
    sensor_f, catalog_f = client.scatter(list(args[:2]), broadcast=True)
    futures = [
        client.submit(
            _trials,
            sensor_f,
            catalog_f,
            args[2],
            n_trials,
            range(s, min(s + chunk, n_trials)),
            *args[3:],
            pure=False,
        )
        for s in starts
    ]
    index = {f.key: i for i, f in enumerate(futures)}
    parts: list = [None] * len(futures)
    done = 0
    for fut in as_completed(futures):
        part = fut.result()
        parts[index[fut.key]] = part
        done += len(part)
        if progress is not None:
            progress(done, n_trials)
    return [r for part in parts for r in part]


def montecarlo(
    sensor,
    catalog=None,
    *,
    n_trials: int = 100,
    rate_rad_s: float = 0.0,
    model: str = "reed",
    max_mag: float | None = None,
    rng: int | np.random.Generator | None = 0,
    wrong_rad: float = 60.0 * ARCSEC,
    progress: Callable[[int, int], None] | None = None,
    client=None,
    fast_noise: bool = True,
    refine: str = "model",
) -> MonteCarloResult:
    """Run the tracker ``n_trials`` times at random attitudes (see the module docstring).

    Parameters
    ----------
    sensor : str, Path or Sensor
        Sensor preset, TOML file or object.
    catalog : Catalog, str or None
        Stars to render: a catalogue, a specification (``"hipparcos"``, ``"bsc5:PATH"``) or
        None for the bundled Hipparcos, with the stars of the solver's database it lacks
        (:func:`starsense.analysis.inputs.completed_sky`).
    n_trials : int
        Random attitudes to render and solve, >= 1.
    rate_rad_s : float
        Magnitude of the body rate of every trial, rad/s (>= 0), about a random cross-boresight
        axis.
    model : str
        Sensitivity model of the rendering ("reed", "liebe", "blackbody").
    max_mag : float, optional
        Render only stars brighter than this.
    rng : None, int or numpy.random.Generator
        Root seed; trial k uses the k-th child of ``numpy.random.SeedSequence(seed)`` (a
        Generator gives one seed drawn from it, None a fresh one; the result records it).
    wrong_rad : float
        A solution whose boresight is farther than this from the truth is wrong, rad
        (default 60 arcsec).
    progress : callable(done, total), optional
        Called after each trial (after each chunk on Dask).
    client : dask.distributed.Client, optional
        Run the trials on this cluster, in chunks; the result is identical to the in-process
        run for the same seed (but for the times).
    fast_noise : bool
        Read frames out with :func:`starsense.render.readout.fast_read_out` where it applies
        (default); False: :func:`starsense.render.noise.apply_noise` (other random draws, the
        same statistics).
    refine : {"model", "cog"}
        The solver's last step (:class:`starsense.solve.Solver`): the forward model's fit
        (default) or the centroids' attitude.

    Returns
    -------
    MonteCarloResult
    """
    n_trials = check_count(n_trials, "n_trials", MAX_FRAMES, FRAME_COST)
    rate_rad_s = finite_float(rate_rad_s, "rate_rad_s")
    if rate_rad_s < 0:
        raise InputError(f"rate_rad_s must be >= 0, got {show(rate_rad_s)}")
    sens = as_sensor(sensor)
    # the frames show the catalogue's stars and the database's it lacks (the real sky holds both)
    cat = completed_sky(as_catalog(catalog), Solver(sensor=sens).catalog)
    seed = root_seed(rng)
    if refine not in ("model", "cog"):
        raise InputError(f"refine must be 'model' or 'cog', got {show(refine)}")
    args = (sens, cat, seed, float(rate_rad_s), model, max_mag, float(wrong_rad), bool(fast_noise),
            refine)  # fmt: skip
    if client is not None:
        records = _dask_trials(client, args, n_trials, progress)
    else:
        done = [0]

        def tick(_n: int) -> None:
            done[0] += 1
            if progress is not None:
                progress(done[0], n_trials)

        records = _trials(*args[:3], n_trials, range(n_trials), *args[3:], progress=tick)
    return _result(sens.name, records, n_trials, rate_rad_s, model, seed)


#: the former name of :func:`montecarlo`
run_montecarlo = montecarlo


def _result(
    name: str, records: list[tuple], n_trials: int, rate_rad_s: float, model: str, seed: int
) -> MonteCarloResult:
    """Gather the per-trial records into a :class:`MonteCarloResult`."""
    statuses: dict = {}
    for r in records:
        statuses[r[0]] = statuses.get(r[0], 0) + 1
    right = [r for r in records if r[3] is not None]
    return MonteCarloResult(
        sensor=name,
        n_trials=n_trials,
        n_solved=sum(bool(r[1]) for r in records),
        n_wrong=sum(bool(r[2]) for r in records),
        errors_rad=np.array([r[3] for r in right]).reshape(-1, 3),
        predicted_sigma_rad=np.array([r[4] for r in right]).reshape(-1, 3),
        time_ms={
            "render": float(np.mean([r[6] for r in records])),
            "solve": float(np.mean([r[7] for r in records])),
        },
        statuses=statuses,
        rate_rad_s=float(rate_rad_s),
        model=model,
        seed=seed,
        truth_quat=np.array([r[5] for r in right]).reshape(-1, 4),
        solve_ms=np.array([r[7] for r in records], dtype=float),
        n_matched=np.array([r[8] for r in right], dtype=int),
        rates_rad_s=np.array([r[9] for r in right], dtype=float).reshape(-1, 3),
    )
