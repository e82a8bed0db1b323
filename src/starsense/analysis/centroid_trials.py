"""Lost in space at Monte Carlo scale: simulated centroids instead of rendered frames.

The false-identification rate a customer asks for is small (below 1e-5): bounding it takes
1e5-1e6 trials, too many frames to render. Here each trial simulates what the detector would
hand the identifier, from the datasheet's own predictions (:class:`CentroidModel`):

* a uniformly random attitude; the catalogue stars projected through the sensor's optics onto
  its detector (:meth:`Sensor.project`, distortion included);
* each star **detected** with the probability the slew-tolerance Monte Carlo measured for its
  magnitude at rest (rendered stamps, :func:`starsense.analysis.slew.simulate_slew`): faint
  stars are dropped as the detector drops them;
* each detected star displaced by Gaussian centroid noise of the predicted 1-sigma per axis for
  its photo-electrons (:func:`starsense.analysis.datasheet.noise.centroid_noise`), its
  brightness the photo-electrons with their shot noise (the order the identifier sees);
* a Poisson number of **false stars** (hot pixels, debris, planets: ``n_false`` a frame on
  average) at uniform positions, brightness log-uniform over the true stars' range (random ranks);

then solves the centroids with the product's lost-in-space solver
(:meth:`starsense.solve.solver.Solver.solve_centroids`) and scores it against the truth: a
solution whose boresight is farther than ``wrong_rad`` (60 arcsec) from the truth is **wrong**.
The 95 % upper bound on the false-identification rate is the exact one-sided Clopper-Pearson
bound (:func:`~starsense.analysis.datasheet.verify.wrong_rate_upper`; with no wrong solution in
n trials it is ``1 - 0.05^(1/n)``, about 3/n, the rule of three).

Trial k draws everything from the k-th child of ``SeedSequence(seed)`` (as
:mod:`starsense.analysis.montecarlo`), so a run is reproducible bit for bit wherever its chunks
run (in process, or on a Dask cluster) and any wrong trial can be replayed alone.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from starsense._validate import check_count, check_int
from starsense.analysis.availability.field import catalog_stars
from starsense.analysis.centroid_sim import (
    CentroidModel,
    centroid_model,
    simulate_centroids,
    star_field,
)
from starsense.analysis.datasheet.verify import wrong_rate_upper
from starsense.analysis.inputs import as_catalog, as_sensor, at_epoch, completed_sky, root_seed
from starsense.geometry.attitude import angular_separation, boresight
from starsense.solve.solver import Solver
from starsense.units import ARCSEC

__all__ = ["CentroidTrialsResult", "centroid_trials"]

#: trials per Dask task at most (a task pays one database load: ~0.2 s against ~30 s of work)
MAX_CHUNK = 20_000
#: most trials of one run: each simulates and identifies a centroid set, ~1 ms (``datasheet
#: --centroids-only`` at 200 and 2,000 trials), so the cap bounds a run to ~20 minutes
MAX_CENTROID_TRIALS = 1_000_000
CENTROID_TRIAL_COST = "~1 ms per simulated centroid set"


@dataclass(frozen=True)
class CentroidTrialsResult:
    """Outcome of a centroid-level lost-in-space run.

    Attributes
    ----------
    sensor : str
    n_trials, n_solved, n_wrong : int
        Trials, solved (right or wrong), solved wrongly.
    wrong_trials : ndarray of int
        Indices of the wrong trials (replay trial k alone with the same seed).
    statuses : dict
        Count of each solver status.
    solve_ms : ndarray, shape (n_trials,)
        Time of each solve, ms.
    n_centroids : ndarray of int, shape (n_trials,)
        Centroids handed to the identifier (true and false).
    seed : int
        Root seed.
    n_false : float
        Mean false stars per frame.
    wall_s : float
        Wall time of the run, s.
    workers : int
        Processes that ran it (1: in process).
    """

    sensor: str
    n_trials: int
    n_solved: int
    n_wrong: int
    wrong_trials: np.ndarray
    statuses: dict
    solve_ms: np.ndarray = field(repr=False)
    n_centroids: np.ndarray = field(repr=False)
    seed: int = 0
    n_false: float = 2.0
    wall_s: float = math.nan
    workers: int = 1

    @property
    def wrong_rate_upper95(self) -> float:
        """One-sided 95 % upper bound on the false-identification rate (Clopper-Pearson)."""
        return wrong_rate_upper(self.n_wrong, self.n_trials, 0.95)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        ms = self.solve_ms
        return {
            "sensor": self.sensor,
            "mode": "centroids_only",
            "trials": self.n_trials,
            "solved": self.n_solved,
            "wrong": self.n_wrong,
            "wrong_rate_upper95": self.wrong_rate_upper95,
            "wrong_trials": [int(k) for k in self.wrong_trials],
            "statuses": dict(self.statuses),
            "solve_ms_median": float(np.median(ms)) if len(ms) else None,
            "solve_ms_p95": float(np.percentile(ms, 95)) if len(ms) else None,
            "centroids_median": float(np.median(self.n_centroids)) if len(ms) else None,
            "false_stars_mean": self.n_false,
            "seed": self.seed,
            "wall_s": self.wall_s,
            "workers": self.workers,
        }


def _one_trial(rng, solver, stars, cmodel: CentroidModel, wrong_rad: float):
    """Simulate and solve one frame's centroids; (status, solved, wrong, ms, centroids)."""
    sim = simulate_centroids(solver.sensor, stars, cmodel, rng=rng)
    det = solver.sensor.detector
    x, y = sim.xy.T
    # the noise may move a star at the edge off the detector: it is not seen
    keep = (x >= -0.5) & (x < det.columns - 0.5) & (y >= -0.5) & (y < det.rows - 0.5)
    t0 = time.perf_counter()
    sol = solver.solve_centroids(sim.xy[keep], (det.columns, det.rows), brightness=sim.flux[keep])
    ms = (time.perf_counter() - t0) * 1e3
    wrong = False
    if sol.solved:
        miss = float(angular_separation(boresight(sim.rotation), boresight(sol.rotation)))
        wrong = miss > wrong_rad
    return sol.status, sol.solved, wrong, ms, int(keep.sum())


