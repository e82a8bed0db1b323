"""Detection logic over a stack of small images at once (the slew Monte Carlo's hot path).

The ST-16 logic (Dzamba & Enright 2014, sec. 1.2) on K stamps in one pass: one
``scipy.ndimage.label`` call over the (K, H, W) stack with a structuring element that connects
pixels only within a stamp, then per-region sizes and sums with ``np.bincount``. Same rules as the
full-frame detector: a pixel is lit when its background-subtracted counts exceed
``lit_pixel_counts``; a region is a star when it has at least ``min_pixels`` contiguous lit pixels
and its lit pixels sum (background-subtracted) to at least ``min_integrated_counts``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from starsense.errors import InputError


def _structure(connectivity: int) -> np.ndarray:
    plane = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    s = np.zeros((3, 3, 3), dtype=bool)
    s[1] = plane  # no connection across stamps
    return s


def detect_stack(stack, thresholds, background_counts: float = 0.0):
    """Apply the detection logic to each image of a stack.

    Parameters
    ----------
    stack : array (K, H, W)
        Counts.
    thresholds : starsense.sensor.DetectionThresholds
        lit_pixel_counts, min_pixels, min_integrated_counts, connectivity.
    background_counts : float
        Known background (bias) subtracted before the thresholds.

    Returns
    -------
    detected : array (K,) bool
        At least one region passes the logic.
    integrated_counts : array (K,)
        Integrated intensity of the brightest passing region (NaN where none).
    """
    a = np.asarray(stack)
    if a.ndim != 3:
        raise InputError(f"stack must be 3-D (K, H, W), got shape {a.shape}")
    k = a.shape[0]
    sub = a.astype(np.float32) - np.float32(background_counts)
    lit = sub > thresholds.lit_pixel_counts
    labels, n = ndimage.label(lit, structure=_structure(thresholds.connectivity))
    best = np.full(k, np.nan)
    if n == 0:
        return np.zeros(k, dtype=bool), best
    flat = labels.ravel()
    on = flat > 0
    lab = flat[on]
    sizes = np.bincount(lab, minlength=n + 1)
    sums = np.bincount(lab, weights=sub.ravel()[on], minlength=n + 1)
    stamp_of = np.zeros(n + 1, dtype=np.intp)
    stamp_of[lab] = np.flatnonzero(on) // (a.shape[1] * a.shape[2])
    ok = (sizes >= thresholds.min_pixels) & (sums >= thresholds.min_integrated_counts)
    ok[0] = False
    np.fmax.at(best, stamp_of[ok], sums[ok])
    return np.isfinite(best), best
