"""Pick an attitude estimator by name: :func:`estimate_attitude` and its table."""

from __future__ import annotations

from numpy.typing import ArrayLike

from starsense.attitude.davenport import DavenportEstimator
from starsense.attitude.quest import QuestEstimator
from starsense.attitude.solution import AttitudeSolution
from starsense.attitude.svd import SvdEstimator
from starsense.attitude.triad import TriadEstimator
from starsense.errors import InputError

__all__ = ["ESTIMATORS", "estimate_attitude"]

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
    *,
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
