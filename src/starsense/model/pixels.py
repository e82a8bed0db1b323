"""A pixel's reading as the forward model's likelihood sees it: its variance, and its floor.

Each pixel is normal about the model's expected electrons ``mu`` with the detector's variance
(:func:`pixel_variance`). The ADC reads no less than zero counts: a camera whose bias sits
within a few read-noise sigmas of zero reads its dark pixels as 0 about half the time (a
rectified Gaussian). Such a reading says only that the pixel's value lay below the floor
``c = (0.5 - bias) / g`` electrons (g counts per electron): it is *censored* (Tobit 1958). Left
out, the pixels that stay are those the noise pushed up (a biased background, a reduced
chi-square near 0.5); read as a value, it biases the model down. Its likelihood is
``Phi(a)``, ``a = (c - mu) / sigma``, and a pixel read above the floor has the normal density.
Per pixel, with ``lambda(a) = phi(a) / Phi(a)`` (the inverse Mills ratio):

- the information on ``mu``: ``kappa(a) / sigma^2``, ``kappa = 1 - Phi(a) + a phi(a) +
  phi(a) lambda(a)``, which is 1 far above the floor and falls to 0 far below it;
- the score: ``(y - mu) / sigma^2`` above the floor, ``-lambda(a) / sigma`` at it;
- a chi-square term of expectation 1: ``(y - mu)^2 / sigma^2`` above the floor,
  ``1 - a lambda(a)`` (the mean of ``z^2`` below ``a``) at it.

Gauss-Newton with the information as the weight and the score over it as the residual (Fisher
scoring) then maximises the censored likelihood, and the same information, summed, is the
Cramer-Rao bound the datasheet predicts (:mod:`starsense.model.fisher`). A pixel at the ADC's
top or the full well stays out of the sums (its star's core says little of where the star is).
"""

from __future__ import annotations

import numpy as np
from scipy.special import log_ndtr, ndtr

__all__ = ["censored_information", "floor_e", "pixel_terms", "pixel_variance"]

#: a pixel whose expected value lies more than this many of its sigmas above the floor reads
#: as an uncensored one: it reads 0 with probability below 3e-7, and keeps all but ~1e-6 of
#: its information
FLOOR_REACH_SIGMAS = 5.0
LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


def pixel_variance(detector, mu_e, exposure_s: float) -> np.ndarray:
    """Variance of a pixel's reading, electrons^2, about the expected signal ``mu_e``.

    Shot noise on the signal and the dark charge, read noise, DSNU, PRNU (``(prnu mu)^2``) and
    the ADC's quantisation (``1 / (12 g^2)``, g counts per electron).
    """
    mu = np.maximum(np.asarray(mu_e, dtype=float), 0.0)
    dark = detector.dark_current_e_s * exposure_s
    return (
        mu
        + dark
        + detector.read_noise_e**2
        + detector.dsnu_e**2
        + (detector.prnu_fraction * mu) ** 2
        + 1.0 / (12.0 * detector.gain_counts_per_e**2)
    )


def floor_e(detector, exposure_s: float) -> float | None:
    """Return the ADC's floor in electrons above the bias, or None where no pixel reaches it.

    A reading of 0 counts means ``g e + bias < 0.5``: ``e < (0.5 - bias) / g``.
    """
    c = (0.5 - detector.bias_counts) / detector.gain_counts_per_e
    dark = float(np.sqrt(pixel_variance(detector, 0.0, exposure_s)))
    return c if c > -FLOOR_REACH_SIGMAS * dark else None


def _mills(a) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``Phi(a)``, ``phi(a)`` and ``lambda(a) = phi / Phi`` (stable where Phi is tiny)."""
    log_pdf = -0.5 * a * a - LOG_SQRT_2PI
    return ndtr(a), np.exp(log_pdf), np.exp(log_pdf - log_ndtr(a))


def censored_information(a) -> np.ndarray:
    """Return ``kappa(a)``: a floor-censored pixel's information over the uncensored one's."""
    a = np.asarray(a, dtype=float)
    cdf, pdf, mills = _mills(a)
    return np.clip(1.0 - cdf + a * pdf + pdf * mills, 0.0, 1.0)


def pixel_terms(detector, mu, data, *, use, exposure_s: float):
    """Return the weights, residuals and chi-square terms of the fit's pixels (module docstring).

    Parameters
    ----------
    detector : Detector
    mu, data : ndarray
        The model's and the frame's electrons above the bias (a reading of 0 counts is at the
        floor).
    use : ndarray of bool
        The pixels in the sums.
    exposure_s : float

    Returns
    -------
    weight, resid, chi2 : ndarray
        ``kappa / sigma^2`` (0 where unused), the score over the weight, the chi-square terms.
    """
    v = pixel_variance(detector, mu, exposure_s)
    resid = data - mu
    floor = floor_e(detector, exposure_s)
    if floor is None:  # the plain normal likelihood
        weight = use / v
        return weight, resid, weight * resid * resid
    weight = use / v
    chi2 = weight * resid * resid
    sigma = np.sqrt(v)
    a = (floor - mu) / sigma
    near = np.flatnonzero((a > -FLOOR_REACH_SIGMAS) & use)  # the rest read as uncensored
    if near.size:
        a, s_, v_, r_ = a.flat[near], sigma.flat[near], v.flat[near], resid.flat[near]
        cdf, pdf, mills = _mills(a)
        kappa = np.clip(1.0 - cdf + a * pdf + pdf * mills, 1e-12, 1.0)
        at_floor = data.flat[near] < floor
        score = np.where(at_floor, -mills / s_, r_ / v_)
        weight.flat[near] = kappa / v_
        resid = resid.copy()
        resid.flat[near] = score * v_ / kappa
        chi2.flat[near] = np.where(at_floor, 1.0 - a * mills, r_ * r_ / v_)
    return weight, resid, chi2
