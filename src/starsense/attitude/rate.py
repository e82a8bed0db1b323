"""Angular rate from consecutive attitudes, and attitude prediction at a known rate.

Convention (:mod:`starsense.render.scene`): for a constant body rate ``w`` in the camera frame,
the attitude (ICRS -> camera) evolves as ``A(t + dt) = R(-w dt) A(t)``, with ``R`` the rotation
by that rotation vector. Attitude errors are camera-frame rotation vectors ``d``
(``A_est = R(d) A_true``, :func:`starsense.geometry.attitude.small_rotation_angles`) with
covariance ``P`` (:mod:`starsense.attitude.covariance`, Fialho & Mortari 2019 eq. 21).

From two attitudes ``dt`` apart, ``w = -rotvec(A_1 A_0^-1) / dt``. To first order in the errors,
``rotvec(A_1^est A_0^est^-1) = -w dt + d_1 - M d_0`` with ``M = R(-w dt)``, so

    cov(w) = (P_1 + M P_0 M^T) / dt^2

and a prediction ``A_1 = R(-w dt) A_0`` has the error ``M d_0 - dt e_w`` (``e_w`` the rate error):

    P_1^pred = M P_0 M^T + dt^2 cov(w).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import positive_float
from starsense.errors import InputError

__all__ = ["predict_attitude", "rate_from_attitudes"]


def _cov(value: ArrayLike | None, name: str) -> NDArray[np.float64]:
    if value is None:
        return np.zeros((3, 3))
    c = np.asarray(value, dtype=float)
    if c.shape != (3, 3) or not np.isfinite(c).all():
        raise InputError(f"{name} must be a finite 3 x 3 covariance, got shape {c.shape}")
    return c


def _rotation(value: object, name: str) -> Rotation:
    if not isinstance(value, Rotation) or not value.single:
        raise InputError(f"{name} must be a single scipy Rotation, got {value!r}")
    return value


def rate_from_attitudes(
    attitude0: Rotation,
    attitude1: Rotation,
    dt_s: float,
    *,
    cov0_rad2: ArrayLike | None = None,
    cov1_rad2: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the constant body rate carrying ``attitude0`` to ``attitude1``, and its covariance.

    ``w = -rotvec(A_1 A_0^-1) / dt`` and ``cov(w) = (P_1 + M P_0 M^T) / dt^2`` with
    ``M = R(-w dt)`` (module docstring). The rotation between the frames must be below pi.

    Parameters
    ----------
    attitude0, attitude1 : Rotation
        Attitudes (ICRS -> camera) at t and t + dt.
    dt_s : float
        Time between them, s (> 0).
    cov0_rad2, cov1_rad2 : array_like, shape (3, 3), optional
        Their camera-frame covariances, rad^2 (zero if not given).

    Returns
    -------
    rate_rad_s : ndarray, shape (3,)
        Body rate in the camera frame, rad/s.
    cov_rad2_s2 : ndarray, shape (3, 3)
        Its covariance, (rad/s)^2.

    Raises
    ------
    InputError
        Bad rotation, interval or covariance.
    """
    a0 = _rotation(attitude0, "attitude0")
    a1 = _rotation(attitude1, "attitude1")
    dt = positive_float(dt_s, "dt_s")
    p0 = _cov(cov0_rad2, "cov0_rad2")
    p1 = _cov(cov1_rad2, "cov1_rad2")
    step = a1 * a0.inv()
    w = -step.as_rotvec() / dt
    m = step.as_matrix()
    return w, (p1 + m @ p0 @ m.T) / dt**2


def predict_attitude(
    attitude: Rotation,
    dt_s: float,
    *,
    rate_rad_s: ArrayLike | None = None,
    cov_rad2: ArrayLike | None = None,
    rate_cov_rad2_s2: ArrayLike | None = None,
) -> tuple[Rotation, NDArray[np.float64]]:
    """Propagate an attitude by ``dt_s`` at a constant rate, with its covariance.

    ``A(t + dt) = R(-w dt) A(t)``; ``P = M P_0 M^T + dt^2 cov(w)`` (module docstring).

    Parameters
    ----------
    attitude : Rotation
        Attitude at t, ICRS -> camera.
    dt_s : float
        Time step, s (>= 0).
    rate_rad_s : array_like, shape (3,), optional
        Body rate in the camera frame, rad/s (zero if not given).
    cov_rad2 : array_like, shape (3, 3), optional
        Covariance of the attitude at t, rad^2.
    rate_cov_rad2_s2 : array_like, shape (3, 3), optional
        Covariance of the rate, (rad/s)^2.

    Returns
    -------
    attitude : Rotation
        Predicted attitude at t + dt.
    cov_rad2 : ndarray, shape (3, 3)
        Its covariance, rad^2.
    """
    a = _rotation(attitude, "attitude")
    dt = float(dt_s)
    if not np.isfinite(dt) or dt < 0:
        raise InputError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
    w = np.zeros(3) if rate_rad_s is None else np.asarray(rate_rad_s, dtype=float)
    if w.shape != (3,) or not np.isfinite(w).all():
        raise InputError(f"rate_rad_s must be 3 finite numbers, got {rate_rad_s!r}")
    p0, p_w = _cov(cov_rad2, "cov_rad2"), _cov(rate_cov_rad2_s2, "rate_cov")
    if not (w * dt).any():  # no turn: M = I (the same covariance, no rotation to compose)
        return a, p0 + dt**2 * p_w
    step = Rotation.from_rotvec(-w * dt)
    m = step.as_matrix()
    return step * a, m @ p0 @ m.T + dt**2 * p_w
