"""Attitude estimation from matched star directions: Wahba's problem with per-star weights.

Four estimators share one interface (configure, then call)::

    solution = QuestEstimator()(body_vectors, reference_vectors, sigma_rad)

* :class:`TriadEstimator` - TRIAD on the two most accurate stars (Black 1964);
* :class:`QuestEstimator` - QUEST (Shuster & Oh 1981) with sequential rotations and a checked
  fallback to the q-method;
* :class:`DavenportEstimator` - Davenport's q-method (eigenvector of the 4x4 K matrix);
* :class:`SvdEstimator` - the SVD solution, via scipy's ``Rotation.align_vectors``.

Each returns an :class:`AttitudeSolution` holding the attitude (ICRS -> camera, the
convention of :mod:`starsense.geometry.attitude`), its camera-frame covariance (the inverse
Fisher matrix of Fialho & Mortari 2019, eq. 21, for the optimal methods), the residuals and the
Wahba loss. :func:`estimate_attitude` picks an estimator by name.
"""

from __future__ import annotations

from numpy.typing import ArrayLike

from starsense.attitude.covariance import fisher_covariance, triad_covariance
from starsense.attitude.davenport import DavenportEstimator, davenport_k_matrix, q_method
from starsense.attitude.quest import QuestEstimator, quest_kernel
from starsense.attitude.solution import AttitudeSolution, validate_observations
from starsense.attitude.svd import SvdEstimator
from starsense.attitude.triad import TriadEstimator, triad
from starsense.errors import InputError

__all__ = [
    "ESTIMATORS",
    "AttitudeSolution",
    "DavenportEstimator",
    "QuestEstimator",
    "SvdEstimator",
    "TriadEstimator",
    "davenport_k_matrix",
    "estimate_attitude",
    "fisher_covariance",
    "q_method",
    "quest_kernel",
    "triad",
    "triad_covariance",
    "validate_observations",
]

#: Estimator classes by method name.
ESTIMATORS = {
    "svd": SvdEstimator,
    "quest": QuestEstimator,
    "davenport": DavenportEstimator,
    "triad": TriadEstimator,
}


def estimate_attitude(
    body_vectors: ArrayLike,
    reference_vectors: ArrayLike,
    sigma_rad: ArrayLike,
    method: str = "svd",
) -> AttitudeSolution:
    """Estimate the attitude with a named method and its default configuration.

    Parameters
    ----------
    body_vectors : array_like, shape (N, 3)
        Measured star directions in the camera frame.
    reference_vectors : array_like, shape (N, 3)
        The same stars' catalogue directions, ICRS.
    sigma_rad : float or array_like, shape (N,)
        Per-axis angular noise of each measured direction, rad; weights are sigma^-2.
    method : {"svd", "quest", "davenport", "triad"}
        The estimator.

    Returns
    -------
    AttitudeSolution

    Raises
    ------
    InputError
        Unknown method, or bad observations.
    SingularGeometryError
        The stars do not determine the attitude.
    """
    try:
        estimator = ESTIMATORS[method]()
    except (KeyError, TypeError):
        raise InputError(
            f"method = {method!r} is not known; choose one of {', '.join(ESTIMATORS)}"
        ) from None
    return estimator(body_vectors, reference_vectors, sigma_rad)
