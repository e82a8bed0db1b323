"""Checks and conversions shared by the modules of :mod:`starsense.analysis.guide_stars`."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import positive_float
from starsense.errors import InputError

METRICS = ("total", "pointing")
"""Accuracy metrics: the whole error rotation vector, or its cross-boresight part."""

SIGMA_KINDS = {"1sigma": 1.0, "3sigma": 3.0}
"""How a quoted measurement error relates to the per-axis standard deviation."""


def check_metric(metric: str) -> None:
    """Raise :class:`InputError` unless ``metric`` is one of :data:`METRICS`."""
    if metric not in METRICS:
        raise InputError(f"metric = {metric!r} is not known; choose one of {', '.join(METRICS)}")


def check_sigmas(sigmas_rad: ArrayLike, sigma_kind: str) -> tuple[NDArray[np.float64], float]:
    """Return validated sigmas (rad, 1-D) and the standard deviation per quoted sigma.

    Parameters
    ----------
    sigmas_rad : array_like of float
        Quoted measurement errors, rad, each > 0.
    sigma_kind : {"1sigma", "3sigma"}
        What a quoted sigma is (:data:`SIGMA_KINDS`).

    Returns
    -------
    sigmas : ndarray, shape (n_sigma,)
        The sigmas, rad.
    per_quoted : float
        Per-axis standard deviation per quoted sigma (1 or 1/3).
    """
    sig = np.atleast_1d(np.asarray(sigmas_rad, dtype=np.float64))
    if sig.ndim != 1 or sig.size == 0:
        raise InputError("sigmas_rad must be a non-empty list of numbers")
    for s in sig:
        positive_float(s, "sigma_rad")
    if sigma_kind not in SIGMA_KINDS:
        raise InputError(
            f"sigma_kind = {sigma_kind!r} is not known; choose one of {', '.join(SIGMA_KINDS)}"
        )
    return sig, 1.0 / SIGMA_KINDS[sigma_kind]
