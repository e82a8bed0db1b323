"""Lin et al. 2024, Table 1: P(accuracy < threshold) per area configuration and sigma."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import check_count, check_scalar, positive_float
from starsense.analysis.guide_stars._common import check_metric, check_sigmas
from starsense.analysis.guide_stars.focal_plane import (
    CONFIGURATIONS,
    PAPER_STEP,
    configuration_areas,
    focal_to_vectors,
    sample_placements,
    triangle_fov_ratio,
)
from starsense.analysis.guide_stars.metrics import (
    batch_covariance,
    error_norm,
    monte_carlo_errors,
    probability_within,
    tangent_noise,
)
from starsense.analysis.inputs import root_seed
from starsense.errors import InputError
from starsense.geometry.sampling import random_attitudes
from starsense.identify.batch import ID_CORRECT, identify_triangles
from starsense.references import lin2024
from starsense.units import ARCSEC, DEG, to_edge

__all__ = [
    "ID_TOLERANCE_SIGMA",
    "MAX_TABLE1_TRIALS",
    "PAPER_FOV",
    "PAPER_SIGMAS",
    "PAPER_THRESHOLD",
    "TABLE1_TRIAL_COST",
    "GuideStarTable",
    "simulate_table1",
]

#: most placements per configuration of one Table 1 run: the run holds ~32 KB per placement
#: (peak RSS 0.46 GB at 10,000, 6.5 GB at 200,000), so the cap keeps it near 1 GB
MAX_TABLE1_TRIALS = 30_000
TABLE1_TRIAL_COST = "~32 KB of memory per placement"

PAPER_SIGMAS = tuple(s * ARCSEC for s in lin2024.TABLE1_SIGMAS_ARCSEC)
"""Measurement errors of the paper's simulation (sec. 4, Table 1's rows), rad."""
PAPER_THRESHOLD = lin2024.TABLE1_THRESHOLD_ARCSEC * ARCSEC
"""Accuracy requirement of Table 1 (0.1 arcsec), rad."""
PAPER_FOV = lin2024.CAMERA_FOV_DEG * DEG
"""Default science field V: the paper's 2048 px x 2 arcsec camera (1.138 deg), rad."""
ID_TOLERANCE_SIGMA = 3.0
"""Default side tolerance, in standard deviations of a measured inter-star angle."""


