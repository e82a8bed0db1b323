"""What the calibrated lens leaves: the part of the stars' residuals that is not their noise.

After the calibration (:func:`starsense.solve.calibration.calibrate`) a star's residual holds its
centroid's noise, which falls with its light, and what the lens model misses, which does not.
The squared residuals per axis are fitted against the magnitude,
``r^2 = a + b F^-1 + c F^-2`` (``F = 10^(-0.4 m)``; non-negative least squares: a floor, photon
noise, background noise), and the floor ``a`` is the lens's residual variance, what
``optics.distortion_residual_px`` means (a rendered frame displaces each star by it on top of
its noise). Its 1-sigma is the floor's standard error, from the squared residuals' scatter
about the fit (each axis's ``r^2`` of a normal residual has variance ``2 s^4``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["lens_residual_px", "star_residuals", "star_residuals_px2"]


def star_residuals(frames, calibration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return each matched star's centroid (N, 2), residual (N, 2) and V magnitude, px.

    The residual is the centroid less where the calibrated sensor projects the star at its
    frame's fitted attitude (x = column, y = row).

    Parameters
    ----------
    frames : list of SolvedFrame
    calibration : Calibration
        Its sensor and fitted attitudes (one per frame, in order).
    """
    sensor = calibration.sensor
    xy, res, mags = [np.zeros((0, 2))], [np.zeros((0, 2))], [np.zeros(0)]
    for fr, rot in zip(frames, calibration.rotations, strict=True):
        cam = np.asarray(fr.stars.vectors, dtype=float) @ rot.as_matrix().T
        x, y = sensor.project(cam)
        c = np.asarray(fr.stars.centroids_px, dtype=float)
        xy.append(c)
        res.append(c - np.column_stack([x, y]))
        mags.append(np.asarray(fr.mags_v, dtype=float))
    return np.concatenate(xy), np.concatenate(res), np.concatenate(mags)


def star_residuals_px2(frames, calibration) -> tuple[np.ndarray, np.ndarray]:
    """Return each matched star's V magnitude and squared residual per axis (px^2)."""
    _, d, mags = star_residuals(frames, calibration)
    return mags, 0.5 * np.sum(d * d, axis=1)


def lens_residual_px(mags, r2_px2, *, clip: float = 5.0) -> tuple[float, float, float]:
    """Fit the floor of the squared residuals against magnitude (module docstring).

    Parameters
    ----------
    mags : array_like (N,)
        V magnitudes.
    r2_px2 : array_like (N,)
        Squared residual per axis, px^2.
    clip : float
        Stars whose squared residual exceeds this many times the fit's at their magnitude
        (a mismatch, a blend; the calibration drops them too) are left out.

    Returns
    -------
    floor_px, sigma_px, rms_px : float
        The lens's residual (sqrt of the floor), its 1-sigma, and the stars' rms per axis.
    """
    from scipy.optimize import nnls

    m = np.asarray(mags, dtype=float)
    r2 = np.asarray(r2_px2, dtype=float)
    ok = np.isfinite(m) & np.isfinite(r2)
    m, r2 = m[ok], r2[ok]
    if m.size < 4:
        return math.nan, math.nan, math.nan
    inv_f = 10.0 ** (0.4 * (m - np.median(m)))  # scaled: the columns of one order
    design = np.column_stack([np.ones_like(inv_f), inv_f, inv_f**2])
    keep = np.ones(m.size, dtype=bool)
    for _ in range(3):
        coef, _ = nnls(design[keep], r2[keep])
        model = np.maximum(design @ coef, 1e-12)
        keep = r2 <= clip * 2.0 * model + 1e-12  # r^2 of a normal residual: mean s^2, rarely 5x2
    rms = math.sqrt(float(np.mean(r2[keep])))
    a = float(coef[0])
    used = design[keep][:, coef > 0] if np.any(coef > 0) else design[keep][:, :1]
    if coef[0] <= 0:
        # the floor is at its bound: its 1-sigma from the intercept-only column's information
        w = 1.0 / (2.0 * np.maximum(model[keep], 1e-12) ** 2)
        var_a = 1.0 / float(np.sum(w))
        return 0.0, math.sqrt(math.sqrt(var_a)), rms
    w = 1.0 / (2.0 * model[keep] ** 2)
    info = used.T @ (used * w[:, None])
    var_a = float(np.linalg.inv(info)[0, 0])
    floor = math.sqrt(a)
    return floor, math.sqrt(var_a) / (2.0 * floor), rms
