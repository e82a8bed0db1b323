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

from starsense.attitude.covariance import fisher_covariance, triad_covariance
from starsense.attitude.davenport import DavenportEstimator, davenport_k_matrix, q_method
from starsense.attitude.estimate import ESTIMATORS, estimate_attitude
from starsense.attitude.quest import QuestEstimator, quest_kernel
from starsense.attitude.solution import AttitudeSolution, validate_observations
from starsense.attitude.svd import SvdEstimator
from starsense.attitude.triad import TriadEstimator, triad

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
