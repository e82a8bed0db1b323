"""The solver's Wahba fit of matched stars, in the compiled kernel where it is built.

:func:`kernel_fit` is :func:`starsense.attitude.estimate_attitude` with ``method="svd"`` (the
weighted SVD solution and its inverse-Fisher covariance, Fialho & Mortari 2019 eq. 21) in the
compiled kernel of :mod:`starsense.identify.track_kernels`: the attitude agrees to rounding
(~1e-15 rad), the residual angles (from the chord) to ~1e-15 rad. The solver hands it to
:func:`starsense.attitude.robust.robust_attitude` (``fit=``), whose few fits per frame were a
third of the time of a centroid solve in NumPy and scipy (per-call overhead on ~20 stars).
"""

from __future__ import annotations

import math

import numpy as np

from starsense.attitude.covariance import SINGULAR_RCOND, fisher_covariance
from starsense.attitude.estimate import estimate_attitude
from starsense.attitude.solution import AttitudeSolution
from starsense.identify.track_kernels import weighted_fit_compiled

__all__ = ["kernel_fit"]


def kernel_fit(body: np.ndarray, reference: np.ndarray, sigma: np.ndarray) -> AttitudeSolution:
    """Return the weighted SVD attitude of matched stars (``body ~ A reference``).

    Parameters
    ----------
    body, reference : ndarray, shape (N, 3)
        Camera-frame and ICRS unit vectors of the matched stars, N >= 2 (the solver's
        unprojections and catalogue places are unit to rounding; the estimator's check, which
        renormalises them, is not repeated).
    sigma : ndarray, shape (N,)
        Each star's 1-sigma direction noise per axis, rad, > 0 (weights sigma^-2).

    Returns
    -------
    AttitudeSolution
        Method "svd"; its ``rotation`` given as the fit's matrix (the Rotation is built when
        first read).

    Raises
    ------
    SingularGeometryError
        The stars do not determine the attitude (as the estimator raises it).
    """
    fitted = weighted_fit_compiled(body, reference, sigma, rcond=SINGULAR_RCOND)
    if fitted is None:  # no kernel: the estimator itself
        return estimate_attitude(body, reference, sigma, method="svd")
    c, resid, _chord2, cov, loss = fitted
    if cov is False:  # singular or not finite: the estimator's check raises its error
        cov = fisher_covariance(body, sigma)
    return AttitudeSolution.of_fit(
        c,
        covariance_rad2=cov,
        residual_rms_rad=math.sqrt(float(resid @ resid) / len(resid)),
        residuals_rad=resid,
        method="svd",
        n_stars=len(body),
        loss=loss,
    )
