"""Lost in space on a smeared frame: the matched stars centroided over their whole streaks.

At a body rate ``w`` a star draws a streak ``l`` during the exposure, and its mid-exposure
position is the centre of that streak. The detector's centre of gravity over a region's box is
that centre only when the region holds the whole streak; a faint streak breaks into pieces
above the threshold, and the centroid of a piece is off the star's position by up to half the
streak (on rendered frames at 1 deg/s: 5-9 px for streaks of 21 px), and the faint ends of a
streak that taper below the threshold, or a streak cut by the frame's edge, pull the box's
centroid along the streak. The identification is right, but an attitude fitted to those
centroids can be off by more than a pixel: a wrong solution.

Once the frame is identified, :func:`streak_centroids_of`:

1. measures the body rate from the brightest matched stars' streaks
   (:func:`starsense.solve.streak_model.streak_model`); a frame whose streaks are short keeps
   its centroids (its boxes hold each streak), and the rate its streaks suggest
   (:class:`ShortStreaks`) is kept for the forward model's fit, should the frame not fit at
   rest;
2. predicts each matched star's streak from that rate, lengthened by the fit's systematic
   shortfall (the lit pixels' tapered ends, ``SYSTEMATIC``): the window must span the whole
   streak, or a window shorter than the streak would stay wherever it started;
3. centroids each star over the pixels within ``2.5 sigma + 1`` px of its streak, started from
   the detection and moved until it stays (:func:`starsense.detect.streak.streak_centroids`,
   the tracking windows' centroid);
4. gives each star the covariance of that centroid (the tracking model,
   :mod:`starsense.solve.tracking.star_noise`)::

       C = (sigma_psf^2 / N) I + (sigma_r^2 / N^2) S + l l^T / (12 N)

   (``sigma_r`` the read noise and the ADC's quantisation, 1/12 count^2), and to a star whose
   streak runs off the frame, or whose window found no light, the covariance of a point
   anywhere along its streak, ``l l^T / 12`` (uniform over it): its centroid is pulled inwards
   by the cut, and the fit all but ignores it.

The streaks are returned with the centroids: their body rate
(:func:`starsense.solve.streak_model.streak_body_rate`) starts
the forward model's fit, which draws each streak with its neighbours' and fits the rate with
the attitude (:mod:`starsense.solve.refine`); the capsule centroids give the attitude it starts
from, and the attitude itself where no sensor model is fitted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.detect.centroid import cog_sigma_px
from starsense.detect.streak import SYSTEMATIC, WINDOW_PIXELS, streak_centroids
from starsense.solve.streak_model import (
    CAPSULE_PAD_PX,
    CAPSULE_SIGMAS,
    MIN_STREAK_SIGMAS,
    streak_model,
)

__all__ = [
    "CAPSULE_PAD_PX",
    "CAPSULE_SIGMAS",
    "MIN_STREAK_SIGMAS",
    "ShortStreaks",
    "StreakCentroids",
    "capsule_centroids",
    "matched_measurements",
    "streak_centroids_of",
    "streak_cov_px2",
    "streak_measure",
]


@dataclass(frozen=True)
class StreakCentroids:
    """Matched stars centroided over their streaks (module docstring).

    Attributes
    ----------
    x, y : ndarray, shape (N,)
        Centroids, px.
    cov_px2 : ndarray, shape (N, 2, 2)
        Their covariance, px^2 (x = column, y = row).
    streaks_px : ndarray, shape (N, 2)
        Each star's streak, start to end (or end to start), px.
    electrons : ndarray, shape (N,), optional
        Each capsule's sum above the level, electrons (0 where none was found).
    """

    x: np.ndarray
    y: np.ndarray
    cov_px2: np.ndarray
    streaks_px: np.ndarray
    electrons: np.ndarray | None = None

    @property
    def sigma_px(self) -> np.ndarray:
        """Mean-of-axes 1-sigma of each centroid, px (shape (N,))."""
        return np.sqrt(0.5 * (self.cov_px2[:, 0, 0] + self.cov_px2[:, 1, 1]))


@dataclass(frozen=True)
class ShortStreaks:
    """A frame whose streaks are too short to re-centroid (its detections' centroids stand).

    Attributes
    ----------
    rate_rad_s : ndarray, shape (3,)
        The body rate the brightest matched stars' measured streaks suggest, camera frame,
        rad/s, up to its sign (noise where the frame is at rest).
    """

    rate_rad_s: np.ndarray


def _planes(image, x, y, half: int, level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return windows of 2 half + 1 px around (x, y), less the level, and their corners.

    Shapes (N, 2 half + 1, 2 half + 1), zero off the frame; first rows and columns (N,) each.
    """
    rows, cols = image.shape
    size = 2 * half + 1
    r0 = np.floor(y).astype(int) - half
    c0 = np.floor(x).astype(int) - half
    planes = np.zeros((len(x), size, size))
    for i in range(len(x)):
        a, b = max(r0[i], 0), min(r0[i] + size, rows)
        c, d = max(c0[i], 0), min(c0[i] + size, cols)
        sub = np.asarray(image[a:b, c:d], dtype=float)
        base = level
        if base is None:  # the median of the window's border
            base = float(np.median(np.concatenate([sub[0], sub[-1], sub[:, 0], sub[:, -1]])))
        planes[i, a - r0[i] : b - r0[i], c - c0[i] : d - c0[i]] = sub - base
    return planes, r0, c0


#: the most window pixels held at once (each star's window spans twice its streak)
_CHUNK_PIXELS = WINDOW_PIXELS


def capsule_centroids(image, x, y, *, seg, half: int, level, radius: float) -> tuple:
    """Return :func:`streak_centroids` over the stars' windows (:func:`_planes`), in chunks.

    (x, y, counts, boxes, spread) in the windows, and the windows' first rows and columns.
    """
    step = max(1, _CHUNK_PIXELS // (2 * half + 1) ** 2)
    parts = []
    for k in range(0, max(len(x), 1), step):
        at = slice(k, k + step)
        planes, r0, c0 = _planes(image, x[at], y[at], half, level)
        got = streak_centroids(planes, x[at] - c0, y[at] - r0, streaks=seg[at], radius=radius)
        parts.append((*got, r0, c0))
    return tuple(np.concatenate(z) for z in zip(*parts, strict=True))


def streak_centroids_of(
    sensor,
    image,
    xy,
    *,
    counts,
    extent_px,
    level: float | None,
    threshold: float,
    threshold_sigma: float | None = None,
    margin_px: int = 2,
) -> StreakCentroids | None:
    """Return the matched stars centroided over their whole streaks (module docstring).

    Parameters
    ----------
    sensor : Sensor
        The camera (projection, exposure, PSF, gain and read noise).
    image : ndarray, shape (rows, columns)
        The frame, counts.
    xy : array_like, shape (N, 2)
        The matched detections' centroids (x = column, y = row), px.
    counts : array_like, shape (N,)
        Their integrated counts (the brightest give the rate).
    extent_px : array_like, shape (N,)
        The larger side of each detection's box, px (the windows that measure the streaks
        hold the brightest whole).
    level : float or None
        Background level, counts (the known bias); None: the median of each window's border.
    threshold : float
        Lit-pixel threshold above the level, counts (the detection logic's).
    threshold_sigma : float, optional
        With ``level`` None, the threshold is at least this many times a window's noise.
    margin_px : int
        The margin of the detector's centroid window around a region's box, px.

    Returns
    -------
    StreakCentroids, ShortStreaks or None
        ShortStreaks when the streaks are shorter than re-centroiding needs
        (``MIN_STREAK_SIGMAS`` PSF sigmas): the detections' centroids stand, and the rate the
        brightest streaks suggest may start the forward model's; None when the rate cannot be
        measured (fewer than 3 measured streaks).
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    x, y = xy[:, 0].copy(), xy[:, 1].copy()
    counts = np.asarray(counts, dtype=float)
    if len(x) < 3:
        return None
    order = np.argsort(-counts, kind="stable")
    model, rate = streak_model(
        sensor,
        image,
        (x, y),
        order=order,
        counts=counts,
        extent_px=np.asarray(extent_px, dtype=float),
        level=level,
        threshold=threshold,
        threshold_sigma=threshold_sigma,
        margin_px=margin_px,
    )
    if model is None:
        return None if rate is None else ShortStreaks(np.asarray(rate, dtype=float))
    det = sensor.detector
    sigma = det.psf_sigma_px
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX  # the tracking windows' capsule
    streaks = model(x, y)
    rows, cols = image.shape
    seg = streaks * (1.0 + SYSTEMATIC)
    half = math.ceil(float(np.hypot(seg[:, 0], seg[:, 1]).max()) + radius + 2.0)
    gx, gy, total, _, spread, r0, c0 = capsule_centroids(
        image, x, y, seg=seg, half=half, level=level, radius=radius
    )
    found = np.isfinite(gx) & (total > 0)
    out_x = np.where(found, gx + c0, x)
    out_y = np.where(found, gy + r0, y)
    hx = 0.5 * np.abs(streaks[:, 0]) + radius
    hy = 0.5 * np.abs(streaks[:, 1]) + radius
    whole = found & (hx <= out_x) & (out_x <= cols - 1 - hx) & (hy <= out_y)
    whole &= out_y <= rows - 1 - hy  # a streak run off the frame is pulled inwards
    g = det.gain_counts_per_e
    electrons = np.where(found, total, 0.0) / g
    cov = streak_cov_px2(
        electrons,
        np.where(found[:, None, None], spread, 0.0),
        streaks,
        whole=whole,
        sigma_px=sigma,
        read_noise_e=math.hypot(det.read_noise_e, 1.0 / (math.sqrt(12.0) * g)),  # + quantising
    )
    return StreakCentroids(out_x, out_y, cov, np.asarray(streaks), electrons)


def streak_cov_px2(electrons, spread_px2, streaks_px, *, whole, sigma_px: float, read_noise_e):
    """Return the covariance the solver gives streak centroids (module docstring, step 4), px^2.

    Parameters
    ----------
    electrons : array_like, shape (N,)
        Electrons summed over each star's capsule (at least 1 is used).
    spread_px2 : array_like, shape (N, 2, 2)
        Sum over the capsule of (pixel - centroid)(pixel - centroid)^T, px^2.
    streaks_px : array_like, shape (N, 2)
        Each star's streak, px.
    whole : array_like of bool, shape (N,)
        Whether the streak lies whole inside the frame (else the covariance of a point
        anywhere along it).
    sigma_px : float
        PSF sigma, px.
    read_noise_e : float
        Read noise, electrons rms.

    Returns
    -------
    ndarray, shape (N, 2, 2)
        px^2 (x = column, y = row).
    """
    streaks = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    along = streaks[:, :, None] * streaks[:, None, :] / 12.0  # a point anywhere on the streak
    n_e = np.maximum(np.asarray(electrons, dtype=float), 1.0)[:, None, None]
    cov = (sigma_px**2 / n_e) * np.eye(2) + (read_noise_e**2 / n_e**2) * np.asarray(spread_px2)
    return np.where(np.asarray(whole)[:, None, None], cov + along / n_e, along)


def streak_measure(solver) -> dict:
    """Return the keywords :func:`streak_centroids_of` measures the solver's streaks with.

    ``level``, ``threshold``, ``threshold_sigma`` and ``margin_px``: the known bias, or (the
    background estimated) each window's border median with the threshold at least
    ``threshold_sigma`` of its noise; the detection logic's lit-pixel threshold and the
    detector's centroid margin.
    """
    known = solver.settings.background == "known"
    return {
        "level": float(solver.sensor.detector.bias_counts) if known else None,
        "threshold": solver.logic.lit_pixel_counts,
        "threshold_sigma": None if known else solver.settings.threshold_sigma,
        "margin_px": solver.detector.margin_px,
    }


def matched_measurements(solver, image, det, *, matched, x, vectors):
    """Return the matched detections' unit vectors and 1-sigma, px, for the final attitude.

    The detections' own centroids and noise (:func:`starsense.detect.centroid.cog_sigma_px`
    with ``centroid_sigma_px="snr"``, else the Solver's number), unless the frame is smeared:
    then the centroids over the whole streaks and their noise (:func:`streak_centroids_of`;
    with a number, the larger of it and a star's own). The mirror image of a frame (``x`` not
    the detections' own columns) keeps its centroids.

    Parameters
    ----------
    solver : Solver
        The solver (its sensor, settings and detector).
    image : ndarray, shape (rows, columns)
        The frame, counts.
    det : Detections
        The frame's detections.
    matched : ndarray of int, shape (N,)
        The matched detections.
    x : ndarray, shape (M,)
        The columns the frame was solved with (``det.x``, or their mirror image).
    vectors : ndarray, shape (N, 3)
        The matched detections' camera-frame unit vectors.

    Returns
    -------
    vectors : ndarray, shape (N, 3)
        Camera-frame unit vectors.
    sigma_px : ndarray, shape (N,), or float
        Per-axis 1-sigma of each centroid, px.
    streaks : StreakCentroids, ShortStreaks or None
        The streak centroids (their streaks, px, capsule sums and clipping); where the
        detections' centroids stand, the rate short streaks suggest, or None.
    """
    sensor, fixed = solver.sensor, solver.settings.centroid_sigma_px
    sigma = fixed
    if fixed == "snr":
        sigma = cog_sigma_px(
            det,
            matched,
            detector=sensor.detector,
            margin_px=solver.detector.margin_px,
            shape=np.shape(image),
        )
    if sensor is None or x is not det.x or len(matched) < 3:
        return vectors, sigma, None
    box = det.bbox[matched]
    got = streak_centroids_of(
        sensor,
        image,
        np.column_stack([det.x[matched], det.y[matched]]),
        counts=det.integrated_counts[matched],
        extent_px=np.maximum(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]),
        **streak_measure(solver),
    )
    if got is None or isinstance(got, ShortStreaks):
        return vectors, sigma, got
    own = got.sigma_px
    sigma = own if fixed == "snr" else np.maximum(own, fixed)
    return sensor.unproject(got.x, got.y), sigma, got
