"""Attitude noise over the sky: per-star sigmas through eq. 21, pointing by pointing.

For every attitude of a set (quasi-uniform boresights, or the Monte Carlo's true attitudes),
the catalogue stars inside the sensor's rectangular field are found once
(:func:`starsense.analysis.availability.field.field_pairs`), put in the camera frame, and
their per-star information ``1 / sigma_i^2`` summed into the attitude Fisher matrix (Fialho &
Mortari 2019, eq. 21, :func:`starsense.attitude.covariance.fisher_components`). The inverse,
in the camera frame, gives the 1-sigma cross-boresight (rms of the x and y axes) and roll
(about z) of that attitude.

The stars are those the solver fits its attitude to, each counted by its chance of being in a
frame's fit (:mod:`starsense.analysis.datasheet.stars`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from starsense.analysis.availability.field import field_pairs_cam
from starsense.attitude.covariance import (
    SINGULAR_RCOND,
    fisher_components,
    fisher_from_components,
)

__all__ = [
    "FieldStarsCam",
    "axis_sigmas",
    "field_stars_cam",
    "fisher_per_pointing",
    "propagated_covariance",
    "propagated_sigmas",
    "sandwich_terms",
]


class FieldStarsCam:
    """The (pointing, star) pairs of a set of attitudes, with camera-frame star vectors.

    Parameters
    ----------
    point : ndarray (P,) of int
        Pointing of each pair.
    star : ndarray (P,) of int
        Catalogue index of each pair.
    v_cam : ndarray (P, 3)
        Star unit vector in the camera frame.
    n_pointings : int
        Number of attitudes.
    """

    def __init__(self, point, star, v_cam, *, n_pointings: int) -> None:
        self.point = point
        self.star = star
        self.v_cam = v_cam
        self.n_pointings = int(n_pointings)

    def counts(self, mask: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
        """Return the stars per pointing (only the pairs in ``mask`` if given)."""
        p = self.point if mask is None else self.point[mask]
        return np.bincount(p, minlength=self.n_pointings)


def field_stars_cam(fov, matrices: NDArray[np.float64], vectors: NDArray[np.float64], *, tree=None):
    """Return the :class:`FieldStarsCam` of attitudes ``matrices`` (M, 3, 3), ICRS -> camera."""
    point, star, v_cam = field_pairs_cam(fov, matrices, vectors, tree=tree)
    return FieldStarsCam(point, star, v_cam, n_pointings=matrices.shape[0])


def fisher_per_pointing(pairs: FieldStarsCam, weights: NDArray[np.float64]) -> np.ndarray:
    """Return eq. 21 per pointing, camera frame, (M, 3, 3) rad^-2.

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        Information of each pair's star, ``1 / sigma^2``, rad^-2 (0 drops the pair).
    """
    comp = fisher_components(pairs.v_cam, weights)
    sums = np.zeros((pairs.n_pointings, 7))
    point = np.asarray(pairs.point)
    if point.size and np.all(point[1:] >= point[:-1]):  # grouped by pointing: segment sums
        starts = np.searchsorted(point, np.arange(pairs.n_pointings))
        held = np.bincount(point, minlength=pairs.n_pointings) > 0
        sums[held] = np.add.reduceat(comp, starts[held], axis=0)
    else:
        np.add.at(sums, point, comp)
    return fisher_from_components(sums)


def axis_sigmas(fishers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the 1-sigma cross-boresight (per axis, rms of x and y) and roll of each Fisher.

    Parameters
    ----------
    fishers : ndarray (M, 3, 3)
        Camera-frame attitude Fisher matrices, rad^-2.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad; NaN where the matrix is singular (fewer than two usable stars).
    """
    f = np.asarray(fishers, dtype=float)
    eig = np.linalg.eigvalsh(f)
    ok = eig[:, 0] > SINGULAR_RCOND * np.maximum(eig[:, -1], np.finfo(float).tiny)
    cross = np.full(len(f), np.nan)
    roll = np.full(len(f), np.nan)
    if ok.any():
        p = np.linalg.inv(f[ok])
        cross[ok] = np.sqrt(0.5 * (p[:, 0, 0] + p[:, 1, 1]))
        roll[ok] = np.sqrt(p[:, 2, 2])
    return cross, roll


