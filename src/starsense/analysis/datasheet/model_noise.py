"""The datasheet's noise when the solver fits the forward model: its Cramer-Rao bound.

The default solver refines every attitude by maximum likelihood on the identified stars' pixels
(:mod:`starsense.solve.refine`), which attains the model's Fisher information
(:mod:`starsense.model.fisher`). Its noise-equivalent angle is therefore that information,
summed over the stars of each attitude through the projection:

- at rest, each star's position information depends on its electrons alone (averaged over its
  sub-pixel phase): :func:`model_centroid_noise` tabulates its mean over the two axes as a
  :class:`~starsense.analysis.datasheet.noise.CentroidNoise` whose noise, the solver's weights
  and the bound are the same number (an efficient estimator weighs each star by its own
  information) and whose sub-pixel bias is zero (the model holds the pixel response); a PSF
  that is not round adds its anisotropy (:func:`model_noise_and_shape`);
- under a body rate, each star is a streak whose information is anisotropic (less along the
  streak): :func:`model_nea_at_rate` sums ``J^T I J`` per attitude (the rate is a nuisance of
  the fit, nearly uncorrelated with the attitude: a symmetric streak's mid-point does not move
  with its length).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.analysis.datasheet.field import axis_sigmas, field_stars_cam
from starsense.analysis.datasheet.noise import CentroidNoise
from starsense.analysis.datasheet.terms import PixelSpatialError
from starsense.model.boxes import window_capacity
from starsense.model.fisher import attitude_information, position_information
from starsense.model.psf import psf_of
from starsense.model.tracks import time_nodes
from starsense.model.windows import window_half_px

__all__ = [
    "ROUND_SHAPE",
    "fit_holds_at_rate",
    "model_centroid_noise",
    "model_fisher_at_rate",
    "model_nea_at_rate",
    "model_noise_and_shape",
    "streaks_px_of",
    "zero_pixel_bias",
]

#: sub-pixel phases per axis of a star at rest (a streak averages its phases along itself: 2)
N_PHASE_REST, N_PHASE_STREAK = 4, 2
#: an anisotropy below this (a, c of model_noise_and_shape) is a round PSF's
ROUND_SHAPE = 1e-3


def model_centroid_noise(
    sensor, electrons_min: float, electrons_max: float, *, n_grid: int = 16
) -> CentroidNoise:
    """Tabulate the model fit's position noise against electrons (px, one axis).

    Parameters
    ----------
    sensor : Sensor
    electrons_min, electrons_max : float
        Range of the table, photo-electrons.
    n_grid : int
        Table points, log-spaced.

    Returns
    -------
    CentroidNoise
        ``sigma_px``, ``solver_sigma_px``, ``crb_px``, ``window_model_px``: the bound; biases 0.
    """
    return model_noise_and_shape(sensor, electrons_min, electrons_max, n_grid=n_grid)[0]


def model_noise_and_shape(sensor, electrons_min: float, electrons_max: float, *, n_grid: int = 16):
    """Return :func:`model_centroid_noise`'s table and the shape of the same information.

    A star's position information at rest is the 2 x 2 ``I = m (I + D)``: ``m`` its mean over
    the two axes (the table's ``1 / sigma^2``) and ``D = [[a, c], [c, -a]]`` its anisotropy,
    zero for a round PSF (Gaussian, Airy, Moffat), not for a lens with astigmatism or coma,
    whose star is located better across its long axis than along it: the attitude axes that
    move stars along it are then the less certain
    (:func:`~starsense.analysis.datasheet.field.fisher_per_pointing`'s ``shape``).

    Returns
    -------
    CentroidNoise, and (electrons (K,), a (K,), c (K,)) or None
        None where the PSF is round (``|a|, |c| < 1e-3`` on the whole table: a round PSF's
        phases average to within ~1e-4 of it).
    """
    lo = max(float(electrons_min), 1.0)
    hi = max(float(electrons_max), 2.0 * lo)
    grid = np.geomspace(lo, hi, int(n_grid))
    info = position_information(sensor, grid, n_phase=N_PHASE_REST)
    mean = 0.5 * (info[:, 0, 0] + info[:, 1, 1])
    sigma = np.where(mean > 0, 1.0 / np.sqrt(np.where(mean > 0, mean, 1.0)), np.nan)
    zero = np.zeros(len(grid))
    side = np.full(len(grid), 2.0 * window_half_px(psf_of(sensor)) + 1.0)
    noise = CentroidNoise(grid, sigma, sigma, zero, zero, side, sigma, zero, sigma)
    safe = np.where(mean > 0, mean, 1.0)
    a = np.where(mean > 0, 0.5 * (info[:, 0, 0] - info[:, 1, 1]) / safe, 0.0)
    c = np.where(mean > 0, info[:, 0, 1] / safe, 0.0)
    if max(float(np.max(np.abs(a))), float(np.max(np.abs(c)))) < ROUND_SHAPE:
        return noise, None
    return noise, (grid, a, c)


def zero_pixel_bias(electrons) -> PixelSpatialError:
    """Return the model fit's sub-pixel bias: none (its model integrates the PSF over pixels)."""
    e = np.asarray(electrons, dtype=float)
    return PixelSpatialError(e, np.zeros(len(e)), np.zeros(len(e)), 0)


def streaks_px_of(sensor, v_cam, rates_rad_s) -> tuple[np.ndarray, np.ndarray]:
    """Mid-exposure pixel positions (P, 2) and streaks, start to end (P, 2), of stars v_cam."""
    v_cam = np.array(v_cam, dtype=float)  # a writable copy (Rotation.apply needs one)
    half = Rotation.from_rotvec(np.asarray(rates_rad_s) * 0.5 * sensor.exposure_s)
    x, y = sensor.project(v_cam)
    xs, ys = sensor.project(half.apply(v_cam))
    xe, ye = sensor.project(half.inv().apply(v_cam))
    return np.column_stack([x, y]), np.column_stack([xe - xs, ye - ys])


def model_nea_at_rate(model, fov, matrices, *, rates_rad_s, vectors, magnitudes, presence=None):
    """Return the model fit's 1-sigma (cross, roll) of attitudes at body rates, rad.

    The axis sigmas of :func:`model_fisher_at_rate` (same parameters).

    Returns
    -------
    cross, roll : ndarray (M,)
        rad; NaN where the stars do not fix the attitude.
    """
    return axis_sigmas(
        model_fisher_at_rate(
            model,
            fov,
            matrices,
            rates_rad_s=rates_rad_s,
            vectors=vectors,
            magnitudes=magnitudes,
            presence=presence,
        )
    )


def model_fisher_at_rate(model, fov, matrices, *, rates_rad_s, vectors, magnitudes, presence=None):
    """Return the model fit's attitude Fisher information at body rates, camera frame, rad^-2.

    Parameters
    ----------
    model : StarModel
        Its sensor and sensitivity (magnitude -> electrons).
    fov : RectangularFov
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.
    rates_rad_s : ndarray (M, 3)
        Body rate of each attitude, camera frame, rad/s.
    vectors, magnitudes : ndarray (N, 3), (N,)
        The stars the fit may use, ICRS, V.
    presence : ndarray (N,), optional
        The chance each is in the fit (detected at the rate): its information counts by it
        (the expected sum). Default: always.

    Returns
    -------
    ndarray (M, 3, 3)
        Per attitude, the sum over its stars of ``J^T I J`` (each streak's position
        information through the projection).
    """
    sensor = model.sensor
    pairs = field_stars_cam(fov, np.asarray(matrices), np.asarray(vectors))
    chance = np.ones(len(pairs.star)) if presence is None else np.asarray(presence)[pairs.star]
    point, v_cam, star = pairs.point[chance > 0], pairs.v_cam[chance > 0], pairs.star[chance > 0]
    rates = np.asarray(rates_rad_s, dtype=float).reshape(-1, 3)[point]
    electrons = model.sensitivity.electrons(np.asarray(magnitudes)[star])
    _, streaks = streaks_px_of(sensor, v_cam, rates)
    info = position_information(sensor, electrons, streaks, n_phase=N_PHASE_STREAK)
    per_star = attitude_information(sensor, v_cam, info) * chance[chance > 0][:, None, None]
    fisher = np.zeros((pairs.n_pointings, 3, 3))
    np.add.at(fisher, point, per_star)
    return fisher


def fit_holds_at_rate(sensor, fov, matrices, *, rates_rad_s, vectors, magnitudes, n_stars):
    """Return whether the model fit holds the streaks of each attitude at its body rate (M,).

    The solver first fits its identified stars at their streaks' rate, each in the window of
    its track; where those windows pass what a fit may hold
    (:func:`starsense.model.boxes.window_capacity`: the groups' padded pixels, the model's
    pixel-nodes), it keeps its centroids' attitude. The identified stars are taken as the
    ``n_stars`` brightest in view (the run's matched count); the catalogue neighbours the fit
    also draws add to its work only, and are left out (the test is the pixels' for long
    streaks, which it is about).

    Parameters
    ----------
    sensor : Sensor
    fov : RectangularFov
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.
    rates_rad_s : ndarray (M, 3)
        Body rate of each, camera frame, rad/s.
    vectors, magnitudes : ndarray (N, 3), (N,)
        The stars the fit may use, ICRS, V.
    n_stars : array_like of int (M,)
        The stars fitted at each attitude.

    Returns
    -------
    ndarray of bool (M,)
    """
    psf = psf_of(sensor)
    half = window_half_px(psf)
    pairs = field_stars_cam(fov, np.asarray(matrices), np.asarray(vectors))
    rates = np.asarray(rates_rad_s, dtype=float).reshape(-1, 3)[pairs.point]
    mids, streaks = streaks_px_of(sensor, pairs.v_cam, rates)
    mags = np.asarray(magnitudes, dtype=float)[pairs.star]
    # the pairs by pointing, brightest first within each: one sort, then each pointing's slice
    order = np.lexsort((mags, pairs.point))
    bounds = np.searchsorted(pairs.point[order], np.arange(pairs.n_pointings + 1))
    out = np.ones(pairs.n_pointings, dtype=bool)
    for m, n in enumerate(np.asarray(n_stars, dtype=int)):
        mine = order[bounds[m] : bounds[m] + max(min(int(n), bounds[m + 1] - bounds[m]), 0)]
        if not len(mine):
            continue
        lengths = np.hypot(streaks[mine, 0], streaks[mine, 1])
        frac, _ = time_nodes(float(np.max(lengths)), psf.sigma_px)
        x = mids[mine, 0, None] + frac[None, :] * streaks[mine, 0, None]
        y = mids[mine, 1, None] + frac[None, :] * streaks[mine, 1, None]
        out[m] = not window_capacity(x, y, half_px=half, free=np.ones(len(mine), dtype=bool))
    return out
