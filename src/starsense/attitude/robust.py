"""The final attitude of a solve, robust to a blended or double star."""

from __future__ import annotations

import numpy as np

from starsense.attitude.estimate import estimate_attitude

__all__ = ["OUTLIER_SIGMA", "robust_attitude"]


#: a matched star whose residual exceeds this many of its own 1-sigma (per axis, so ~ sqrt(2)
#: sigma expected in angle) is dropped from the final attitude: a blend or a close double star
OUTLIER_SIGMA = 7.0


def robust_attitude(body, reference, sigma_rad, *, max_drop: int = 5):
    """Estimate the attitude, dropping one by one the stars whose residual is an outlier.

    A blended or double star is identified right but centroided at the photocentre of the
    pair: its residual is many of its own sigma, and left in it pulls the attitude. While the
    worst residual exceeds ``OUTLIER_SIGMA`` sigma and more than three stars remain, that star
    is dropped and the attitude re-estimated (SVD, Wahba weights 1 / sigma^2).

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars.
    sigma_rad : float or ndarray (N,)
        Each star's 1-sigma direction noise, rad.
    max_drop : int
        Most stars dropped.

    Returns
    -------
    AttitudeSolution, and the mask of the stars kept (N,)
    """
    sigma = np.broadcast_to(np.asarray(sigma_rad, dtype=float), (len(body),))
    keep = np.ones(len(body), dtype=bool)
    att = estimate_attitude(body, reference, sigma, method="svd")
    for _ in range(max_drop):
        if keep.sum() <= 3:
            break
        z = np.full(len(body), -np.inf)
        z[keep] = att.residuals_rad / sigma[keep]
        worst = int(np.argmax(z))
        if z[worst] <= OUTLIER_SIGMA:
            break
        keep[worst] = False
        att = estimate_attitude(body[keep], reference[keep], sigma[keep], method="svd")
    return att, keep