@dataclass(frozen=True, eq=False)
class GuideStarTable:
    """Probability of accuracy better than a threshold, per configuration and sigma (Table 1).

    Angles are stored in radians; ``sigma_arcsec``, ``threshold_arcsec`` and ``fov_deg`` give
    them in the units of the paper and the command line.

    Attributes
    ----------
    sigmas_rad : tuple of float
        Quoted measurement errors, rad (rows).
    probability_mc, probability_analytic : dict str -> ndarray (n_sigma,)
        Monte Carlo fraction of trials with error < threshold, and the mean over the same
        placements of the Gaussian prediction from P = F^-1; 0-1.
    triangle_ratio : dict str -> ndarray (n_trials,)
        Average FOV ratio of the triangles of each placement (denominator: the
        configuration's own areas).
    placements : dict str -> ndarray (n_trials, n_stars, 2)
        Focal-plane positions, units of V.
    success : dict str -> ndarray of bool (n_sigma, n_trials)
        Per trial: identified correctly (when ``identify``) and error below the threshold.
    identified : dict str -> ndarray (n_sigma,)
        Fraction of trials whose stars the triangle algorithm identified correctly (1 when
        ``identify`` is False).
    threshold_rad, fov_rad : float
        Accuracy requirement and science field side V, rad.
    step, n_stars, n_trials, metric, seed, identify, sigma_kind
        Settings of :func:`simulate_table1`.
    elapsed_s : float
        Wall-clock time of the whole table, s.
    """

    sigmas_rad: tuple[float, ...]
    probability_mc: dict[str, NDArray[np.float64]]
    probability_analytic: dict[str, NDArray[np.float64]]
    triangle_ratio: dict[str, NDArray[np.float64]] = field(repr=False)
    placements: dict[str, NDArray[np.float64]] = field(repr=False)
    success: dict[str, NDArray[np.bool_]] = field(repr=False, default_factory=dict)
    identified: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    threshold_rad: float = PAPER_THRESHOLD
    fov_rad: float = PAPER_FOV
    step: float = PAPER_STEP
    n_stars: int = lin2024.N_GUIDE_STARS
    n_trials: int = 10_000
    metric: str = "pointing"
    seed: int = 0
    identify: bool = True
    sigma_kind: str = "1sigma"
    elapsed_s: float = 0.0

    @property
    def sigma_arcsec(self) -> tuple[float, ...]:
        """Quoted measurement errors, arcsec (as given at the edge)."""
        return tuple(to_edge(s, ARCSEC) for s in self.sigmas_rad)

    @property
    def threshold_arcsec(self) -> float:
        """Accuracy requirement, arcsec."""
        return to_edge(self.threshold_rad, ARCSEC)

    @property
    def fov_deg(self) -> float:
        """Science field side V, deg."""
        return to_edge(self.fov_rad, DEG)

    def by_triangle_ratio(
        self, configuration: str, sigma_rad: float, n_bins: int = 10
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int_]]:
        """Return the probability of success against the triangle ratio (Figs. 5-6).

        Lin et al. 2024, Figs. 5-6. Trials are binned on quantiles of their average FOV ratio
        of the triangles, so every bin holds about the same number of trials.

        Parameters
        ----------
        configuration : str
            A configuration of this table.
        sigma_rad : float
            One of this table's sigmas, rad (matched to 1e-9 relative).
        n_bins : int
            Number of equal-count bins, >= 1.

        Returns
        -------
        ratio : ndarray (n_bins,)
            Mean triangle ratio of each bin.
        probability : ndarray (n_bins,)
            Fraction of the bin's trials that succeeded, 0-1.
        count : ndarray of int (n_bins,)
            Trials per bin.
        """
        if configuration not in self.success:
            raise InputError(f"configuration {configuration!r} is not in this table")
        hits = np.flatnonzero(np.isclose(self.sigmas_rad, float(sigma_rad), rtol=1e-9, atol=0))
        if not len(hits):
            raise InputError(
                f"sigma_rad = {sigma_rad!r} is not in this table ({list(self.sigmas_rad)})"
            )
        if not isinstance(n_bins, int) or n_bins < 1:
            raise InputError(f"n_bins = {n_bins!r} must be an integer >= 1")
        r = self.triangle_ratio[configuration]
        ok = self.success[configuration][int(hits[0])]
        order = np.argsort(r, kind="stable")
        groups = np.array_split(order, n_bins)
        ratio = np.array([r[g].mean() for g in groups])
        prob = np.array([ok[g].mean() for g in groups])
        count = np.array([len(g) for g in groups])
        return ratio, prob, count

    def as_dict(self) -> dict:
        """Return the JSON-ready summary (the CLI's ``--json`` payload; arcsec and deg)."""
        paper = self.sigma_arcsec == lin2024.TABLE1_SIGMAS_ARCSEC
        return {
            "sigma_arcsec": list(self.sigma_arcsec),
            "probability": {k: v.tolist() for k, v in self.probability_mc.items()},
            "probability_analytic": {k: v.tolist() for k, v in self.probability_analytic.items()},
            "paper_percent": {k: list(lin2024.TABLE1_PERCENT[k]) for k in self.probability_mc}
            if paper
            else None,
            "threshold_arcsec": self.threshold_arcsec,
            "fov_deg": self.fov_deg,
            "step": self.step,
            "n_stars": self.n_stars,
            "n_trials": self.n_trials,
            "metric": self.metric,
            "seed": self.seed,
            "identify": self.identify,
            "identified": {k: v.tolist() for k, v in self.identified.items()},
            "sigma_kind": self.sigma_kind,
            "elapsed_s": self.elapsed_s,
        }


@dataclass(frozen=True)
class _Cell:
    """Settings shared by every cell of the table (checked once)."""

    sigmas: NDArray[np.float64]
    per_quoted: float
    threshold: float
    fov: float
    n_trials: int
    n_stars: int
    step: float
    metric: str
    identify: bool
    id_tolerance_sigma: float


def _configuration_rows(c: str, gen: np.random.Generator, cfg: _Cell, tick) -> dict:
    """Simulate one configuration (one column of Table 1) over all sigmas."""
    xy = sample_placements(c, n_trials=cfg.n_trials, n_stars=cfg.n_stars, step=cfg.step, rng=gen)
    vec = focal_to_vectors(xy, cfg.fov)
    z = gen.standard_normal((cfg.n_trials, cfg.n_stars, 2))
    att = random_attitudes(cfg.n_trials, gen)
    cov1 = batch_covariance(vec, 1.0)  # P scales with sigma^2
    an, ok_rows, id_rows = [], [], []
    for s in cfg.sigmas:
        s_rad = s * cfg.per_quoted
        err = monte_carlo_errors(vec, s_rad, noise=z, attitudes=att)
        ok = error_norm(err, cfg.metric) < cfg.threshold
        if cfg.identify:
            measured = tangent_noise(vec, z, s_rad)  # the same noisy stars the solve used
            tol = cfg.id_tolerance_sigma * math.sqrt(2.0) * s_rad
            found = identify_triangles(measured, vec, tol)
            ok &= found == ID_CORRECT
            id_rows.append(float(np.mean(found == ID_CORRECT)))
        else:
            id_rows.append(1.0)
        ok_rows.append(ok)
        an.append(float(np.mean(probability_within(cov1 * s_rad**2, cfg.threshold, cfg.metric))))
        tick()
    success = np.array(ok_rows)
    return {
        "success": success,
        "mc": success.mean(axis=1),
        "analytic": np.array(an),
        "identified": np.array(id_rows),
        "ratio": triangle_fov_ratio(xy, c),
        "xy": xy,
    }


