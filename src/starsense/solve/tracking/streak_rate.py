"""Body rate from the streaks of a single smeared frame (up to its sign).

During an exposure ``t_e`` at the body rate ``w`` (camera frame) the star at ``b`` draws the
streak ``l(w) = p(R(-w t_e / 2) b) - p(R(w t_e / 2) b)`` on the detector (``p`` the sensor's
projection; :mod:`starsense.render.scene`). The light of its lit pixels (those above the
detection threshold) has the second-moment matrix of a PSF cut at the threshold, ``s^2 I``,
spread uniformly along the streak::

    M = s^2 I_2 + l l^T / 12

so the difference of its eigenvalues is ``|l|^2 / 12`` and its major axis is the streak's axis,
whatever the cut does to ``s``; only lit pixels count, so the background level hardly matters.
:func:`rate_from_streaks` fits ``w`` to ``l l^T`` of several stars by least squares
(``scipy.optimize.least_squares``). ``w`` and ``-w`` draw the same streaks: the rate comes with
its sign undetermined, which the next frame settles. Its covariance is the Gauss-Newton one,
scaled by the fit's residual variance.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from starsense.detect.clip import MAD_TO_SIGMA
from starsense.errors import InputError

__all__ = ["SYSTEMATIC", "rate_from_streaks", "streak_axes"]

#: Relative error of a streak rate from the lit pixels' shortened ends (see rate_from_streaks)
SYSTEMATIC = 0.2


def streak_axes(
    image,
    x,
    y,
    *,
    half_px: int,
    threshold: float,
    level: float | None = 0.0,
    threshold_sigma: float | None = None,
) -> np.ndarray:
    """Return ``l l^T`` of the streak through each centroid, from its lit pixels, px^2.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame, counts.
    x, y : array_like, shape (N,)
        Centroids, px.
    half_px : int
        Half-width of the square window searched around each centroid, px.
    threshold : float
        Lit-pixel threshold above ``level``, counts (the detection logic's).
    level : float or None
        Background level, counts; None: the median of each window's border.
    threshold_sigma : float, optional
        With ``level`` None, the threshold is at least this many times the border's noise
        (scaled median absolute deviation).

    Returns
    -------
    ndarray, shape (N, 2, 2)
        ``12 (lambda_1 - lambda_2) e e^T`` of the lit region at the centroid (x = column,
        y = row); NaN where the window leaves the frame or no lit region holds the centroid.
    """
    a = np.asarray(image)  # each window is read as float, not the whole frame
    rows, cols = a.shape
    out = np.full((len(x), 2, 2), np.nan)
    for i, (xc, yc) in enumerate(zip(np.asarray(x, float), np.asarray(y, float), strict=True)):
        r0, c0 = round(yc) - half_px, round(xc) - half_px
        r1, c1 = r0 + 2 * half_px + 1, c0 + 2 * half_px + 1
        if r0 < 0 or c0 < 0 or r1 > rows or c1 > cols:
            continue
        sub = a[r0:r1, c0:c1].astype(float)
        cut = threshold
        if level is None:
            border = np.concatenate([sub[0], sub[-1], sub[1:-1, 0], sub[1:-1, -1]])
            base = float(np.median(border))
            if threshold_sigma is not None:
                noise = MAD_TO_SIGMA * float(np.median(np.abs(border - base)))
                cut = max(threshold, threshold_sigma * noise)
            sub = sub - base
        else:
            sub = sub - level
        labels, _ = ndimage.label(sub > cut, structure=np.ones((3, 3)))
        lit = np.argwhere(labels > 0)
        if len(lit) < 3:
            continue
        near = lit[np.argmin(np.hypot(lit[:, 0] - (yc - r0), lit[:, 1] - (xc - c0)))]
        mine = labels == labels[near[0], near[1]]
        wgt = np.where(mine, sub, 0.0)
        total = wgt.sum()
        py, px = np.nonzero(mine)
        v = wgt[py, px]
        cx, cy = v @ px / total, v @ py / total
        dx, dy = px - cx, py - cy
        m = np.array([[v @ dx**2, v @ (dx * dy)], [v @ (dx * dy), v @ dy**2]]) / total
        lam, vec = np.linalg.eigh(m)
        e = vec[:, 1]
        out[i] = 12.0 * (lam[1] - lam[0]) * np.outer(e, e)
    return out


def _streaks(sensor, b, w, exposure_s):
    half = Rotation.from_rotvec(w * exposure_s / 2.0)
    xs, ys = sensor.project(half.apply(b))
    xe, ye = sensor.project(half.inv().apply(b))
    return np.column_stack([xe - xs, ye - ys])


def rate_from_streaks(sensor, x, y, *, axes_px2, exposure_s: float | None = None):
    """Fit the body rate (up to sign) to the streaks of one frame.

    Parameters
    ----------
    sensor : Sensor
        The optics.
    x, y : array_like, shape (N,)
        Centroids, px (at least 3 streaks; the brightest few: a faint streak breaks into
        pieces, and a piece is shorter than its streak).
    axes_px2 : ndarray, shape (N, 2, 2)
        ``l l^T`` of each streak (:func:`streak_axes`), px^2.
    exposure_s : float, optional
        Exposure, s (default the sensor's).

    Returns
    -------
    rate_rad_s : ndarray, shape (3,)
        Body rate, camera frame, rad/s; ``-rate`` fits as well.
    cov_rad2_s2 : ndarray, shape (3, 3)
        Its covariance, (rad/s)^2.

    Raises
    ------
    InputError
        Fewer than three usable streaks.
    """
    te = sensor.exposure_or(exposure_s)
    m = np.asarray(axes_px2, dtype=float)
    ok = np.all(np.isfinite(m.reshape(len(m), -1)), axis=1)
    if ok.sum() < 3:
        raise InputError(f"the rate needs at least 3 measured streaks, got {int(ok.sum())}")
    b = sensor.unproject(np.asarray(x, float)[ok], np.asarray(y, float)[ok])
    ll = m[ok]
    target = np.column_stack([ll[:, 0, 0], ll[:, 0, 1], ll[:, 1, 1]])
    scale = max(float(np.sqrt(np.mean(target**2))), 1.0)

    def residual(w):
        s = _streaks(sensor, b, w, te)
        model = np.column_stack([s[:, 0] ** 2, s[:, 0] * s[:, 1], s[:, 1] ** 2])
        return ((model - target) / scale).ravel()

    # start across the mean streak axis (a cross-axis rate), and about the boresight
    mean = ll.sum(axis=0)
    axis = np.linalg.eigh(mean)[1][:, -1]
    length = math.sqrt(max(float(np.trace(mean)) / len(ll), 0.0))
    speed = length / (te * sensor.focal_length_px)
    starts = [np.array([-axis[1], axis[0], 0.0]) * speed, np.array([0.0, 0.0, speed * 5.0])]
    best = min((least_squares(residual, s0, x_scale="jac") for s0 in starts), key=lambda r: r.cost)
    dof = max(best.fun.size - 3, 1)
    cov = 2.0 * best.cost / dof * np.linalg.pinv(best.jac.T @ best.jac)
    # the lit region is shorter than the streak where its ends taper below the threshold: on
    # rendered ST-16 frames at 0.3-2 deg/s, from the 4-5 brightest streaks, the cross-axis
    # rate comes out 0-16 % low; 20 % of |w| per axis is added to the covariance for it
    return best.x, cov + np.eye(3) * (SYSTEMATIC * float(np.linalg.norm(best.x))) ** 2
