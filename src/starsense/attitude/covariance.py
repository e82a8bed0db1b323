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

from starsense.attitude.solution import cross3
from starsense.errors import InputError, SingularGeometryError

__all__ = [
    "covariance",
    "fisher_components",
    "fisher_covariance",
    "fisher_from_components",
    "fisher_matrix",
    "theta_rms",
    "triad_covariance",
]

SINGULAR_RCOND = 1e-10
"""Smallest eigenvalue ratio of a Fisher matrix taken as non-singular."""


def fisher_matrix(vectors, weights) -> np.ndarray:
    """Compute the attitude Fisher information matrix, eq. 21: sum_i w_i (I - r_i r_i^T).

    The one copy of eq. 21 in the package: the in-memory limit, the distributed per-chunk sums
    (:func:`fisher_components`) and the estimators' covariances all come back here.

    Parameters
    ----------
    vectors : array (N, 3) or (M, N, 3)
        Unit vectors of the stars (a batch of M star sets for the 3-d form).
    weights : array (N,) or (M, N)
        Per-star centroid Fisher information, rad^-2.

    Returns
    -------
    array (3, 3) or (M, 3, 3)
        rad^-2.
    """
    r = np.asarray(vectors, dtype=float)
    w = np.asarray(weights, dtype=float)
    if r.ndim == 2:
        s = (r * w[:, None]).T @ r
        return w.sum() * np.eye(3) - s
    s = np.swapaxes(r * w[..., None], -1, -2) @ r
    return w.sum(axis=-1)[..., None, None] * np.eye(3) - s


def fisher_components(vectors, weights) -> np.ndarray:
    """Return the seven independent terms of eq. 21 per star: w, wx^2, wy^2, wz^2, wxy, wxz, wyz.

    Parameters
    ----------
    vectors : array (N, 3)
        Unit vectors of the stars.
    weights : array (N,)
        Per-star centroid Fisher information, rad^-2.

    Returns
    -------
    array (N, 7)
        Any sum of rows is the (sum w, sum w r r^T) of those stars: sums over chunks of a
        catalogue add exactly, and :func:`fisher_from_components` turns a sum into F.
    """
    r = np.asarray(vectors, dtype=float)
    w = np.asarray(weights, dtype=float)
    return np.column_stack(
        [
            w,
            w * r[:, 0] ** 2,
            w * r[:, 1] ** 2,
            w * r[:, 2] ** 2,
            w * r[:, 0] * r[:, 1],
            w * r[:, 0] * r[:, 2],
            w * r[:, 1] * r[:, 2],
        ]
    )


def fisher_from_components(sums) -> np.ndarray:
    """Return eq. 21's F = sum w I - sum w r r^T from summed :func:`fisher_components`.

    Parameters
    ----------
    sums : array (7,) or (M, 7)
        One row (or a batch of rows) of summed components.

    Returns
    -------
    array (3, 3) or (M, 3, 3)
        rad^-2.
    """
    s = np.asarray(sums, dtype=float)
    sw, xx, yy, zz, xy, xz, yz = np.moveaxis(s, -1, 0)
    outer = np.stack(
        [
            np.stack([xx, xy, xz], axis=-1),
            np.stack([xy, yy, yz], axis=-1),
            np.stack([xz, yz, zz], axis=-1),
        ],
        axis=-2,
    )
    return np.asarray(sw)[..., None, None] * np.eye(3) - outer


def covariance(fisher: np.ndarray, n_stars: int | None = None) -> np.ndarray:
    """P = F^-1 (eq. 20), with a specific error when F is singular.

    F is singular exactly when all stars lie along one axis (a single star, or stars at the same
    or antipodal points): a rotation about that axis moves none of them.
    """
    f = np.asarray(fisher, dtype=float)
    if not np.isfinite(f).all():
        raise InputError("Fisher matrix has non-finite entries (NaN or inf in the star data)")
    eig = np.linalg.eigvalsh(f)
    stars = "" if n_stars is None else f" ({n_stars} star{'s' if n_stars != 1 else ''})"
    if eig[-1] <= 0 or eig[0] <= SINGULAR_RCOND * eig[-1]:
        raise SingularGeometryError(
            f"singular geometry{stars}: the stars do not constrain rotation about every axis "
            "(at least two stars in distinct, non-antipodal directions are needed)"
        )
    return np.linalg.inv(f)


def theta_rms(cov: np.ndarray) -> float:
    """sqrt(tr P): the rms attitude error angle, eq. 22."""
    return float(np.sqrt(np.trace(cov)))


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
    b1: NDArray[np.float64], b2: NDArray[np.float64], *, sigma1_rad: float, sigma2_rad: float
) -> NDArray[np.float64]:
    """Return the covariance of the TRIAD attitude with ``b1`` as the anchor (Shuster & Oh 1981).

    The closed form::

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
