"""Davenport's q-method: the attitude quaternion is the top eigenvector of the 4x4 K matrix.

With normalised weights ``a_i = w_i / sum_j w_j`` (``w_i = sigma_i^-2``), the attitude profile
matrix and its derived quantities are (Markley & Crassidis 2014, sec. 5.5; the sign of ``z``
follows scipy's scalar-last quaternion of the ICRS -> camera rotation)::

    B = sum_i a_i b_i r_i^T,   S = B + B^T,   sigma = tr B,   z = sum_i a_i r_i x b_i

    K = [[S - sigma I_3, z],
         [z^T,         sigma]]

The gain ``g(q) = 1 - L/sum(w) = q^T K q`` is maximised by the unit eigenvector of K with the
largest eigenvalue ``lambda_max``; the loss is ``L = sum(w) (1 - lambda_max)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense.attitude.covariance import fisher_covariance
from starsense.attitude.solution import Estimator

__all__ = ["DavenportEstimator", "attitude_profile_matrix", "davenport_k_matrix", "q_method"]


def attitude_profile_matrix(
    body: NDArray[np.float64], reference: NDArray[np.float64], weights: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``B = sum_i a_i b_i r_i^T`` with the weights normalised to sum 1.

    Parameters
    ----------
    body, reference : ndarray, shape (N, 3)
        Unit camera-frame and ICRS vectors.
    weights : ndarray, shape (N,)
        Positive weights (any scale), e.g. sigma^-2.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    a = weights / np.sum(weights)
    return (body * a[:, None]).T @ reference


def davenport_k_matrix(b_matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    """Davenport's symmetric 4x4 K matrix from the attitude profile matrix B.

    Parameters
    ----------
    b_matrix : ndarray, shape (3, 3)
        ``B = sum_i a_i b_i r_i^T``.

    Returns
    -------
    ndarray, shape (4, 4)
        K for scalar-last quaternions: ``q^T K q = tr(A(q) B^T)`` where ``A(q)`` is scipy's
        ``Rotation.from_quat(q).as_matrix()``.
    """
    s = b_matrix + b_matrix.T
    sigma = np.trace(b_matrix)
    z = np.array(
        [
            b_matrix[2, 1] - b_matrix[1, 2],
            b_matrix[0, 2] - b_matrix[2, 0],
            b_matrix[1, 0] - b_matrix[0, 1],
        ]
    )
    k = np.empty((4, 4))
    k[:3, :3] = s - sigma * np.eye(3)
    k[:3, 3] = z
    k[3, :3] = z
    k[3, 3] = sigma
    return k


def q_method(
    body: NDArray[np.float64], reference: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[Rotation, NDArray[np.float64]]:
    """Solve Wahba's problem by the q-method (Davenport 1968).

    Parameters
    ----------
    body, reference : ndarray, shape (N, 3)
        Unit camera-frame and ICRS vectors.
    weights : ndarray, shape (N,)
        Positive weights, e.g. sigma^-2.

    Returns
    -------
    rotation : Rotation
        The attitude, ICRS -> camera.
    eigenvalues : ndarray, shape (4,)
        Eigenvalues of K in ascending order (normalised weights: all in [-1, 1]); the gap
        between the last two says how well the problem is conditioned.
    """
    k = davenport_k_matrix(attitude_profile_matrix(body, reference, weights))
    eigenvalues, eigenvectors = np.linalg.eigh(k)
    return Rotation.from_quat(eigenvectors[:, -1]), eigenvalues


@dataclass(frozen=True)
class DavenportEstimator(Estimator):
    """Davenport's q-method estimator (configure, then call with the observations).

    Calling it with ``(body_vectors (N, 3), reference_vectors (N, 3), sigma_rad)`` returns an
    :class:`~starsense.attitude.solution.AttitudeSolution`; weights are ``sigma^-2`` and the
    covariance is the inverse Fisher matrix (Fialho & Mortari 2019, eq. 21).
    """

    method = "davenport"

    def _solve(self, body, reference, sigma):
        cov = fisher_covariance(body, sigma)
        rotation, _ = q_method(body, reference, sigma**-2.0)
        return rotation, cov, (), self.method
