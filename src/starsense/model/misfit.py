"""Whether a forward-model fit's misfit pulls the attitude: the sandwich against the Fisher bound.

The fit (:mod:`starsense.model.fit`) reports the Fisher covariance of its geometric parameters
and the sandwich ``S^-1 M S^-1`` of its groups' scores; where the model is right the two agree
within the sandwich's own noise. These functions say by how much they disagree, and whether
the disagreement is one that moves the stars (:func:`misfit_pulls`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PULL_SIGMAS", "covariance_pulls", "misfit_pulls", "sandwich", "sandwich_exceeds"]

#: the attitude's sandwich variance beyond the pixels' own excess scatter (the reduced
#: chi-square times the Fisher bound's) by this many of the sandwich's relative noise: the
#: model's misfit is not noise about the stars but pulls them (:func:`misfit_pulls`)
PULL_SIGMAS = 3.0


def sandwich(s, scores, s_groups):
    """Return the Fisher covariance, the sandwich's, and the sandwich's relative noise per axis.

    The sandwich's variance per axis sums each group's share, ``v_g = (cov S_g cov)_kk``, of a
    score drawn from the model: its relative noise is ``sqrt(2 sum v_g^2) / sum v_g``.
    """
    cov = np.linalg.inv(s)
    v = np.einsum("kp,gpq,qk->gk", cov, s_groups, cov)
    noise = np.sqrt(2.0 * (v * v).sum(axis=0)) / np.abs(v.sum(axis=0))
    return cov, cov @ (scores.T @ scores) @ cov, noise


def sandwich_exceeds(cov, robust, noise, *, scale: float, sigmas: float) -> bool | None:
    """Whether an attitude axis's sandwich variance is beyond ``scale`` times the Fisher's.

    Beyond by more than ``sigmas`` of the sandwich's relative noise ``noise``; None without a
    sandwich.
    """
    if robust is None or noise is None or not np.all(np.isfinite(robust)):
        return None
    ratio = np.diag(robust)[:3] / np.diag(cov)[:3]
    return bool(np.any(ratio > scale * (1.0 + sigmas * np.asarray(noise)[:3])))


def covariance_pulls(cov, robust, noise, *, reduced_chi2: float) -> bool:
    """:func:`misfit_pulls` of a covariance, its sandwich and the sandwich's relative noise."""
    beyond = sandwich_exceeds(cov, robust, noise, scale=reduced_chi2, sigmas=PULL_SIGMAS)
    return True if beyond is None else beyond


def misfit_pulls(fit) -> bool:
    """Whether a fit's misfit pulls the attitude rather than scattering about the stars.

    Pixels that scatter about the model by a reduced chi-square ``c`` as noise would (a
    camera's noise above the sensor's) raise the attitude's variance, estimated from the
    groups' scores (the sandwich), ``c`` times the Fisher bound's; a profile error symmetric
    about each star (an Airy or a Moffat drawn as a Gaussian of its width) raises it less,
    since it does not move the stars. A misfit the stars' positions follow (a PSF asymmetric
    across the field: coma, a tilted detector) raises it far more: real frames of a camera
    whose PSF the sensor does not describe read 6-66 times the Fisher sigma at a reduced
    chi-square of 14-42, where bright GalSim Airy stars read 1-3.7 at 4-10. Above ``c`` by
    :data:`PULL_SIGMAS` of the sandwich's own relative noise on an attitude axis, the model
    does not place the stars.
    """
    return covariance_pulls(
        fit.covariance, fit.robust_covariance, fit.robust_noise, reduced_chi2=fit.reduced_chi2
    )