def _chunk(sensor, vectors, mags, cmodel, seed: int, start: int, stop: int, wrong_rad: float):
    """Run trials ``start..stop`` (a top-level function: a Dask task); arrays of their records.

    Trial k draws from ``SeedSequence(seed, spawn_key=(k,))``, the k-th child of
    ``SeedSequence(seed).spawn``, wherever it runs.
    """
    solver = Solver(sensor=sensor)
    solver.identifier(2.0 * sensor.half_fov_rad[0])  # the database loaded before the clock
    stars = star_field(sensor, vectors, mags)
    statuses: dict = {}
    n = stop - start
    solved, wrong = np.zeros(n, bool), np.zeros(n, bool)
    ms, count = np.zeros(n, np.float32), np.zeros(n, np.int32)
    for i, k in enumerate(range(start, stop)):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(k,)))
        status, solved[i], wrong[i], ms[i], count[i] = _one_trial(
            rng, solver, stars, cmodel, wrong_rad
        )
        statuses[status] = statuses.get(status, 0) + 1
    return statuses, solved, wrong, ms, count


def _merge(parts):
    """Return the chunks' records joined in trial order."""
    statuses: dict = {}
    for part in parts:
        for k, v in part[0].items():
            statuses[k] = statuses.get(k, 0) + v
    solved, wrong, ms, count = (np.concatenate([p[j] for p in parts]) for j in range(1, 5))
    return statuses, solved, wrong, ms, count


