"""QUEST (Shuster & Oh 1981): the q-method's eigenproblem through its characteristic equation.

Shuster's method of sequential rotations is used, with a checked fallback to the q-method.

With normalised weights and ``B, S, sigma, z, K`` as in :mod:`starsense.attitude.davenport`,
``kappa = tr adj S`` and ``Delta = det S``, the characteristic equation of K is
(Shuster & Oh 1981, eqs. 70-72)::

    psi(l) = l^4 - (a + b) l^2 - c l + (a b + c sigma - d) = 0
    a = sigma^2 - kappa,   b = sigma^2 + z.z,   c = Delta + z^T S z,   d = z^T S^2 z

Its largest root ``lambda_max`` is found by Newton-Raphson from ``lambda_0 = sum a_i = 1``; the
roots lie in [-1, 1] and psi is convex above the largest, so the iteration descends
monotonically onto ``lambda_max``. The optimal quaternion is then the last column of
``adj(lambda I - K)`` (Shuster & Oh's Gibbs-vector solution written without the division)::

    alpha = l^2 - sigma^2 + kappa,   beta = l - sigma,   gamma = (l + sigma) alpha - Delta
    x = (alpha I + beta S + S^2) z,   q = (x, gamma) / |(x, gamma)|          (scalar last)

Since ``adj(lambda_max I - K) = psi'(lambda_max) q q^T``, ``gamma = psi'(lambda_max) q4^2``:
the column vanishes as the rotation angle approaches 180 deg (q4 -> 0, the Gibbs vector
singularity). When ``q4^2 = gamma / psi'`` is below ``sequential_q4**2`` the reference frame
is rotated by 180 deg about the reference x, y or z axis, whichever makes gamma largest
(Shuster & Oh's method of sequential rotations), and the rotation is undone afterwards.

Failure detection
-----------------
When the two largest eigenvalues of K are close (few stars, heavy noise, stars nearly
parallel, or inconsistent matches), psi has a nearly double root: Newton converges only
linearly, the root computed from the rounded polynomial coefficients is off by about
``eps / psi'``, and the adjoint column then mixes in the second eigenvector with an error of
about ``eps / gap^2`` instead of the q-method's ``eps / gap``. Each QUEST solution is therefore
checked a posteriori, without an eigendecomposition:

* Newton must converge within ``max_iterations`` and give a finite root;
* the Rayleigh quotient ``rho = q^T K q`` must be within ``psi'/8`` of the root;
* the eigenvector error bound ``sin phi <= |K q - rho q| / gap`` (Davis-Kahan), with
  ``gap >= psi'(lambda) / 4`` because the other three eigenvalues lie within 2 of lambda_max,
  gives an attitude error bound ``2 phi`` that must not exceed ``max_error_bound_rad``.

A solution failing any check is replaced by the q-method's (``np.linalg.eigh``), and a note says
why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import check_int, check_scalar
from starsense.attitude.covariance import fisher_covariance
from starsense.attitude.davenport import attitude_profile_matrix, davenport_k_matrix, q_method
from starsense.attitude.solution import Estimator
from starsense.errors import InputError

__all__ = ["QuestEstimator", "QuestKernelResult", "quest_kernel"]

_AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class QuestKernelResult:
    """Raw QUEST output and its self-checks (before any fallback).

    Attributes
    ----------
    rotation : Rotation
        QUEST's attitude, ICRS -> camera.
    lambda_max : float
        Root of the characteristic equation found by Newton-Raphson.
    iterations : int
        Newton iterations taken.
    converged : bool
        Whether the Newton step fell below the tolerance within the iteration limit.
    dpsi : float
        psi'(lambda_max) = product of the distances from lambda_max to the other eigenvalues.
    sequential_axis : int or None
        Reference axis (0, 1, 2) of the 180 deg sequential rotation, or None.
    rayleigh_offset : float
        ``q^T K q - lambda_max``.
    error_bound_rad : float
        A posteriori bound on the attitude error from inexact eigenvector computation, rad
        (inf when psi' <= 0).
    """

    rotation: Rotation
    lambda_max: float
    iterations: int
    converged: bool
    dpsi: float
    sequential_axis: int | None
    rayleigh_offset: float
    error_bound_rad: float


def _adjoint_column(b_matrix: NDArray[np.float64], lam: float) -> NDArray[np.float64]:
    """(x, gamma): the last column of adj(lam I - K), scalar last."""
    s = b_matrix + b_matrix.T
    sigma = np.trace(b_matrix)
    z = np.array(
        [
            b_matrix[2, 1] - b_matrix[1, 2],
            b_matrix[0, 2] - b_matrix[2, 0],
            b_matrix[1, 0] - b_matrix[0, 1],
        ]
    )
    kappa = 0.5 * (np.trace(s) ** 2 - np.trace(s @ s))
    delta = np.linalg.det(s)
    alpha = lam * lam - sigma * sigma + kappa
    beta = lam - sigma
    gamma = (lam + sigma) * alpha - delta
    sz = s @ z
    x = alpha * z + beta * sz + s @ sz
    return np.append(x, gamma)


def quest_kernel(
    b_matrix: NDArray[np.float64],
    *,
    max_iterations: int = 20,
    tolerance: float = 1e-14,
    sequential_q4: float = 0.1,
) -> QuestKernelResult:
    """QUEST on an attitude profile matrix with normalised weights (no fallback).

    Parameters
    ----------
    b_matrix : ndarray, shape (3, 3)
        ``B = sum_i a_i b_i r_i^T`` with ``sum a_i = 1``.
    max_iterations : int
        Newton-Raphson iteration limit.
    tolerance : float
        Convergence when the Newton step is at most this (lambda is O(1)).
    sequential_q4 : float
        Use a sequential rotation when the estimated ``|q4|`` is below this; 0 disables
        sequential rotations (for demonstrating the singularity only).

    Returns
    -------
    QuestKernelResult
    """
    s = b_matrix + b_matrix.T
    sigma = float(np.trace(b_matrix))
    z = np.array(
        [
            b_matrix[2, 1] - b_matrix[1, 2],
            b_matrix[0, 2] - b_matrix[2, 0],
            b_matrix[1, 0] - b_matrix[0, 1],
        ]
    )
    kappa = 0.5 * (np.trace(s) ** 2 - np.trace(s @ s))
    delta = float(np.linalg.det(s))
    sz = s @ z
    a = sigma**2 - kappa
    b = sigma**2 + z @ z
    c = delta + z @ sz
    d = sz @ sz
    c0 = a * b + c * sigma - d

    lam = 1.0
    converged = False
    iterations = 0
    dpsi = 4.0 * lam**3 - 2.0 * (a + b) * lam - c
    for iterations in range(1, max_iterations + 1):  # noqa: B007 - reported below
        lam2 = lam * lam
        psi = lam2 * lam2 - (a + b) * lam2 - c * lam + c0
        dpsi = 4.0 * lam2 * lam - 2.0 * (a + b) * lam - c
        step = psi / dpsi if dpsi != 0.0 else math.inf
        if not math.isfinite(step):
            break
        if step <= 0.0:
            # Newton descends monotonically onto the root from above; a non-positive step
            # means the rounding floor is reached.
            converged = True
            break
        lam -= step
        if step <= tolerance:
            converged = True
            dpsi = 4.0 * lam**3 - 2.0 * (a + b) * lam - c
            break

    column = _adjoint_column(b_matrix, lam)
    axis = None
    if sequential_q4 > 0.0 and not (dpsi > 0.0 and column[3] >= sequential_q4**2 * dpsi):
        # Near 180 deg (or ill-conditioned): rotate the reference frame by pi about the axis
        # that makes gamma = psi' q4'^2 largest. B' = B R_k with R_k = diag(+-1).
        best = column[3]
        for k in range(3):
            flip = -np.ones(3)
            flip[k] = 1.0
            col_k = _adjoint_column(b_matrix * flip[None, :], lam)
            if col_k[3] > best:
                best, column, axis = col_k[3], col_k, k
    norm = np.linalg.norm(column)
    if not (np.isfinite(norm) and norm > 0.0):
        column = np.array([0.0, 0.0, 0.0, 1.0])
        norm = 1.0
        converged = False
    rotation = Rotation.from_quat(column / norm)
    if axis is not None:
        rotation = rotation * Rotation.from_rotvec(np.pi * np.eye(3)[axis])

    k_matrix = davenport_k_matrix(b_matrix)
    q = rotation.as_quat()
    kq = k_matrix @ q
    rho = float(q @ kq)
    residual = float(np.linalg.norm(kq - rho * q))
    if dpsi > 0.0 and math.isfinite(dpsi):
        bound = 2.0 * math.asin(min(1.0, 4.0 * residual / dpsi))
    else:
        bound = math.inf
    return QuestKernelResult(
        rotation=rotation,
        lambda_max=float(lam),
        iterations=iterations,
        converged=converged,
        dpsi=float(dpsi),
        sequential_axis=axis,
        rayleigh_offset=rho - float(lam),
        error_bound_rad=bound,
    )


@dataclass(frozen=True, kw_only=True)
class QuestEstimator(Estimator):
    """QUEST estimator with sequential rotations and a checked q-method fallback.

    Parameters
    ----------
    max_iterations : int
        Newton-Raphson iteration limit (default 20; well-separated roots need about 3-5).
    tolerance : float
        Newton convergence tolerance on lambda (normalised weights), default 1e-14.
    sequential_q4 : float
        Sequential rotation when the estimated ``|q4|`` is below this (default 0.1, i.e. a
        rotation angle above about 168.5 deg), in (0, 1).
    max_error_bound_rad : float
        Fall back to the q-method when the a posteriori bound on QUEST's numerical attitude
        error exceeds this, rad (default 1e-10).

    Notes
    -----
    Calling it with ``(body_vectors (N, 3), reference_vectors (N, 3), sigma_rad)`` returns an
    :class:`~starsense.attitude.solution.AttitudeSolution`. Weights are ``sigma^-2`` normalised
    to sum 1; the covariance is the inverse Fisher matrix (Fialho & Mortari 2019, eq. 21).
    ``method`` is "quest", or "davenport" after a fallback (with a note saying why).
    """

    max_iterations: int = 20
    tolerance: float = 1e-14
    sequential_q4: float = 0.1
    max_error_bound_rad: float = 1e-10
    method = "quest"

    def __post_init__(self) -> None:
        if not isinstance(self.max_iterations, int):
            raise InputError(f"max_iterations = {self.max_iterations!r}; must be an integer >= 1")
        check_int(self.max_iterations, "max_iterations", 1)
        check_scalar(self.tolerance, "tolerance", 0.0, None, lo_open=True)
        check_scalar(self.sequential_q4, "sequential_q4", 0.0, 1.0, lo_open=True, hi_open=True)
        check_scalar(
            self.max_error_bound_rad, "max_error_bound_rad", 0.0, None, lo_open=True, allow_inf=True
        )

    def _solve(self, body, reference, sigma):
        cov = fisher_covariance(body, sigma)
        weights = sigma**-2.0
        result = quest_kernel(
            attitude_profile_matrix(body, reference, weights),
            max_iterations=self.max_iterations,
            tolerance=self.tolerance,
            sequential_q4=self.sequential_q4,
        )
        notes: list[str] = []
        if result.sequential_axis is not None:
            notes.append(
                "QUEST: rotation angle near 180 deg; sequential rotation by 180 deg about "
                f"reference {_AXIS_NAMES[result.sequential_axis]} axis used"
            )
        reason = None
        if not result.converged:
            reason = (
                f"Newton-Raphson did not converge in {result.iterations} iterations "
                f"(psi' = {result.dpsi:.3g}: the two largest eigenvalues of K are close)"
            )
        elif not abs(result.rayleigh_offset) <= result.dpsi / 8.0:
            reason = (
                f"QUEST quaternion's Rayleigh quotient is {result.rayleigh_offset:.3g} from the "
                f"root (psi' = {result.dpsi:.3g})"
            )
        elif not result.error_bound_rad <= self.max_error_bound_rad:
            reason = (
                f"QUEST error bound {result.error_bound_rad:.3g} rad exceeds "
                f"{self.max_error_bound_rad:.3g} rad (psi' = {result.dpsi:.3g}: the two largest "
                "eigenvalues of K are close)"
            )
        if reason is None:
            return result.rotation, cov, tuple(notes), self.method
        rotation, _ = q_method(body, reference, weights)
        notes.append(f"QUEST rejected: {reason}; q-method (Davenport) used")
        return rotation, cov, tuple(notes), "davenport"
