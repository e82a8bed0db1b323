"""Confidence levels of a performance statement (ECSS-E-ST-60-10C, sec. 4.2.2 and annex A).

A statement quotes each error at a probability ``p`` that it is not exceeded. For an error that
is Gaussian per axis (zero mean, 1-sigma ``s``) the two-sided bound is ``k(p) s`` with
``k(p) = Phi^-1((1 + p) / 2)``: 1 at 68.27 %, 1.96 at 95 %, 3 at 99.73 %. Over the sky the
1-sigma itself varies from attitude to attitude (the stars in the field), so the error of a
frame at a random attitude is a mixture of Gaussians with heavier tails than one Gaussian of the
median sigma: :func:`mixture_bound` gives that ensemble bound.
"""

from __future__ import annotations

import math
import re

import numpy as np
from scipy.special import ndtr, ndtri

from starsense.errors import InputError

__all__ = [
    "ONE_SIGMA",
    "THREE_SIGMA",
    "gaussian_factor",
    "mixture_bound",
    "parse_confidence",
    "weighted_median",
]

#: the probability of |x| <= 1 sigma for a Gaussian: 0.682689...
ONE_SIGMA = float(math.erf(1.0 / math.sqrt(2.0)))
#: the probability of |x| <= 3 sigma for a Gaussian: 0.997300...
THREE_SIGMA = float(math.erf(3.0 / math.sqrt(2.0)))
_NAMED = {"1sigma": ONE_SIGMA, "2sigma": float(math.erf(math.sqrt(2.0))), "3sigma": THREE_SIGMA}


def parse_confidence(text, where: str = "--confidence") -> float:
    """Return a confidence level (probability in (0, 1)) from a number or a name.

    Parameters
    ----------
    text : str or float
        ``0.95``, ``95`` or ``95%`` (percent when > 1), ``1sigma``, ``2sigma`` or ``3sigma``
        (the Gaussian two-sided probabilities 68.27 %, 95.45 %, 99.73 %).
    where : str
        Named in the error message.

    Returns
    -------
    float
        The probability, in (0, 1).

    Raises
    ------
    InputError
        Not a number or a name, or outside (0, 100) %.
    """
    raw = str(text).strip().lower().replace(" ", "")
    if raw in _NAMED:
        return _NAMED[raw]
    m = re.fullmatch(r"([0-9]*\.?[0-9]+(?:e-?[0-9]+)?)(%?)", raw)
    if m is None:
        raise InputError(
            f"{where} = {text!r} is not a confidence level; give a probability (0.95), a "
            "percentage (95 or 95%) or 1sigma, 2sigma, 3sigma"
        )
    value = float(m.group(1))
    if m.group(2) or value > 1.0:
        value /= 100.0
    if not 0.0 < value < 1.0 or not math.isfinite(value):
        raise InputError(
            f"{where} = {text!r} is out of range; must lie strictly between 0 and 100 %"
        )
    return value


def gaussian_factor(confidence: float) -> float:
    """Return ``k`` such that a zero-mean Gaussian lies within ``k`` sigma with ``confidence``.

    ``k = Phi^-1((1 + p) / 2)`` (two-sided, one axis): 1.0 at 68.27 %, 1.96 at 95 %, 3.0 at
    99.73 %.

    Parameters
    ----------
    confidence : float
        Probability, in (0, 1).

    Returns
    -------
    float
    """
    return float(ndtri(0.5 * (1.0 + float(confidence))))


def _weighted(values, weights) -> tuple[np.ndarray, np.ndarray]:
    """Return the finite values with a positive weight, and those weights (1 when None)."""
    v = np.asarray(values, dtype=float).ravel()
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=float).ravel()
    keep = np.isfinite(v) & (w > 0)
    return v[keep], w[keep]


def mixture_bound(sigmas, confidence: float, weights=None) -> float | None:
    """Return the bound that an error drawn at a random attitude stays within, with ``confidence``.

    The error is Gaussian with the 1-sigma of its attitude, and the attitude drawn among the
    ones given with their ``weights`` (uniform by default):
    ``P(|e| <= q) = sum_m w_m (2 Phi(q / s_m) - 1) / sum_m w_m``; ``q`` solved for ``confidence``
    (the ensemble interpretation). For equal sigmas it is :func:`gaussian_factor` times the
    sigma.

    Parameters
    ----------
    sigmas : array_like (M,)
        1-sigma of each attitude (any unit; NaN where the attitude has none, left out; 0 is an
        attitude without this error).
    confidence : float
        Probability, in (0, 1).
    weights : array_like (M,), optional
        Each attitude's weight, >= 0 (e.g. its chance of giving a solution).

    Returns
    -------
    float or None
        In the unit of ``sigmas``; None when no attitude has a finite sigma (and a weight).
    """
    s, w = _weighted(sigmas, weights)
    if s.size == 0:
        return None
    top = float(np.max(s))
    if top <= 0.0:
        return 0.0
    live = s > 0
    total = float(np.sum(w))
    zero_share = float(np.sum(w[~live])) / total
    s_live, w_live = s[live], w[live] / total

    def inside(q: float) -> float:
        return zero_share + float(np.sum(w_live * (2.0 * ndtr(q / s_live) - 1.0))) - confidence

    from scipy.optimize import brentq  # loaded on use (the package's start-up rule)

    if inside(0.0) >= 0.0:  # enough attitudes without the error
        return 0.0
    hi = gaussian_factor(confidence) * top * 1.01 + 1e-300
    return float(brentq(inside, 0.0, hi, xtol=1e-12 * top, rtol=1e-10))


def weighted_median(values, weights=None) -> float | None:
    """Return the median of ``values`` drawn with ``weights`` (NaN and weight 0 left out).

    The smallest value whose cumulative weight reaches half the total (with unit weights, the
    lower median; :func:`numpy.median` averages the two middle values of an even count).

    Parameters
    ----------
    values : array_like (M,)
    weights : array_like (M,), optional
        >= 0; uniform by default.

    Returns
    -------
    float or None
        None when no value is finite with a weight.
    """
    v, w = _weighted(values, weights)
    if v.size == 0:
        return None
    if weights is None:
        return float(np.median(v))
    order = np.argsort(v, kind="stable")
    cum = np.cumsum(w[order])
    return float(v[order][np.searchsorted(cum, 0.5 * cum[-1])])
