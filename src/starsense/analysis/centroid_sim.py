"""Simulated centroids: what the detector would hand the identifier, from the datasheet's models.

:class:`CentroidModel` tabulates, per magnitude, the chance of detection (the slew-tolerance
Monte Carlo at rest), the centroid noise and the photo-electrons the datasheet predicts;
:func:`simulate_centroids` draws one frame's centroids at a random attitude from it, with false
stars (:mod:`starsense.analysis.centroid_trials` runs them through the solver at scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from starsense._validate import as_generator
from starsense.analysis.datasheet.predict import StarModel, limiting_magnitude
from starsense.analysis.inputs import as_sensor
from starsense.analysis.slew import simulate_slew
from starsense.errors import InputError
from starsense.geometry.sampling import random_attitudes

__all__ = [
    "CentroidModel",
    "SimulatedCentroids",
    "centroid_model",
    "simulate_centroids",
    "star_field",
]


@dataclass(frozen=True)
class CentroidModel:
    """What the detector hands the identifier, per magnitude (tabulated; V band).

    Attributes
    ----------
    magnitudes : ndarray, shape (M,)
        Increasing magnitudes of the table.
    detected : ndarray, shape (M,)
        Probability that a star of each magnitude is detected at rest.
    sigma_px : ndarray, shape (M,)
        Centroid 1-sigma per axis, px.
    electrons : ndarray, shape (M,)
        Photo-electrons of a star of each magnitude in one exposure.
    n_false : float
        Mean number of false stars per frame (Poisson).
    """

    magnitudes: np.ndarray
    detected: np.ndarray
    sigma_px: np.ndarray
    electrons: np.ndarray
    n_false: float = 2.0

    @property
    def max_mag(self) -> float:
        """Faintest magnitude of the table with a non-zero detection probability."""
        on = np.flatnonzero(self.detected > 0)
        return float(self.magnitudes[on[-1]]) if len(on) else -math.inf

    def at(self, mags: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (detection probability, sigma px, electrons) of stars of magnitudes ``mags``.

        Linear in magnitude; the electrons log-linear (exact for a flux 10^(-0.4 m)).
        """
        m = self.magnitudes
        p = np.interp(mags, m, self.detected, left=self.detected[0], right=0.0)
        s = np.interp(mags, m, self.sigma_px)
        e = np.exp(np.interp(mags, m, np.log(self.electrons)))
        return p, s, e


def centroid_model(
    sensor, *, model: str = "reed", n_false: float = 2.0, n_slew_trials: int = 20, rng=0
) -> CentroidModel:
    """Tabulate the datasheet's detection and centroid-noise predictions for ``sensor``.

    Parameters
    ----------
    sensor : str, Path or Sensor
        Sensor preset, TOML file or object.
    model : str
        Sensitivity model (magnitude -> photo-electrons), as the datasheet's.
    n_false : float
        Mean false stars per frame, >= 0.
    n_slew_trials : int
        Rendered stamps per magnitude of the detection probability.
    rng : int
        Seed of the stamps.

    Returns
    -------
    CentroidModel

    Raises
    ------
    InputError
        Nothing is detected even at magnitude -2, or ``n_false`` < 0.
    """
    sens = as_sensor(sensor)
    if not (np.isfinite(n_false) and n_false >= 0):
        raise InputError(f"n_false must be a finite number >= 0, got {n_false!r}")
    mags = np.arange(-2.0, 16.0001, 0.25)
    rest = simulate_slew(
        sens, model=model, magnitudes=mags, rates_rad_s=[0.0], n_trials=n_slew_trials, rng=rng
    )
    detected = np.asarray(rest.detected_fraction[:, 0], dtype=float)
    limit = limiting_magnitude(mags, detected)
    if limit is None:
        raise InputError(f"{sens.name}: no star is detected, even at magnitude {mags[0]:g}")
    faint = float(mags[np.flatnonzero(detected > 0)[-1]])
    stars = StarModel.build(sens, model=model, bright_mag=float(mags[0]), faint_mag=faint)
    electrons = np.asarray(stars.sensitivity.electrons(mags), dtype=float)
    sigma = np.asarray(stars.noise.sigma(electrons), dtype=float)
    finite = np.isfinite(sigma)
    detected = np.where(finite, detected, 0.0)  # no centroid noise known: never detected
    sigma = np.where(finite, sigma, np.nanmax(np.where(finite, sigma, np.nan)))
    return CentroidModel(mags, detected, sigma, electrons, float(n_false))


