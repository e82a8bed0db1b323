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

1. measures the streaks of the brightest matched stars (the second moments of their lit pixels,
   :func:`starsense.detect.streak.streak_axes`, the collinear pieces of a faint streak broken
   by the noise bridged into it, ``bridge_px``) and fits the body rate, up to its
   sign, to the longest whole ones (the model of :mod:`~starsense.solve.tracking.streak_rate`,
   linear in the rate to first order in the angle turned during the exposure, solved for
   every choice of the streaks' unknown signs): a piece of a streak is shorter than the
   streak and a blend of two streaks longer (at most twice) or turned, so the reference is
   the streak the most others confirm (as long within the lit pixels' shortfall,
   ``SYSTEMATIC``, and as turned within the PSF's width), counting the brightest
   ``N_RATE_STARS`` first (a bright streak is whole; the pieces of faint ones, broken alike
   where their ridges cross the pixel rows, can outnumber them), of those at least half as
   long as the longest; only streaks within that shortfall of it take part, and a streak the fitted
   rate does not predict is dropped and the rate refitted (with fewer than 3 of them, their
   mean streak stands for every star's). A frame whose streaks, as the fitted rate draws
   them (a faint streak's lit pixels fall short of it), are all shorter than 2 PSF sigmas
   plus the centroid margin on each side keeps its centroids (with fewer than 3 streaks
   agreeing on the rate, the brightest measured ones decide): its boxes hold each streak;
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

The streaks are returned with the centroids: their body rate (:func:`streak_body_rate`) starts
the forward model's fit, which draws each streak with its neighbours' and fits the rate with
the attitude (:mod:`starsense.solve.refine`); the capsule centroids give the attitude it starts
from, and the attitude itself where no sensor model is fitted.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.detect.centroid import cog_sigma_px
from starsense.detect.streak import SYSTEMATIC, WINDOW_PIXELS, streak_axes, streak_centroids

__all__ = [
    "CAPSULE_PAD_PX",
    "CAPSULE_SIGMAS",
    "MIN_STREAK_SIGMAS",
    "N_RATE_STARS",
    "StreakCentroids",
    "matched_measurements",
    "streak_body_rate",
    "streak_centroids_of",
    "streak_cov_px2",
]

#: a frame whose measured streaks are shorter than this many PSF sigmas (plus the centroid
#: window's margins) is not re-centroided
MIN_STREAK_SIGMAS = 2.0
#: the capsule each streak is centroided over: within CAPSULE_SIGMAS PSF sigmas plus
#: CAPSULE_PAD_PX px of the streak (the tracking windows' capsule)
CAPSULE_SIGMAS, CAPSULE_PAD_PX = 2.5, 1.0
#: the brightest matched stars whose streaks give the rate (a faint streak breaks into pieces)
N_RATE_STARS = 5


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


def _streaks(sensor, x, y, rate_rad_s) -> np.ndarray:
    """Streak (start to end) of the stars at (x, y) at a body rate, px, shape (N, 2)."""
    b = sensor.unproject(x, y)
    half = Rotation.from_rotvec(np.asarray(rate_rad_s) * sensor.exposure_s / 2.0)
    xs, ys = sensor.project(half.apply(b))
    xe, ye = sensor.project(half.inv().apply(b))
    return np.column_stack([xe - xs, ye - ys])


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


def _capsule_centroids(image, x, y, seg, half: int, level, radius: float) -> tuple:
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


def _measured(axes) -> np.ndarray:
    """Return the streaks ``l`` (N, 2), px, sign unknown, whose ``l l^T`` are ``axes``."""
    length = np.sqrt(np.maximum(axes[:, 0, 0] + axes[:, 1, 1], 0.0))
    return np.linalg.eigh(axes)[1][:, :, -1] * length[:, None]


def _rate(sensor, x, y, axes) -> np.ndarray:
    """Return the body rate (up to sign) whose streaks fit ``l l^T`` of stars (x, y), rad/s.

    To first order in the angle turned during the exposure the streak is linear in the rate,
    ``l_i = A_i w`` (``A_i`` from the projection); each measured streak is ``+-l_i``, the sign
    unknown: the least-squares ``w`` is found for every choice of the signs (the first fixed)
    and the best kept.
    """
    eps = 1e-6 / sensor.exposure_s  # a turn of 1 microradian over the exposure
    a = np.stack([_streaks(sensor, x, y, eps * e) / eps for e in np.eye(3)], axis=2)
    meas = _measured(axes)
    a2 = a.reshape(-1, 3)
    best, rate = math.inf, np.zeros(3)
    for signs in itertools.product((1.0, -1.0), repeat=len(x) - 1):
        rhs = (meas * np.array([1.0, *signs])[:, None]).ravel()
        w = np.linalg.lstsq(a2, rhs, rcond=None)[0]
        cost = float(np.sum((a2 @ w - rhs) ** 2))
        if cost < best:
            best, rate = cost, w
    return rate


def _streak_model(sensor, image, x, y, order, **measure):
    """Return the streaks of stars (x, y) -> (N, 2) px from the brightest ones, or None.

    None when fewer than 3 streaks are measured or they are short (module docstring): the
    longest the fitted rate draws decides, as the datasheet's prediction does on the true ones.
    """
    sigma = sensor.detector.psf_sigma_px
    use = order[: 3 * N_RATE_STARS]
    half = math.ceil(0.5 * float(np.max(measure.pop("extent_px")[use])) + 3.0 * sigma + 4.0)
    shortest = MIN_STREAK_SIGMAS * sigma + 2.0 * measure.pop("margin_px")
    # a faint streak's pieces (gaps where the noise took its ridge below the threshold) join
    measure["bridge_px"] = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX
    # the brightest streaks first: where they measure short of half the shortest the frame is
    # at rest, and the other windows are not read (it pays for N_RATE_STARS windows only)
    bright = use[:N_RATE_STARS]
    first = streak_axes(image, x[bright], y[bright], half_px=half, **measure)
    first2 = first[:, 0, 0] + first[:, 1, 1]
    first2, screen = first2[np.isfinite(first2)], 0.5 * shortest
    if len(first2) == 0 or np.median(first2) < screen**2:
        return None
    rest = streak_axes(image, x[use[N_RATE_STARS:]], y[use[N_RATE_STARS:]], half_px=half, **measure)
    axes = np.concatenate([first, rest])
    length2 = axes[:, 0, 0] + axes[:, 1, 1]  # |l|^2
    ok = np.flatnonzero(np.isfinite(length2))
    if len(ok) < 3:
        return None
    # the rate: the streaks within SYSTEMATIC of the reference one (_confirmed), longest first
    ok = ok[np.argsort(-length2[ok], kind="stable")]
    if np.median(length2[ok[:N_RATE_STARS]]) < screen**2:
        return None
    low = (1.0 - SYSTEMATIC) ** 2
    top = _confirmed(axes[ok], length2[ok], low, 2.0 * sigma + 1.0, ok < N_RATE_STARS)
    typical2 = float(length2[ok[top]])
    ok = ok[top:][length2[ok[top:]] >= low * typical2]
    ok = ok[np.argsort(-length2[ok], kind="stable")][:N_RATE_STARS]
    if len(ok) < 3:  # one or two whole streaks (or a blend): the brightest measured decide
        if np.median(first2) < shortest**2:
            return None
        m = axes[ok].sum(axis=0)
        vec = np.linalg.eigh(m)[1][:, -1] * math.sqrt(float(np.trace(m)) / len(ok))
        model = lambda xs, _ys: np.broadcast_to(vec, (len(xs), 2))  # noqa: E731
    else:
        rate = _consensus_rate(sensor, x[use[ok]], y[use[ok]], axes[ok], math.sqrt(typical2))
        model = lambda xs, ys: _streaks(sensor, xs, ys, rate)  # noqa: E731
    drawn = model(x, y)
    if float(np.max(np.hypot(drawn[:, 0], drawn[:, 1]))) < shortest:
        return None
    return model


def _confirmed(axes, length2, low: float, width_px: float, bright) -> int:
    """Return the reference streak of :func:`_streak_model` (index into length-sorted ones).

    Candidates: the streaks at least half as long as the longest of the brightest (``bright``)
    that another confirms (shorter within ``low``, turned within the angle ``width_px``
    spans); a blend is seldom confirmed, and collinear pieces bridged end to end can blend
    several streaks. Of those, the one the most of the brightest measure as long as (to
    ``width_px``: a bright streak is whole), then the one the most of them confirm, then the
    most of all (pieces of faint streaks broken alike can outnumber the whole ones).
    """
    direction = np.linalg.eigh(axes)[1][:, :, -1]
    length = np.sqrt(length2)
    across = np.abs(direction @ np.column_stack([-direction[:, 1], direction[:, 0]]).T)
    with np.errstate(divide="ignore"):  # a streak of no length: nothing is turned from it
        turned = across > width_px / length[None, :]  # [j, i]: streak j turned from streak i
    alike = (np.abs(length[:, None] - length[None, :]) <= width_px) & ~turned
    within = (length2[:, None] >= low * length2[None, :]) & (length2[:, None] <= length2[None, :])
    within &= ~turned & ~np.eye(len(length), dtype=bool)  # [j, i]: j confirms i
    held = np.asarray(bright, dtype=bool) & within.any(axis=0)
    longest = float(length[held].max()) if held.any() else float(length[0])
    n = len(length2) + 1
    support = np.full(len(length2), -1, dtype=np.int64)
    for i in np.flatnonzero(length >= 0.5 * longest):
        near = (length2 >= low * length2[i]) & (length2 <= length2[i]) & ~turned[:, i]
        support[i] = n * n * np.count_nonzero(alike[:, i] & bright)
        support[i] += n * np.count_nonzero(near & bright) + np.count_nonzero(near)
    return int(np.argmax(support))


def _consensus_rate(sensor, x, y, axes, typical_px: float) -> np.ndarray:
    """Return the rate of :func:`_rate`, refitted without the streaks it does not predict.

    A streak farther from the fitted one (either sign) than the lit pixels' shortfall
    (``SYSTEMATIC`` of the typical streak) plus 2 PSF sigmas is a blend whose direction the
    length window did not catch: the worst is dropped and the rate refitted, while 3 remain.
    """
    keep = np.arange(len(x))
    tol = SYSTEMATIC * typical_px + 2.0 * sensor.detector.psf_sigma_px
    while True:
        rate = _rate(sensor, x[keep], y[keep], axes[keep])
        if len(keep) <= 3:
            return rate
        model = _streaks(sensor, x[keep], y[keep], rate)
        meas = _measured(axes[keep])
        miss = np.minimum(np.hypot(*(meas - model).T), np.hypot(*(meas + model).T))
        worst = int(np.argmax(miss))
        if miss[worst] <= tol:
            return rate
        keep = np.delete(keep, worst)


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
    StreakCentroids or None
        None when the frame is not smeared (streaks shorter than ``MIN_STREAK_SIGMAS`` PSF
        sigmas) or its rate cannot be measured (fewer than 3 measured streaks): the
        detections' centroids stand.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    x, y = xy[:, 0].copy(), xy[:, 1].copy()
    counts = np.asarray(counts, dtype=float)
    if len(x) < 3:
        return None
    order = np.argsort(-counts, kind="stable")
    model = _streak_model(
        sensor,
        image,
        x,
        y,
        order,
        extent_px=np.asarray(extent_px, dtype=float),
        level=level,
        threshold=threshold,
        threshold_sigma=threshold_sigma,
        margin_px=margin_px,
    )
    if model is None:
        return None
    det = sensor.detector
    sigma = det.psf_sigma_px
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX  # the tracking windows' capsule
    streaks = model(x, y)
    rows, cols = image.shape
    seg = streaks * (1.0 + SYSTEMATIC)
    half = math.ceil(float(np.hypot(seg[:, 0], seg[:, 1]).max()) + radius + 2.0)
    gx, gy, total, _, spread, r0, c0 = _capsule_centroids(image, x, y, seg, half, level, radius)
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
    streaks : StreakCentroids or None
        The streak centroids (their streaks, px, capsule sums and clipping), None where the
        detections' centroids stand.
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
    known = solver.settings.background == "known"
    box = det.bbox[matched]
    got = streak_centroids_of(
        sensor,
        image,
        np.column_stack([det.x[matched], det.y[matched]]),
        counts=det.integrated_counts[matched],
        extent_px=np.maximum(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]),
        level=float(sensor.detector.bias_counts) if known else None,
        threshold=solver.logic.lit_pixel_counts,
        threshold_sigma=None if known else solver.settings.threshold_sigma,
        margin_px=solver.detector.margin_px,
    )
    if got is None:
        return vectors, sigma, None
    own = got.sigma_px
    sigma = own if fixed == "snr" else np.maximum(own, fixed)
    return sensor.unproject(got.x, got.y), sigma, got


def streak_body_rate(sensor, cam, streaks_px) -> np.ndarray:
    """Return the body rate (rad/s, camera frame) whose streaks fit ``streaks_px`` (N, 2).

    The streaks the solver centroided over come from one rate, their signs consistent; to first
    order they are linear in it (``l_i = A_i w``, ``A_i`` the projection's), the least-squares
    ``w`` their rate, up to the sign every streak shares (the forward model of a streak is even
    in it). ``cam`` (N, 3): the stars, camera frame.
    """
    n = len(cam)
    eps = 1e-6  # a turn of 1 microradian over the exposure
    turns = np.concatenate([[0.5 * eps * e, -0.5 * eps * e] for e in np.eye(3)])  # (6, 3)
    x, y = sensor.project(np.concatenate([Rotation.from_rotvec(t).apply(cam) for t in turns]))
    x, y = x.reshape(6, n), y.reshape(6, n)
    cols = [np.column_stack([x[2 * k + 1] - x[2 * k], y[2 * k + 1] - y[2 * k]]) for k in range(3)]
    a = np.column_stack([c.ravel() for c in cols]) / (eps / sensor.exposure_s)
    return np.linalg.lstsq(a, np.ravel(streaks_px), rcond=None)[0]