def propagated_sigmas(
    pairs: FieldStarsCam,
    weights: NDArray[np.float64],
    error_rad: NDArray[np.float64],
    *,
    presence: NDArray[np.float64] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return the attitude error a per-star error makes through the weighted estimate, rad.

    The estimator weights each star by ``weights`` (its NEA information, eq. 21); a star
    carrying an independent error of ``error_rad`` (1 sigma per axis: a sub-pixel bias met at a
    random phase, a PRNU-driven shift, a calibration residual) moves the estimate by the
    weighted least-squares sandwich ``F^-1 G F^-1``, with ``F = sum w (I - r r^T)`` and
    ``G = sum w^2 e^2 (I - r r^T)``: an error, not a weight, so stars with small errors do not
    hide the others.

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        The estimator's weight of each pair, rad^-2.
    error_rad : ndarray (P,)
        Each pair's error, 1 sigma per axis, rad.
    presence : ndarray (P,), optional
        The chance each pair's star is in the fit (detected): both sums are their expectations
        over the frames, ``sum p w`` and ``sum p w^2 e^2``. Default: every star, always.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad (rms of x and y; about z); NaN where F is singular.
    """
    return _sandwich(*sandwich_terms(pairs, weights, error_rad, presence=presence))


def sandwich_terms(
    pairs: FieldStarsCam, weights, error_rad, *, presence=None
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``F = sum p w (I - r r^T)`` and ``G = sum p w^2 e^2 (I - r r^T)`` per attitude.

    The two sums (M, 3, 3) of :func:`propagated_sigmas`' sandwich ``F^-1 G F^-1``
    (``weights`` (P,) rad^-2 and ``error_rad`` (P,) rad per pair, a non-finite one counting as
    0; ``presence`` (P,) the chance each star is in the fit, default 1).
    """
    w = np.where(np.isfinite(weights), weights, 0.0)
    e2 = np.where(np.isfinite(error_rad), np.asarray(error_rad, dtype=float) ** 2, 0.0)
    p = 1.0 if presence is None else np.asarray(presence, dtype=float)
    return fisher_per_pointing(pairs, p * w), fisher_per_pointing(pairs, p * w * w * e2)


def _sandwich(f: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return cross and roll (rad) of ``F^-1 G F^-1`` per pointing; NaN where F is singular."""
    eig = np.linalg.eigvalsh(f)
    ok = eig[:, 0] > SINGULAR_RCOND * np.maximum(eig[:, -1], np.finfo(float).tiny)
    cross = np.full(len(f), np.nan)
    roll = np.full(len(f), np.nan)
    if ok.any():
        finv = np.linalg.inv(f[ok])
        cov = finv @ g[ok] @ finv
        cross[ok] = np.sqrt(0.5 * (cov[:, 0, 0] + cov[:, 1, 1]))
        roll[ok] = np.sqrt(cov[:, 2, 2])
    return cross, roll


def propagated_covariance(
    pairs: FieldStarsCam, weights: NDArray[np.float64], cov_rad2: NDArray[np.float64]
) -> tuple[np.ndarray, np.ndarray]:
    """Return the attitude error per-star error covariances make through the weighted estimate.

    :func:`propagated_sigmas` for errors that are not the same on both axes (a streak's
    centroid is worse along it than across): the weighted least-squares sandwich
    ``F^-1 G F^-1`` with ``F = sum w (I - r r^T)`` and ``G = sum w^2 [r]x^T C [r]x``, ``C``
    each star's 3 x 3 error covariance in the plane normal to it (for ``C = e^2 (I - r r^T)``
    this is :func:`propagated_sigmas`).

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        The estimator's weight of each pair, rad^-2.
    cov_rad2 : ndarray (P, 3, 3)
        Each pair's error covariance (camera frame), rad^2.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad (rms of x and y; about z); NaN where F is singular.
    """
    w = np.where(np.isfinite(weights), weights, 0.0)
    c = np.where(np.isfinite(cov_rad2), np.asarray(cov_rad2, dtype=float), 0.0)
    r = np.asarray(pairs.v_cam, dtype=float)
    skew = np.zeros((len(r), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew -= np.transpose(skew, (0, 2, 1))
    terms = (w * w)[:, None, None] * np.einsum("pji,pjk,pkl->pil", skew, c, skew)
    g = np.zeros((pairs.n_pointings, 3, 3))
    np.add.at(g, np.asarray(pairs.point), terms)
    f = fisher_per_pointing(pairs, w)
    return _sandwich(f, g)