@dataclass(frozen=True)
class SimulatedCentroids:
    """One frame's simulated centroids with their truth.

    Attributes
    ----------
    xy : ndarray, shape (N, 2)
        Centroids (x = column, y = row), px, true stars first then false ones.
    flux : ndarray, shape (N,)
        Measured brightness (photo-electrons with shot noise; false stars drawn).
    xy_true : ndarray, shape (N, 2)
        Noiseless positions of the true stars, px (NaN for false stars).
    sigma_px : ndarray, shape (N,)
        Centroid 1-sigma per axis of each, px (NaN for false stars).
    magnitudes : ndarray, shape (N,)
        V magnitudes (NaN for false stars).
    n_in_field : int
        Catalogue stars (to the table's faintest) on the detector, detected or not.
    rotation : Rotation
        The true attitude (ICRS -> camera).
    """

    xy: np.ndarray
    flux: np.ndarray
    xy_true: np.ndarray
    sigma_px: np.ndarray
    magnitudes: np.ndarray
    n_in_field: int
    rotation: object


def star_field(sensor, vectors: np.ndarray, magnitudes: np.ndarray):
    """Return the stars to simulate with their k-d tree and the field's search chord.

    Parameters
    ----------
    sensor : Sensor
    vectors : ndarray, shape (N, 3)
        ICRS unit vectors.
    magnitudes : ndarray, shape (N,)
        Their V magnitudes.

    Returns
    -------
    tuple
        (vectors, magnitudes, cKDTree, chord of the half-diagonal plus 0.6 deg), as
        :func:`simulate_centroids` takes it.
    """
    field_r = math.atan(math.hypot(*(math.tan(h) for h in sensor.half_fov_rad)))
    reach = 2.0 * math.sin(min(field_r + 0.01, math.pi / 2) / 2.0)
    return (vectors, magnitudes, cKDTree(vectors), reach)


def simulate_centroids(sensor, stars, cmodel: CentroidModel, *, rng) -> SimulatedCentroids:
    """Simulate one random frame's centroids (see the module docstring).

    Parameters
    ----------
    sensor : Sensor
        Projects the stars (optics and distortion) onto its detector.
    stars : tuple
        :func:`star_field`.
    cmodel : CentroidModel
        Detection probability, centroid noise, electrons per magnitude; false stars.
    rng : numpy.random.Generator or int
        The trial's stream (or its seed).

    Returns
    -------
    SimulatedCentroids
    """
    rng, _ = as_generator(rng)
    vectors, mags, tree, reach = stars
    truth = random_attitudes(1, rng)[0]
    m = truth.as_matrix()
    near = np.asarray(tree.query_ball_point(m[2], reach), dtype=np.intp)
    x, y = sensor.project(vectors[near] @ m.T)
    det = sensor.detector
    w, h = det.columns - 0.5, det.rows - 0.5
    on = (x >= -0.5) & (x < w) & (y >= -0.5) & (y < h)
    x, y, mag = x[on], y[on], mags[near[on]]
    p, sigma, e = cmodel.at(mag)
    seen = rng.random(len(mag)) < p
    x, y, sigma, e, mag = x[seen], y[seen], sigma[seen], e[seen], mag[seen]
    n = len(x)
    xy_true = np.column_stack([x, y])
    xy = xy_true + rng.normal(0.0, 1.0, (n, 2)) * sigma[:, None]
    flux = e + rng.normal(0.0, 1.0, n) * np.sqrt(e)
    n_false = int(rng.poisson(cmodel.n_false))
    lo, hi = (float(e.min()), float(e.max())) if n else (1.0, 10.0)
    fake = np.column_stack([rng.uniform(-0.5, w, n_false), rng.uniform(-0.5, h, n_false)])
    nan = np.full(n_false, np.nan)
    return SimulatedCentroids(
        xy=np.concatenate([xy, fake]),
        flux=np.concatenate([flux, np.exp(rng.uniform(math.log(lo), math.log(hi), n_false))]),
        xy_true=np.concatenate([xy_true, np.column_stack([nan, nan])]),
        sigma_px=np.concatenate([sigma, nan]),
        magnitudes=np.concatenate([mag, nan]),
        n_in_field=int(on.sum()),
        rotation=truth,
    )
