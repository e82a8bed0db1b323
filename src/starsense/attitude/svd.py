"""The SVD solution of Wahba's problem (Markley 1988), through scipy's ``Rotation.align_vectors``.

``align_vectors(b, r, weights)`` returns the rotation ``C`` minimising
``1/2 sum_i w_i |b_i - C r_i|^2`` (Kabsch algorithm: SVD of ``B = sum_i w_i b_i r_i^T``,
``C = U diag(1, 1, det U det V) V^T``), which is the ICRS -> camera attitude.

:class:`SvdEstimator` solves one problem with per-star weights; :func:`batch_svd_attitude` solves
many equal-weight problems at once (the Monte Carlo form); :func:`wahba_matrix` is the bare
matrix and residuals that identification and tracking fit (the compiled kernel of
:mod:`starsense.identify.track_kernels` computes the same).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from starsense.attitude.covariance import fisher_covariance
from starsense.attitude.solution import Estimator

__all__ = ["SvdEstimator", "batch_svd_attitude", "wahba_matrix"]


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


def _det3(m: np.ndarray) -> float:
    """Return the determinant of a 3 x 3 matrix (cofactors: here +-1, an orthogonal matrix)."""
    (a, b, c), (d, e, f), (g, h, i) = m.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def wahba_matrix(body, ref, weights=None, *, two_exact: bool = False):
    """Attitude matrix of paired vectors (``body ~ C ref``), residual angles and chords^2.

    Weighted SVD (Kabsch / Markley 1988: ``B = sum_i w_i b_i r_i^T = U S V^T``,
    ``C = U diag(1, 1, det U V^T) V^T``, weights normalised to sum 1), or for two pairs with
    ``two_exact`` the rotation that aligns the first pair exactly and the second as closely as
    it can (``Rotation.align_vectors`` with an infinite primary weight).

    Parameters
    ----------
    body, ref : ndarray, shape (N, 3)
        Camera-frame and ICRS unit vectors, N >= 2.
    weights : ndarray, shape (N,), optional
        Positive weights (any scale; default equal).
    two_exact : bool
        Align the first of two pairs exactly.

    Returns
    -------
    c : ndarray, shape (3, 3)
    residuals : ndarray, shape (N,)
        Angle between each body vector and its rotated reference (from the chord), rad.
    chord2 : ndarray, shape (N,)
        Squared chords.
    """
    if two_exact and len(body) == 2:
        rot, _ = Rotation.align_vectors(body, ref, weights=[np.inf, 1.0])
        c = rot.as_matrix()
    else:
        w = np.ones(len(body)) if weights is None else np.asarray(weights, dtype=float)
        w = w / w.sum()
        u, _, vh = np.linalg.svd((w[:, None] * body).T @ ref)
        c = u @ vh
        if _det3(c) < 0:  # an improper rotation (det -1): flip the last axis
            u[:, -1] = -u[:, -1]
            c = u @ vh
    d = body - ref @ c.T
    chord2 = np.einsum("ij,ij->i", d, d)
    # the angle from the chord, 2 asin(|b - C r| / 2): as accurate as atan2(|b x Cr|, b . Cr)
    resid = 2.0 * np.arcsin(np.minimum(np.sqrt(chord2) / 2.0, 1.0))
    return c, resid, chord2
