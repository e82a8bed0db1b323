"""Attitude covariance of guide-star sets, its probability, and the Monte Carlo solves.

Lin et al. 2024, eqs. 1-5: F = sum_i sigma^-2 (I - r_i r_i^T), P = F^-1; the accuracy of a
trial is the norm of the camera-frame error rotation vector (``metric="total"``) or of its
cross-boresight part (``metric="pointing"``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special
from scipy.spatial.transform import Rotation

from starsense._validate import as_generator, positive_float
from starsense.analysis.guide_stars._common import check_metric
from starsense.attitude import estimate_attitude
from starsense.attitude.covariance import fisher_matrix
from starsense.attitude.svd import batch_svd_attitude
from starsense.geometry.sampling import fibonacci_sphere, random_attitudes

__all__ = [
    "batch_covariance",
    "error_norm",
    "metric_block",
    "monte_carlo_errors",
    "probability_within",
    "tangent_noise",
]

_N_SPHERE = 4000
"""Directions for the exact average over the sphere (3 dof); 2000 used, one per antipodal pair."""
_N_CIRCLE = 256
"""Directions for the exact average over the circle (2 dof)."""


def batch_covariance(vectors: ArrayLike, sigma_rad: float) -> NDArray[np.float64]:
    """Return the attitude covariance P = F^-1 of many star sets at once (eqs. 1-3).

    Lin et al. 2024, eqs. 1-3: F = sum_i sigma^-2 (I - r_i r_i^T), the batched form of
    :func:`starsense.attitude.covariance.fisher_matrix` (Fialho & Mortari 2019, eq. 21).

    Parameters
    ----------
    vectors : array_like, shape (M, N, 3)
        Camera-frame unit vectors of the guide stars.
    sigma_rad : float
        Per-axis measurement error of every star, rad, > 0.

    Returns
    -------
    ndarray, shape (M, 3, 3)
        Covariances, rad^2.
    """
    s = positive_float(sigma_rad, "sigma_rad")
    r = np.asarray(vectors, dtype=np.float64)
    f = fisher_matrix(r, np.full(r.shape[:-1], s**-2.0))
    return np.linalg.inv(f)


def metric_block(cov: NDArray[np.float64], metric: str) -> NDArray[np.float64]:
    """Return the block of covariances (..., 3, 3) that a metric sees (x-y for "pointing")."""
    return cov[..., :2, :2] if metric == "pointing" else cov


def chi_cdf(x: ArrayLike, dof: int) -> NDArray[np.float64]:
    """Return the CDF of the chi distribution with ``dof`` degrees of freedom (2: Rayleigh).

    ``P(dof / 2, x^2 / 2)``, the regularised lower incomplete gamma function of
    :func:`scipy.special.gammainc`, and for 2 dof its closed form ``-expm1(-x^2 / 2)``: the
    values ``scipy.stats.chi(dof).cdf`` and ``scipy.stats.rayleigh.cdf`` return (tested), without
    their per-call argument handling, which tripled the cost of Table 1's analytic column.

    Parameters
    ----------
    x : array_like
        Argument, >= 0.
    dof : int
        Degrees of freedom.

    Returns
    -------
    ndarray
        Same shape as ``x``.
    """
    half_x2 = 0.5 * np.square(np.asarray(x, dtype=np.float64))
    if dof == 2:
        return -np.expm1(-half_x2)
    return special.gammainc(0.5 * dof, half_x2)


def probability_within(
    cov_rad2: ArrayLike, threshold_rad: float, metric: str = "pointing"
) -> NDArray[np.float64]:
    """Return P(|delta phi| < t) for a zero-mean Gaussian attitude error of covariance P.

    With ``delta phi = L z`` (``L L^T = P``, z standard normal) and ``z = rho u`` (u uniform on
    the unit sphere, rho chi-distributed), ``P(|delta phi| < t) = E_u[F_chi(t / |L u|)]``; the
    average over u uses a Fibonacci lattice of 4000 directions (3 dof, ``metric="total"``,
    the chi distribution with 3 dof) or 256 equally spaced angles on the circle (2 dof,
    ``metric="pointing"``, the x-y block of P, the Rayleigh distribution).

    Parameters
    ----------
    cov_rad2 : array_like, shape (..., 3, 3)
        Covariances, rad^2.
    threshold_rad : float
        t, rad, > 0.
    metric : {"total", "pointing"}
        Which norm of the error.

    Returns
    -------
    ndarray, shape (...)
        Probabilities, 0-1.
    """
    check_metric(metric)
    t = positive_float(threshold_rad, "threshold_rad")
    p = np.asarray(cov_rad2, dtype=np.float64)
    if metric == "pointing":
        p = p[..., :2, :2]
        ang = (np.arange(_N_CIRCLE) + 0.5) * (math.pi / _N_CIRCLE)  # u and -u are the same
        u2 = np.stack([np.cos(ang) ** 2, np.sin(ang) ** 2], axis=-1)
    else:
        u = fibonacci_sphere(_N_SPHERE)
        u2 = u[u[:, 2] > 0] ** 2  # u and -u are the same
    # in P's eigenbasis |L u|^2 = sum_k lambda_k u_k^2
    lam = np.linalg.eigvalsh(p)
    q = lam @ u2.T
    a = t / np.sqrt(q)
    cdf = chi_cdf(a, 2 if metric == "pointing" else 3)
    return cdf.mean(axis=-1)


def error_norm(rotvec: ArrayLike, metric: str = "pointing") -> NDArray[np.float64]:
    """Return the accuracy of trials from their camera-frame error rotation vectors.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Error rotation vectors, rad.
    metric : {"total", "pointing"}
        Norm of the whole vector, or of its x-y part.

    Returns
    -------
    ndarray, shape (...)
        Errors, rad.
    """
    check_metric(metric)
    e = np.asarray(rotvec, dtype=np.float64)
    return np.linalg.norm(e[..., :2] if metric == "pointing" else e, axis=-1)


def tangent_noise(
    vectors: NDArray[np.float64], z: NDArray[np.float64], sigma_rad: float
) -> NDArray[np.float64]:
    """Displace unit vectors by ``sigma * (z1 e1 + z2 e2)`` in their tangent planes.

    Parameters
    ----------
    vectors : ndarray, shape (..., 3)
        Unit vectors near +z (never along +x).
    z : ndarray, shape (..., 2)
        Standard-normal deviates.
    sigma_rad : float
        Per-axis standard deviation, rad.

    Returns
    -------
    ndarray, shape (..., 3)
        The displaced unit vectors.
    """
    helper = np.zeros_like(vectors)
    helper[..., 0] = 1.0  # guide stars are near +z, never along +x
    e1 = np.cross(vectors, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(vectors, e1)
    out = vectors + sigma_rad * (z[..., 0:1] * e1 + z[..., 1:2] * e2)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def monte_carlo_errors(
    vectors: ArrayLike,
    sigma_rad: float,
    *,
    rng: np.random.Generator | int | None = None,
    batched: bool = True,
    noise: ArrayLike | None = None,
    attitudes: Rotation | None = None,
) -> NDArray[np.float64]:
    """Return the attitude error of one noisy solve per star set.

    Each trial draws a true attitude A (uniform on SO(3)), takes the catalogue directions
    ``r_i = A^-1 b_i``, displaces the true camera-frame directions ``b_i`` by the measurement
    noise, solves for the attitude and returns ``small_rotation_angles(A, A_est)``.

    Parameters
    ----------
    vectors : array_like, shape (M, N, 3)
        True camera-frame unit vectors of the guide stars.
    sigma_rad : float
        Per-axis measurement error, rad, > 0.
    rng : Generator, int or None
        Random generator or seed (for what ``noise`` and ``attitudes`` do not give).
    batched : bool
        True: :func:`starsense.attitude.svd.batch_svd_attitude` (vectorised); False: one
        :func:`starsense.attitude.estimate_attitude` call per trial (slow, the reference).
    noise : array_like, shape (M, N, 2), optional
        Standard-normal tangent-plane deviates (common random numbers across sigmas).
    attitudes : Rotation of length M, optional
        True attitudes.

    Returns
    -------
    ndarray, shape (M, 3)
        Camera-frame error rotation vectors, rad.
    """
    s = positive_float(sigma_rad, "sigma_rad")
    b_true = np.asarray(vectors, dtype=np.float64)
    m, n = b_true.shape[:2]
    gen, _ = as_generator(rng)
    z = gen.standard_normal((m, n, 2)) if noise is None else np.asarray(noise, dtype=float)
    a_true = random_attitudes(m, gen) if attitudes is None else attitudes
    mats = a_true.as_matrix()  # rows: camera axes in ICRS; r = M^T b
    ref = np.einsum("mji,mnj->mni", mats, b_true)
    body = tangent_noise(b_true, z, s)
    if batched:
        a_est = batch_svd_attitude(body, ref)
    else:
        a_est = Rotation.concatenate(
            [estimate_attitude(body[k], ref[k], s, method="svd").rotation for k in range(m)]
        )
    return (a_est * a_true.inv()).as_rotvec()
