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
from scipy.spatial.transform import Rotation

from starsense.detect.streak import SYSTEMATIC, streak_axes
from starsense.errors import InputError

__all__ = ["SYSTEMATIC", "rate_from_streaks", "streak_axes"]


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
    from scipy.optimize import least_squares  # the tracker's, not the solver's, import

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
