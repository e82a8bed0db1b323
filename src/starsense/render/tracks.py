"""Star tracks during an exposure: the exact rotation of the camera, arcs by sub-stepping.

For a body rate ``w`` (rad/s, camera frame) a star's camera-frame direction is
``b(t) = R(-w tau) b_mid``, ``R`` the exact rotation by the rotation vector ``-w tau`` (eq. 10
without its small-angle approximation), ``tau = t - t_e / 2`` the time from mid-exposure, and
its pixel position is ``sensor.project(b(t))`` (pinhole + distortion). Cross-axis rates give
(nearly) straight streaks (eq. 12); roll gives circular arcs, and distortion and off-axis
projection bend and speed up tracks. :func:`star_tracks` handles all of them by sub-stepping:
the exposure is split into ``K`` equal time steps whose end points are joined by straight
segments, each rendered as a uniform straight streak carrying ``S_e / K`` electrons
(:func:`starsense.render.smear.polyline_expected`); ``K`` is doubled until the true position at
8 times within every step is within ``tol_px = 0.001`` px of the uniform straight-line motion
assumed there (this bounds the chord sagitta and the non-uniform speed together). A segment's
light centres on its chord's midpoint, the arc's time average sits two thirds of the sagitta off
the chord, always on the concave side: at 0.01 px that put a long streak's light 0.003-0.006 px
off its true time average, as large as a bright streak's across-track noise; at 0.001 px it is
below 0.0007 px, for a few more segments (16 on a 640 px streak) and no measurable render time.

Equation numbers are those of Dzamba & Enright 2014, Sensors 14, 3939.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import finite_array
from starsense.errors import InputError

__all__ = ["MAX_RATE_RAD_S", "Tracks", "check_rate", "star_tracks"]

#: fastest body rate rendered, rad/s (one turn a second, 360 deg/s): a star tracker's rates are
#: a few deg/s, and faster than this every star crosses the whole sky in one exposure; a
#: larger rate is a typo (or 1e308, which overflows the tracks into a frame of no stars)
MAX_RATE_RAD_S = 2.0 * np.pi


@dataclass(frozen=True)
class Tracks:
    """Centroid tracks of stars during one exposure (pixel coordinates).

    Attributes
    ----------
    start, mid, end : ndarray, shape (N, 2)
        (x, y) at t = 0, t_e / 2 and t_e (exact projections).
    vertices : tuple of ndarray, each (K_i + 1, 2)
        Positions at ``t = k t_e / K_i``; straight uniform motion between them is within
        ``max_deviation_px`` of the true motion.
    max_deviation_px : ndarray, shape (N,)
        Largest distance found between the true position and the sub-stepped one (8 samples
        per step).
    valid : ndarray of bool, shape (N,)
        False where the star is behind the camera at some time in the exposure (NaN positions).
    """

    start: np.ndarray
    mid: np.ndarray
    end: np.ndarray
    vertices: tuple[np.ndarray, ...]
    max_deviation_px: np.ndarray
    valid: np.ndarray

    @property
    def n_segments(self) -> np.ndarray:
        """K_i, the number of straight segments of each track, (N,) int."""
        return np.array([len(v) - 1 for v in self.vertices], dtype=np.int64)

    def __len__(self) -> int:
        return int(self.start.shape[0])


def check_rate(rate_rad_s) -> np.ndarray:
    """Return a body rate as a float array of shape (3,), or raise :class:`InputError`.

    Parameters
    ----------
    rate_rad_s : array_like, shape (3,)
        Body rate (wx, wy, wz) in the camera frame, rad/s; finite, of magnitude at most
        :data:`MAX_RATE_RAD_S`.

    Returns
    -------
    ndarray, shape (3,)
    """
    w = finite_array(rate_rad_s, "rate_rad_s")
    if w.shape != (3,):
        raise InputError(
            f"rate_rad_s must have 3 components (wx, wy, wz) in rad/s, got shape {w.shape}"
        )
    norm = float(np.sqrt(np.sum(np.square(w / max(1.0, float(np.max(np.abs(w))))))))
    norm *= max(1.0, float(np.max(np.abs(w))))  # scaled first: 1e308 does not overflow
    if norm > MAX_RATE_RAD_S:
        raise InputError(
            f"rate_rad_s = {w.tolist()} is {norm:.4g} rad/s, faster than {MAX_RATE_RAD_S:.4g} "
            "rad/s (one turn a second), which no star track survives"
        )
    return w


def _project_at(sensor, vectors, rate, exposure_s, fractions) -> tuple[np.ndarray, np.ndarray]:
    """Return pixel positions (N, T) at times ``fractions * t_e`` of mid-exposure ``vectors``."""
    tau = (np.asarray(fractions, dtype=float) - 0.5) * exposure_s
    rot = Rotation.from_rotvec(-tau[:, None] * rate[None, :]).as_matrix()  # (T, 3, 3)
    v = np.einsum("tij,nj->nti", rot, vectors)
    return sensor.project(v)


def star_tracks(
    sensor,
    vectors_cam,
    *,
    rate_rad_s=(0.0, 0.0, 0.0),
    exposure_s: float | None = None,
    tol_px: float = 0.001,
    max_segments: int = 4096,
) -> Tracks:
    """Pixel tracks of stars during an exposure, sub-stepped into straight segments.

    Parameters
    ----------
    sensor : Sensor
        Provides ``project`` (pinhole + distortion) and the default exposure.
    vectors_cam : array_like, shape (N, 3) or (3,)
        Star directions in the camera frame at mid-exposure.
    rate_rad_s : array_like, shape (3,)
        Body rate (wx, wy, wz) in the camera frame, rad/s; the camera frame turns by
        ``w tau`` so the stars turn by ``-w tau`` (eq. 10, exact rotation).
    exposure_s : float, optional
        Exposure, s (default ``sensor.exposure_s``).
    tol_px : float
        Largest allowed deviation between the true motion and uniform straight motion on each
        segment, px ("arcs by sub-stepping").
    max_segments : int
        Upper limit of K (reached only for pathological rates; the deviation is then reported
        in ``max_deviation_px``).

    Returns
    -------
    Tracks
    """
    w = check_rate(rate_rad_s)
    te = sensor.exposure_or(exposure_s)
    v = np.asarray(vectors_cam, dtype=float).reshape(-1, 3)
    n = v.shape[0]
    sub = 8
    verts: list[np.ndarray | None] = [None] * n
    dev = np.zeros(n)
    start = np.full((n, 2), np.nan)
    mid = np.full((n, 2), np.nan)
    end = np.full((n, 2), np.nan)
    valid = np.ones(n, dtype=bool)
    pending = np.arange(n)
    k = 1
    first = True
    while pending.size:
        m = k * sub
        x, y = _project_at(sensor, v[pending], w, te, np.arange(m + 1) / m)
        if first:
            start[:, 0], start[:, 1] = x[:, 0], y[:, 0]
            mid[:, 0], mid[:, 1] = x[:, m // 2], y[:, m // 2]
            end[:, 0], end[:, 1] = x[:, -1], y[:, -1]
            first = False
        bad = ~(np.isfinite(x).all(axis=1) & np.isfinite(y).all(axis=1))
        xv, yv = x[:, ::sub], y[:, ::sub]  # (P, k + 1)
        frac = np.arange(sub) / sub
        xl = xv[:, :-1, None] + (xv[:, 1:, None] - xv[:, :-1, None]) * frac
        yl = yv[:, :-1, None] + (yv[:, 1:, None] - yv[:, :-1, None]) * frac
        d = np.hypot(x[:, :-1].reshape(-1, k, sub) - xl, y[:, :-1].reshape(-1, k, sub) - yl)
        with np.errstate(invalid="ignore"):
            d_max = np.where(bad, 0.0, np.max(d, axis=(1, 2)))
        done = bad | (d_max <= tol_px) | (k >= max_segments)
        both = np.stack([xv, yv], axis=2)  # (P, k + 1, 2)
        for j in np.flatnonzero(done):
            verts[pending[j]] = both[j]
        dev[pending[done]] = d_max[done]
        valid[pending[done]] = ~bad[done]
        pending = pending[~done]
        k *= 2
    return Tracks(
        start=start,
        mid=mid,
        end=end,
        vertices=tuple(verts),  # type: ignore[arg-type]
        max_deviation_px=dev,
        valid=valid,
    )
