"""Per-axis attitude errors: X, Y (cross-boresight, each on its own) and Z (about the boresight).

The datasheet's "cross" is the rms of the X and Y axes, ``sqrt((P_xx + P_yy) / 2)``
(:func:`starsense.analysis.datasheet.field.axis_sigmas`); a performance statement gives X and
Y apart (ECSS-E-ST-60-20C): the diagonal of the same covariance, so that per attitude
``X^2 + Y^2 = 2 cross^2`` and Z is the datasheet's roll.
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.datasheet.field import FieldStarsCam, sandwich_terms
from starsense.attitude.covariance import SINGULAR_RCOND

__all__ = ["covariance_axes", "fisher_axes", "propagated_axes"]


def _regular(f: np.ndarray) -> np.ndarray:
    """Return which Fisher matrices (M, 3, 3) fix the attitude (not singular)."""
    eig = np.linalg.eigvalsh(f)
    return eig[:, 0] > SINGULAR_RCOND * np.maximum(eig[:, -1], np.finfo(float).tiny)


def covariance_axes(cov: np.ndarray) -> np.ndarray:
    """Return the 1-sigma per camera axis (M, 3) of covariances (M, 3, 3): sqrt of the diagonal."""
    return np.sqrt(np.maximum(np.diagonal(np.asarray(cov, dtype=float), axis1=1, axis2=2), 0.0))


def fisher_axes(fishers: np.ndarray) -> np.ndarray:
    """Return the 1-sigma X, Y, Z (M, 3) of attitude Fisher matrices (camera frame), rad.

    Parameters
    ----------
    fishers : ndarray (M, 3, 3)
        rad^-2.

    Returns
    -------
    ndarray (M, 3)
        rad; NaN where the matrix is singular (fewer than two usable stars).
    """
    f = np.asarray(fishers, dtype=float)
    out = np.full((len(f), 3), np.nan)
    ok = _regular(f)
    if ok.any():
        out[ok] = covariance_axes(np.linalg.inv(f[ok]))
    return out


def propagated_axes(
    pairs: FieldStarsCam, weights, error_rad, *, presence=None, shape=None, efficient=False
) -> np.ndarray:
    """Return the X, Y, Z error (M, 3) that per-star errors make through the weighted fit, rad.

    The weighted least-squares sandwich ``F^-1 G F^-1`` with ``F = sum w (I - r r^T)`` and
    ``G = sum w^2 e^2 (I - r r^T)`` (:func:`starsense.analysis.datasheet.field.
    propagated_sigmas`, whose cross is the rms of this X and Y and whose roll is this Z).

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        The estimator's weight of each pair, rad^-2.
    error_rad : ndarray (P,)
        Each pair's error, 1 sigma per axis, rad.
    presence : ndarray (P,), optional
        The chance each pair's star is in the fit (the expected sums); default 1.
    shape, efficient
        A PSF that is not round, and whether the error is the weighing fit's own noise
        (:func:`~starsense.analysis.datasheet.field.sandwich_terms`).

    Returns
    -------
    ndarray (M, 3)
        rad; NaN where F is singular.
    """
    f, g = sandwich_terms(
        pairs, weights, error_rad, presence=presence, shape=shape, efficient=efficient
    )
    out = np.full((len(f), 3), np.nan)
    ok = _regular(f)
    if ok.any():
        finv = np.linalg.inv(f[ok])
        out[ok] = covariance_axes(finv @ g[ok] @ finv)
    return out
