"""Covariance of an attitude estimate, in the camera frame.

The covariance is that of the camera-frame error rotation vector of
:func:`starsense.geometry.attitude.small_rotation_angles` (x, y cross-boresight, z roll).
Measurement model (Shuster & Oh 1981, "QUEST measurement model"): each measured unit vector
``b_i`` is the true one displaced in its tangent plane by isotropic Gaussian noise of ``sigma_i``
rad per axis.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from starsense.analysis.limits import covariance, fisher_matrix
from starsense.attitude.solution import cross3

__all__ = ["fisher_covariance", "triad_covariance"]


def fisher_covariance(
    body: NDArray[np.float64], sigma_rad: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Inverse Fisher matrix of the attitude, the covariance of an optimal estimator.

    Implements Fialho & Mortari 2019, eqs. 20-21 with per-star weights ``sigma_i^-2``::

        F = sum_i sigma_i^-2 (I_3 - b_i b_i^T),        P = F^-1

    using the measured camera-frame vectors ``b_i``, so ``P`` is in the camera frame. This is
    also the covariance of the QUEST/q-method/SVD solution to first order in sigma
    (Shuster & Oh 1981).

    Parameters
    ----------
    body : ndarray, shape (N, 3)
        Measured camera-frame unit vectors.
    sigma_rad : ndarray, shape (N,)
        Per-axis angular noise of each vector, rad.

    Returns
    -------
    ndarray, shape (3, 3)
        Covariance, rad^2.

    Raises
    ------
    SingularGeometryError
        If the vectors do not constrain every rotation axis (all parallel or antipodal).
    """
    return covariance(fisher_matrix(body, sigma_rad**-2.0), body.shape[0])


def triad_covariance(
    b1: NDArray[np.float64], b2: NDArray[np.float64], sigma1_rad: float, sigma2_rad: float
) -> NDArray[np.float64]:
    """Covariance of the TRIAD attitude with ``b1`` as the anchor (Shuster & Oh 1981)::

        P = s1^2 I + |b1 x b2|^-2 [ (s2^2 - s1^2) b1 b1^T + s1^2 (b1 . b2)(b1 b2^T + b2 b1^T) ]

    Parameters
    ----------
    b1, b2 : ndarray, shape (3,)
        The anchor and the second measured unit vector, camera frame (not parallel).
    sigma1_rad, sigma2_rad : float
        Their per-axis angular noise, rad.

    Returns
    -------
    ndarray, shape (3, 3)
        Covariance of the camera-frame error rotation vector, rad^2.
    """
    c = float(b1 @ b2)
    s2 = float(np.sum(cross3(b1, b2) ** 2))
    return (
        sigma1_rad**2 * np.eye(3)
        + (
            (sigma2_rad**2 - sigma1_rad**2) * np.outer(b1, b1)
            + sigma1_rad**2 * c * (np.outer(b1, b2) + np.outer(b2, b1))
        )
        / s2
    )
