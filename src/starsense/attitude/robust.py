"""The final attitude of a solve, robust to a blended or double star."""

from __future__ import annotations

import dataclasses

import numpy as np

from starsense.attitude.estimate import estimate_attitude

__all__ = [
    "MISFIT_SIGMAS",
    "OUTLIER_SIGMA",
    "median_misfit",
    "pair_outliers",
    "residual_scaled",
    "robust_attitude",
]


#: a matched star whose residual exceeds this many of its own 1-sigma (per axis, so ~ sqrt(2)
#: sigma expected in angle) is dropped from the final attitude: a blend or a close double star
OUTLIER_SIGMA = 7.0
#: an attitude whose kept stars lie a median of more than this many of their own sigma from it
#: does not fit its measurements (right ones: 1.18); the solver reports no attitude
MISFIT_SIGMAS = 10.0


def pair_outliers(body, reference, sigma_rad) -> np.ndarray:
    """Return the stars whose angles to the others disagree with the catalogue's.

    The angle between two stars does not depend on the attitude: measured less catalogue, it
    is a normal error of variance ``sigma_i^2 + sigma_j^2`` (each star's error along the line
    joining them). A star centroided far from its own light (two streaks crossing, a capsule
    slid onto a neighbour) disagrees with most others; a right one agrees with every right one.
    A star is an outlier when the median of its normalised disagreements exceeds
    ``OUTLIER_SIGMA`` times the median of a half-normal (0.674): the median ignores the other
    outliers as long as they are fewer than half. Unlike the residuals of a fit, which one
    heavily weighted outlier can drag onto itself, this cannot be masked.

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars.
    sigma_rad : ndarray (N,)
        Each star's 1-sigma direction noise per axis, rad.

    Returns
    -------
    ndarray of bool (N,)
        True for an outlier (none when fewer than 5 stars, or half or more disagree).
    """
    n = len(body)
    if n < 5:
        return np.zeros(n, dtype=bool)

    def angles(v):
        cross = np.linalg.norm(np.cross(v[:, None, :], v[None, :, :]), axis=2)
        return np.arctan2(cross, v @ v.T)

    var = sigma_rad[:, None] ** 2 + sigma_rad[None, :] ** 2
    z = np.abs(angles(body) - angles(reference)) / np.sqrt(var)
    np.fill_diagonal(z, np.nan)
    bad = np.nanmedian(z, axis=1) > OUTLIER_SIGMA * _HALF_NORMAL_MEDIAN
    return bad if 2 * bad.sum() < n else np.zeros(n, dtype=bool)


#: the median of |x| for a unit normal x
_HALF_NORMAL_MEDIAN = 0.6744897501960817


def robust_attitude(body, reference, sigma_rad, *, max_drop: int = 5, keep=None):
    """Estimate the attitude, dropping the stars whose residual is an outlier.

    A blended or double star is identified right but centroided at the photocentre of the
    pair: its residual is many of its own sigma, and left in it pulls the attitude. The stars
    whose angles to the others disagree with the catalogue's are dropped first
    (:func:`pair_outliers`: several gross outliers, one of which a fit would follow); then,
    while the worst residual exceeds ``OUTLIER_SIGMA`` sigma and more than three stars remain,
    that star is dropped and the attitude re-estimated (SVD, Wahba weights 1 / sigma^2).

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars.
    sigma_rad : float or ndarray (N,)
        Each star's 1-sigma direction noise, rad.
    max_drop : int
        Most stars dropped.
    keep : ndarray (N,) of bool, optional
        The stars to start from (a refit after a first one's outliers), in place of
        :func:`pair_outliers`'.

    Returns
    -------
    AttitudeSolution, and the mask of the stars kept (N,)
    """
    sigma = np.broadcast_to(np.asarray(sigma_rad, dtype=float), (len(body),))
    keep = ~pair_outliers(body, reference, sigma) if keep is None else np.array(keep, dtype=bool)
    att = estimate_attitude(body[keep], reference[keep], sigma[keep], method="svd")
    for _ in range(max_drop):
        if keep.sum() <= 3:
            break
        z = np.full(len(body), -np.inf)
        z[keep] = att.residuals_rad / sigma[keep]
        worst = int(np.argmax(z))
        if z[worst] <= OUTLIER_SIGMA:
            break
        keep[worst] = False
        att = estimate_attitude(body[keep], reference[keep], sigma[keep], method="svd")
    return att, keep


def median_misfit(body, reference, sigma_rad, *, rotation, keep=None) -> float:
    """Return the median of the stars' residuals to an attitude in units of their own sigma.

    ``body`` (N, 3) camera-frame and ``reference`` (N, 3) unit vectors, ``sigma_rad`` (N,) or a
    number, ``rotation`` reference -> camera, ``keep`` (N,) the stars to count (default all).
    Right measurements give about 1.18 (the median of a 2-d residual of per-axis sigma 1);
    measurements all off their stars by many of their sigmas give that many.
    """
    body = np.asarray(body, dtype=float)
    keep = np.ones(len(body), bool) if keep is None else np.asarray(keep, bool)
    if not keep.any():
        return 0.0
    seen = rotation.apply(np.asarray(reference, dtype=float)[keep])
    angle = np.linalg.norm(np.cross(body[keep], seen), axis=1)
    sigma = np.broadcast_to(np.asarray(sigma_rad, dtype=float), (len(body),))[keep]
    return float(np.median(angle / sigma))


def residual_scaled(att):
    """Return ``att`` with its covariance raised by its residuals' chi-square when above 1.

    The covariance of a Wahba fit assumes the stars' sigmas; where the residuals scatter more
    (``2 loss / (2 N - 3)`` above 1: a centroid pulled by light its sigma does not hold, a
    lens's distortion left), the variance is scaled by that ratio (the Birge ratio), so the
    reported sigma stays what the stars show. Never lowered: with few stars the ratio
    scatters (by ``sqrt(2 / dof)``) and a sigma below the stars' own would be a guess.
    """
    dof = att.chi2_dof
    if dof <= 0 or not np.isfinite(att.loss):
        return att
    ratio = 2.0 * float(att.loss) / dof
    if ratio <= 1.0:
        return att
    return dataclasses.replace(att, covariance_rad2=np.asarray(att.covariance_rad2) * ratio)