def simulate_table1(
    sigmas_rad: ArrayLike = PAPER_SIGMAS,
    configurations: tuple[str, ...] | list[str] | None = None,
    *,
    n_trials: int = 10_000,
    fov_rad: float = PAPER_FOV,
    threshold_rad: float = PAPER_THRESHOLD,
    n_stars: int = lin2024.N_GUIDE_STARS,
    step: float = PAPER_STEP,
    metric: str = "pointing",
    rng: int | np.random.Generator | None = 0,
    identify: bool = True,
    sigma_kind: str = "1sigma",
    id_tolerance_sigma: float = ID_TOLERANCE_SIGMA,
    progress=None,
) -> GuideStarTable:
    """Simulate Lin et al. 2024, Table 1: P(accuracy < threshold) per configuration and sigma.

    For each configuration, ``n_trials`` placements (:func:`sample_placements`), each with one
    true attitude and one standard-normal noise draw reused (scaled) for every sigma; the Monte
    Carlo solves with :func:`starsense.attitude.svd.batch_svd_attitude`, the analytic column
    averages :func:`probability_within` of P = F^-1 (eqs. 1-3) over the same placements. Child
    seeds derive from ``seed`` (one per configuration), so the table is reproducible bit for
    bit.

    Parameters
    ----------
    sigmas_rad : array_like of float
        Quoted measurement errors, rad, > 0 (default: the paper's 0.3 ... 0.01 arcsec).
    configurations : sequence of str or None
        Default: all five, in Table 1's order.
    n_trials : int
        Placements (and noise draws) per configuration.
    fov_rad : float
        Side V of the science field, rad, in (0, pi/2) (default: the paper's camera).
    threshold_rad : float
        Accuracy requirement, rad (the paper: 0.1 arcsec).
    n_stars : int
        Guide stars per placement (paper: 5).
    step : float
        Lattice step, fraction of V (paper: 0.07).
    metric : {"total", "pointing"}
        Accuracy = norm of the whole error rotation vector, or of its cross-boresight part.
    rng : None, int or numpy.random.Generator
        Root seed (a Generator gives one seed drawn from it; the result records it).
    identify : bool
        Run triangle identification in the loop
        (:func:`starsense.identify.batch.identify_triangles`); a trial succeeds only if its
        stars are identified correctly.
    sigma_kind : {"1sigma", "3sigma"}
        ``sigmas_rad`` are per-axis standard deviations, or 3-sigma bounds (standard
        deviation sigma / 3), see :mod:`starsense.analysis.guide_stars`.
    id_tolerance_sigma : float
        Side tolerance of the identification, in standard deviations of a measured
        inter-star angle (sqrt(2) x the per-axis standard deviation).
    progress : callable(label, done, total), optional
        Called after each (configuration, sigma) cell.

    Returns
    -------
    GuideStarTable
    """
    start = time.perf_counter()
    sig, per_quoted = check_sigmas(sigmas_rad, sigma_kind)
    thr = positive_float(threshold_rad, "threshold_rad")
    check_metric(metric)
    k_tol = positive_float(id_tolerance_sigma, "id_tolerance_sigma")
    fov = check_scalar(fov_rad, "fov_rad", 0.0, math.pi / 2, lo_open=True, hi_open=True)
    configs = tuple(CONFIGURATIONS) if configurations is None else tuple(configurations)
    for c in configs:
        configuration_areas(c)
    n_trials = check_count(n_trials, "n_trials", MAX_TABLE1_TRIALS, TABLE1_TRIAL_COST)
    cfg = _Cell(sig, per_quoted, thr, fov, n_trials, n_stars, step, metric, identify, k_tol)
    seed = root_seed(rng)
    children = np.random.SeedSequence(seed).spawn(len(configs))
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress("Table 1 cells", done[0], len(configs) * len(sig))

    rows = {
        c: _configuration_rows(c, np.random.default_rng(child), cfg, tick)
        for c, child in zip(configs, children, strict=True)
    }
    return GuideStarTable(
        sigmas_rad=tuple(float(s) for s in sig),
        probability_mc={c: r["mc"] for c, r in rows.items()},
        probability_analytic={c: r["analytic"] for c, r in rows.items()},
        triangle_ratio={c: r["ratio"] for c, r in rows.items()},
        placements={c: r["xy"] for c, r in rows.items()},
        success={c: r["success"] for c, r in rows.items()},
        identified={c: r["identified"] for c, r in rows.items()},
        threshold_rad=thr,
        fov_rad=fov,
        step=step,
        n_stars=n_stars,
        n_trials=n_trials,
        metric=metric,
        seed=seed,
        identify=bool(identify),
        sigma_kind=sigma_kind,
        elapsed_s=time.perf_counter() - start,
    )
