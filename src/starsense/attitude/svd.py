"""The SVD solution of Wahba's problem (Markley 1988), through scipy's ``Rotation.align_vectors``.

``align_vectors(b, r, weights)`` returns the rotation ``C`` minimising
``1/2 sum_i w_i |b_i - C r_i|^2`` (Kabsch algorithm: SVD of ``B = sum_i w_i b_i r_i^T``,
``C = U diag(1, 1, det U det V) V^T``), which is the ICRS -> camera attitude.

:class:`SvdEstimator` solves one problem with per-star weights; :func:`batch_svd_attitude` solves
many equal-weight problems at once (the Monte Carlo form).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from starsense.attitude.covariance import fisher_covariance
from starsense.attitude.solution import Estimator

__all__ = ["SvdEstimator", "batch_svd_attitude"]


@dataclass(frozen=True)
class SvdEstimator(Estimator):
    """SVD (Kabsch / Markley 1988) estimator (configure, then call with the observations).

    Calling it with ``(body_vectors (N, 3), reference_vectors (N, 3), sigma_rad)`` returns an
    :class:`~starsense.attitude.solution.AttitudeSolution`; weights are ``sigma^-2``
    (normalised to sum 1 for conditioning) and the covariance is the inverse Fisher matrix
    (Fialho & Mortari 2019, eq. 21).
    """

    method = "svd"

    def _solve(self, body, reference, sigma):
        # The Fisher check first: it raises SingularGeometryError for degenerate geometry,
        # where align_vectors would only warn.
        cov = fisher_covariance(body, sigma)
        w = sigma**-2.0
        rotation, _ = Rotation.align_vectors(body, reference, weights=w / w.sum())
        return rotation, cov, (), self.method


def batch_svd_attitude(body: ArrayLike, reference: ArrayLike) -> Rotation:
    """Solve many equal-weight Wahba problems at once by SVD (Kabsch / Markley 1988).

    The batched form of :class:`SvdEstimator` for equal sigmas:
    ``B = sum_i b_i r_i^T = U S V^T``, ``A = U diag(1, 1, det U det V) V^T``.

    Parameters
    ----------
    body : array_like, shape (M, N, 3)
        Measured camera-frame unit vectors of each problem.
    reference : array_like, shape (M, N, 3)
        The same stars' ICRS unit vectors.

    Returns
    -------
    Rotation
        Batch of M attitudes (ICRS -> camera).
    """
    b = np.asarray(body, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    mat = np.einsum("mni,mnj->mij", b, r)
    u, _, vt = np.linalg.svd(mat)
    d = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    u[:, :, 2] *= d[:, None]
    return Rotation.from_matrix(u @ vt)