def _run_dask(client, args, n_trials: int, chunk: int, progress):
    """Return the chunks' records run on a Dask cluster, in trial order."""
    from dask.distributed import as_completed

    sensor, vectors, mags, cmodel, seed, wrong_rad = args
    # the sensor and the stars go to the workers once, not inside every task
    sensor_f, vectors_f, mags_f = client.scatter([sensor, vectors, mags], broadcast=True)
    starts = list(range(0, n_trials, chunk))
    futures = [
        client.submit(
            _chunk,
            sensor_f,
            vectors_f,
            mags_f,
            cmodel,
            seed,
            s,
            min(s + chunk, n_trials),
            wrong_rad,
            pure=False,
        )
        for s in starts
    ]
    index = {f.key: i for i, f in enumerate(futures)}
    parts: list = [None] * len(futures)
    done = 0
    for fut in as_completed(futures):
        i = index[fut.key]
        parts[i] = fut.result()
        done += min(starts[i] + chunk, n_trials) - starts[i]
        if progress is not None:
            progress(done, n_trials)
    return parts


def centroid_trials(
    sensor,
    catalog=None,
    *,
    n_trials: int = 10_000,
    cmodel: CentroidModel | None = None,
    model: str = "reed",
    rng: int | np.random.Generator | None = 0,
    wrong_rad: float = 60.0 * ARCSEC,
    client=None,
    chunk: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CentroidTrialsResult:
    """Run ``n_trials`` centroid-level lost-in-space trials (see the module docstring).

    Parameters
    ----------
    sensor : str, Path or Sensor
        Sensor preset, TOML file or object.
    catalog : Catalog, str or None
        The stars to simulate and identify (None: the bundled Hipparcos).
    n_trials : int
        Trials, >= 1.
    cmodel : CentroidModel, optional
        The detection and noise table (default :func:`centroid_model` of the sensor, with
        ``model`` and the root seed).
    model : str
        Sensitivity model of the default ``cmodel``.
    rng : None, int or numpy.random.Generator
        Root seed (the result records it).
    wrong_rad : float
        A solution whose boresight is farther than this from the truth is wrong, rad.
    client : dask.distributed.Client, optional
        Run the chunks on this cluster; the counts are those of the in-process run.
    chunk : int, optional
        Trials per task (default: 8 tasks per worker, at most :data:`MAX_CHUNK`).
    progress : callable(done, total), optional
        Called after each chunk.

    Returns
    -------
    CentroidTrialsResult
    """
    n_trials = check_count(n_trials, "n_trials", MAX_CENTROID_TRIALS, CENTROID_TRIAL_COST)
    sens = as_sensor(sensor)
    cat = as_catalog(catalog)
    seed = root_seed(rng)
    cm = cmodel if cmodel is not None else centroid_model(sens, model=model, rng=seed)
    database = Solver(sensor=sens).catalog
    cat = at_epoch(completed_sky(cat, database), database.epoch_yr)  # the sky it describes
    vectors, mags = catalog_stars(cat, cm.max_mag, band="V")
    args = (sens, vectors, mags, cm, seed, float(wrong_rad))
    t0 = time.perf_counter()
    if client is not None:
        workers = max(1, len(client.scheduler_info()["workers"]))
        size = chunk or min(MAX_CHUNK, max(1, math.ceil(n_trials / (8 * workers))))
        parts = _run_dask(client, args, n_trials, check_int(size, "chunk", 1), progress)
    else:
        workers = 1
        size = check_int(chunk or MAX_CHUNK, "chunk", 1)
        starts = list(range(0, n_trials, size))
        parts = []
        for s in starts:
            parts.append(_chunk(*args[:5], s, min(s + size, n_trials), args[5]))
            if progress is not None:
                progress(min(s + size, n_trials), n_trials)
    statuses, solved, wrong, ms, count = _merge(parts)
    return CentroidTrialsResult(
        sensor=sens.name,
        n_trials=n_trials,
        n_solved=int(solved.sum()),
        n_wrong=int(wrong.sum()),
        wrong_trials=np.flatnonzero(wrong),
        statuses=statuses,
        solve_ms=ms,
        n_centroids=count,
        seed=seed,
        n_false=cm.n_false,
        wall_s=time.perf_counter() - t0,
        workers=workers,
    )
