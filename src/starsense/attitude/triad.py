"""TRIAD (Black 1964; Shuster & Oh 1981): the attitude from two vector pairs.

With the anchor pair ``(b1, r1)`` (the most accurate star) and a second pair ``(b2, r2)``::

    t1 = v1,   t2 = (v1 x v2) / |v1 x v2|,   t3 = t1 x t2          (for v = b and v = r)

    A = [t1_b t2_b t3_b] [t1_r t2_r t3_r]^T

``A`` maps ``r1`` exactly onto ``b1``; the second pair only fixes the rotation about ``b1``.
TRIAD ignores every other star and is not optimal, so its covariance
(:func:`~starsense.attitude.covariance.triad_covariance`) exceeds the Fisher bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import check_scalar
from starsense.attitude.covariance import fisher_covariance, triad_covariance
from starsense.attitude.solution import Estimator, cross3
from starsense.errors import SingularGeometryError

__all__ = ["TriadEstimator", "triad"]


def _triad_frame(v1: NDArray[np.float64], v2: NDArray[np.float64]) -> NDArray[np.float64]:
    t2 = cross3(v1, v2)
    t2 /= np.linalg.norm(t2)
    return np.column_stack([v1, t2, cross3(v1, t2)])


def triad(body: ArrayLike, reference: ArrayLike) -> Rotation:
    """Compute the TRIAD attitude from two non-parallel unit vector pairs, the first the anchor.

    Parameters
    ----------
    body : array_like, shape (2, 3)
        Camera-frame unit vectors ``b1`` (the anchor) and ``b2``.
    reference : array_like, shape (2, 3)
        The matching ICRS unit vectors ``r1`` and ``r2``.

    Returns
    -------
    Rotation
        ICRS -> camera.
    """
    b1, b2 = np.asarray(body, dtype=np.float64)
    r1, r2 = np.asarray(reference, dtype=np.float64)
    matrix = _triad_frame(b1, b2) @ _triad_frame(r1, r2).T
    # Orthonormal to rounding by construction (product of two orthonormal frames).
    return Rotation.from_matrix(matrix, assume_valid=True)


@dataclass(frozen=True)
class TriadEstimator(Estimator):
    """TRIAD on the two most accurate stars (configure, then call with the observations).

    The anchor is the star with the smallest sigma; the second is the next most accurate star
    (ties: the first in input order) whose direction is separated from the anchor's, in both
    frames, by more than ``parallel_tolerance_rad`` (and by less than pi minus it).

    Parameters
    ----------
    parallel_tolerance_rad : float
        Pairs closer than this to parallel or antiparallel are skipped, rad (default 1e-8).
    """

    parallel_tolerance_rad: float = 1e-8
    method = "triad"

    def __post_init__(self) -> None:
        check_scalar(
            self.parallel_tolerance_rad,
            "parallel_tolerance_rad",
            0.0,
            0.5 * math.pi,
            lo_open=True,
            hi_open=True,
        )

    def _solve(self, body, reference, sigma):
        # Singular geometry of the whole set is reported first, as for the other methods.
        fisher_covariance(body, sigma)
        order = np.argsort(sigma, kind="stable")
        i = int(order[0])
        min_sin = math.sin(self.parallel_tolerance_rad)
        sin_b = np.linalg.norm(cross3(body[i], body[order[1:]]), axis=1)
        sin_r = np.linalg.norm(cross3(reference[i], reference[order[1:]]), axis=1)
        ok = np.flatnonzero((sin_b > min_sin) & (sin_r > min_sin))
        if ok.size == 0:
            raise SingularGeometryError(
                f"TRIAD needs a second star not parallel to the anchor (star {i}); every other "
                f"star is within {self.parallel_tolerance_rad:g} rad of it or of its antipode"
            )
        j = int(order[1:][ok[0]])
        rotation = triad(body[[i, j]], reference[[i, j]])
        cov = triad_covariance(
            body[i], body[j], sigma1_rad=float(sigma[i]), sigma2_rad=float(sigma[j])
        )
        note = f"TRIAD used stars {i} (anchor) and {j} of {body.shape[0]}"
        return rotation, cov, (note,), self.method
