"""Centroid error of a smeared star, derived from its pixels: the datasheet's NEA under slew.

At a body rate a star draws a streak ``l`` (px) during the exposure. The solver centroids the
matched stars of a smeared frame over a capsule of radius ``2.5 sigma + 1`` px around a segment
``(1 + SYSTEMATIC) l`` long, moved until it stays on its centre of gravity
(:mod:`starsense.solve.streaks`); a frame whose streaks are short keeps the detector's centre of
gravity over each lit box widened by its margin. This module predicts that centroid's error per
star from the sensor alone, the way :func:`starsense.analysis.datasheet.noise._one` does at
rest:

* the expected counts of each pixel: the renderer's streak (:func:`starsense.render.smear.
  streak_stamp_expected`: the PSF moving uniformly along ``l``) times the star's
  photo-electrons, plus the dark signal, times the gain, plus the bias; each pixel's variance:
  shot noise of star and dark signal, read noise and the ADC's 1/12 count^2, with the clipping
  at 0 and at the ADC's top count applied exactly (:func:`~starsense.analysis.datasheet.noise.
  clipped_moments`: saturation falls as the light spreads along the streak);
* the window: the capsule (or lit box) on the expected image, moved to the fixed point of its
  centre of gravity as the solver's is; pixels off the frame hold no light, so a streak cut by
  the frame's edge gives a centroid pulled inwards, a deterministic error (``bias_px``);
* the centre of gravity linearised in the pixel values over that window:
  ``C = sum_i (r_i - c)(r_i - c)^T var_i / S^2`` (``S`` the window's expected sum). Along the
  streak ``(r_i - c)`` spans the whole streak: the star's own shot noise gives
  ``(sigma^2 + l^2 / 12) / N`` along and ``sigma^2 / N`` across, and the window's longer side
  takes in more background and read noise per unit of signal;
* the covariance the solver assumes for the same centroid
  (:func:`starsense.solve.streaks.streak_cov_px2`, its read noise with the ADC's quantising,
  plus the clipped streak's error over its pixel phase where the expected ridge reaches the
  ADC's top, :func:`starsense.solve.streak_bias.saturated_streak_bias_px`, as the solver adds
  it), whose inverse trace weights the star in its attitude fit: a clipped streak weighted by
  its photon noise alone would carry its clipping's bias into the attitude many times over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from scipy.special import ndtr

from starsense.analysis.datasheet.noise import clipped_moments
from starsense.attitude.robust import OUTLIER_SIGMA
from starsense.detect.centroid import cog_sigma_px
from starsense.detect.streak import SYSTEMATIC
from starsense.render.smear import streak_stamp_expected
from starsense.solve.streak_bias import frame_clipped_bias_px
from starsense.solve.streaks import (
    CAPSULE_PAD_PX,
    CAPSULE_SIGMAS,
    MIN_STREAK_SIGMAS,
    streak_cov_px2,
)

__all__ = ["StreakErrors", "blend_cov_px2", "is_streaked", "streak_errors"]

#: iterations of the window's fixed point (the solver's :func:`starsense.detect.streak.
#: streak_centroids` stops at 6 or when it moves less than 0.01 px)
_ITERATIONS = 6


@dataclass(frozen=True)
class StreakErrors:
    """Predicted centroid errors of smeared stars (module docstring), px.

    Attributes
    ----------
    bias_px : ndarray (N, 2)
        The expected centroid less the star's mid-exposure position (x = column, y = row):
        non-zero for a streak cut by the frame's edge or clipped unevenly.
    cov_px2 : ndarray (N, 2, 2)
        The centroid's noise covariance, px^2.
    solver_cov_px2 : ndarray (N, 2, 2)
        The covariance the solver assumes, px^2 (its weight is ``2 / trace``).
    spread_px2 : ndarray (N, 2, 2)
        Sum over the window's pixels of (pixel - centroid)(pixel - centroid)^T over the square
        of the star's electrons, px^2 e^-2: a noise of variance ``v`` (e^2) in every pixel of
        the window adds ``v spread_px2`` to the covariance.
    """

    bias_px: np.ndarray
    cov_px2: np.ndarray
    solver_cov_px2: np.ndarray
    spread_px2: np.ndarray


def is_streaked(sensor, streak_px: float, margin_px: int = 2) -> bool:
    """Return whether the solver re-centroids a frame whose streaks are ``streak_px`` long.

    The solver keeps the detector's centroids when the streaks its fitted rate draws are all
    shorter than ``MIN_STREAK_SIGMAS`` PSF sigmas plus the centroid margin on each side
    (:mod:`starsense.solve.streaks`); here the longest true streak of the frame decides.
    """
    return streak_px >= MIN_STREAK_SIGMAS * sensor.detector.psf_sigma_px + 2.0 * margin_px


def _pixels(sensor, n_e: float, centre, streak, half: tuple[int, int]):
    """Return the expected counts less the bias, their variance, pixel grid, on-frame mask.

    Also the counts less the bias before the ADC clips them (the solver's test for a clipped
    ridge).
    """
    det = sensor.detector
    g = det.gain_counts_per_e
    x, y = float(centre[0]), float(centre[1])
    r0, c0 = math.floor(y) - half[0], math.floor(x) - half[1]
    shape = (2 * half[0] + 2, 2 * half[1] + 2)
    star = np.zeros(shape)
    sx, sy = 0.5 * float(streak[0]), 0.5 * float(streak[1])
    stamp, sr, sc = streak_stamp_expected(
        sensor, x0=x - sx, y0=y - sy, x1=x + sx, y1=y + sy, electrons=n_e
    )
    a, b = max(sr, r0), min(sr + stamp.shape[0], r0 + shape[0])
    c, d = max(sc, c0), min(sc + stamp.shape[1], c0 + shape[1])
    if a < b and c < d:
        star[a - r0 : b - r0, c - c0 : d - c0] = stamp[a - sr : b - sr, c - sc : d - sc]
    rows = np.arange(r0, r0 + shape[0], dtype=float)[:, None]
    cols = np.arange(c0, c0 + shape[1], dtype=float)[None, :]
    on = (rows >= 0) & (rows < det.rows) & (cols >= 0) & (cols < det.columns)
    star = np.where(on, star, 0.0)
    dark_e = det.dark_current_e_s * sensor.exposure_s
    mu = g * (star + dark_e) + det.bias_counts
    sd = np.sqrt(g * g * (star + dark_e + det.read_noise_e**2) + 1.0 / 12.0)
    mean, var = clipped_moments(mu, sd, lo=0.0, hi=float(det.saturation_counts))
    # the solver subtracts the known bias; the dark signal's mean is the background it leaves
    return mean - det.bias_counts, var, cols, rows, on, mu - det.bias_counts


def _capsule(cols, rows, centre, seg, radius: float) -> np.ndarray:
    """Pixels within ``radius`` of the segment ``seg`` centred on ``centre`` (the solver's)."""
    sx, sy = 0.5 * seg[0], 0.5 * seg[1]
    ax, ay = cols - (centre[0] - sx), rows - (centre[1] - sy)
    length2 = max(4.0 * (sx * sx + sy * sy), 1e-12)
    t = np.clip((ax * 2 * sx + ay * 2 * sy) / length2, 0.0, 1.0)
    return (ax - t * 2 * sx) ** 2 + (ay - t * 2 * sy) ** 2 <= radius * radius


def _lit_box(sub, on, lit: float, margin: int) -> np.ndarray:
    """Return the detector's window: the lit pixels' bounding box widened by its margin."""
    hit = (sub > lit) & on
    if not hit.any():
        return np.zeros_like(on)
    rr, cc = np.flatnonzero(hit.any(axis=1)), np.flatnonzero(hit.any(axis=0))
    box = np.zeros_like(on)
    box[
        max(rr[0] - margin, 0) : rr[-1] + margin + 1, max(cc[0] - margin, 0) : cc[-1] + margin + 1
    ] = 1
    return box & on


def _one(sensor, n_e: float, centre, streak, capsule: bool, margin: int):
    """Bias (2,), covariance (2, 2), solver covariance (2, 2) of one star, px."""
    det = sensor.detector
    sigma = det.psf_sigma_px
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX
    seg = np.asarray(streak, dtype=float) * (1.0 + SYSTEMATIC)
    pad = radius + 5.0 * sigma + margin + 3.0
    half = (math.ceil(0.5 * abs(seg[1]) + pad), math.ceil(0.5 * abs(seg[0]) + pad))
    sub, var, cols, rows, on, raw = _pixels(sensor, n_e, centre, streak, half)
    nan = np.full(2, np.nan), *np.full((3, 2, 2), np.nan), np.nan
    clipped_e = np.nan  # the electrons of a clipped streak's window (the solver's measure)
    c = np.asarray(centre, dtype=float)
    if capsule:
        for _ in range(_ITERATIONS):  # the solver's fixed point, on the expected image
            win = _capsule(cols, rows, c, seg, radius) & on
            s = float(np.sum(sub[win]))
            if not s > 0:
                return nan
            new = np.array([np.sum((sub * cols)[win]), np.sum((sub * rows)[win])]) / s
            moved = float(np.hypot(*(new - c)))
            c = new
            if moved < 0.01:
                break
    else:
        win = _lit_box(sub, on, sensor.detection.lit_pixel_counts, margin)
        s = float(np.sum(sub[win]))
        if not s > 0:
            return nan
        c = np.array([np.sum((sub * cols)[win]), np.sum((sub * rows)[win])]) / s
    dx = np.broadcast_to(cols - c[0], win.shape)[win]
    dy = np.broadcast_to(rows - c[1], win.shape)[win]
    v = var[win]
    cov = np.array([[v @ (dx * dx), v @ (dx * dy)], [v @ (dx * dy), v @ (dy * dy)]]) / s**2
    g = det.gain_counts_per_e
    spread = np.array([[dx @ dx, dx @ dy], [dx @ dy, dy @ dy]])
    if capsule:
        # the fixed point: a window moved by d moves the centroid of the background's mean
        # in it (a pedestal where the ADC clips the noise at 0) by d too, so the noise's pull
        # is divided by the star's light alone, not the window's sum
        pedestal = float(_pixels(sensor, 0.0, centre, (0.0, 0.0), (0, 0))[0][0, 0])
        star = s - max(pedestal, 0.0) * int(np.sum(win))
        cov = cov * (s / star) ** 2 if star > 0 else np.full((2, 2), np.inf)
        total, s = s, star  # the window's sum (the solver's N), the light pulls divide by
        hx, hy = 0.5 * abs(streak[0]) + radius, 0.5 * abs(streak[1]) + radius
        whole = hx <= c[0] <= det.columns - 1 - hx and hy <= c[1] <= det.rows - 1 - hy
        solver = streak_cov_px2(
            [total / g],
            spread[None],
            np.asarray(streak, dtype=float)[None],
            whole=[whole],
            sigma_px=sigma,
            read_noise_e=math.hypot(det.read_noise_e, 1.0 / (math.sqrt(12.0) * g)),
        )[0]
        if np.max(raw[win]) >= det.clip_e * g - 0.5:  # a clipped ridge, as the solver sees it
            clipped_e = total / g
    else:  # the detector's own noise model on the lit box (cog_sigma_px)
        lit = (sub > sensor.detection.lit_pixel_counts) & on
        rr, cc = np.flatnonzero(lit.any(axis=1)), np.flatnonzero(lit.any(axis=0))
        found = SimpleNamespace(
            integrated_counts=np.array([float(np.sum(sub[lit]))]),
            bbox=np.array([[rr[0], rr[-1] + 1, cc[0], cc[-1] + 1]]),
            noise_counts=0.0,  # the detector's own read noise (a frame of known background)
        )
        sig = float(cog_sigma_px(found, [0], detector=det, margin_px=margin)[0])
        solver = sig * sig * np.eye(2)
    return c - np.asarray(centre, dtype=float), cov, solver, spread * (g / s) ** 2, clipped_e


def _add_clipping(sensor, solver, clipped_e, streaks, frames) -> None:
    """In place: the solver's clipped-streak term in ``solver`` (N, 2, 2), one call per frame.

    As :func:`starsense.solve.streaks.streak_centroids_of` does: the frame's clipped stars
    share one streak (their mean, signs aligned) and their capsule sums set their brightness.
    """
    sigma = sensor.detector.psf_sigma_px
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX
    hit = np.flatnonzero(np.isfinite(clipped_e))
    for f in np.unique(frames[hit]):
        at = hit[frames[hit] == f]
        bias = frame_clipped_bias_px(
            streaks[at], clipped_e[at], sigma_px=sigma, saturation_e=sensor.detector.clip_e,
            radius_px=radius,
        )  # fmt: skip
        solver[at] += (bias**2)[:, None, None] * np.eye(2)


def streak_errors(
    sensor,
    electrons,
    centres_px,
    *,
    streaks_px,
    capsule: bool = True,
    margin_px: int = 2,
    frames=None,
) -> StreakErrors:
    """Return the predicted centroid errors of smeared stars (module docstring).

    Parameters
    ----------
    sensor : Sensor
        Detector (noise, ADC, PSF sigma), exposure and detection logic.
    electrons : array_like (N,)
        Photo-electrons of each star over the exposure.
    centres_px : array_like (N, 2)
        Mid-exposure positions on the detector (x = column, y = row), px.
    streaks_px : array_like (N, 2)
        Streaks, start to end, px.
    capsule : bool
        The solver's window over the whole streak (a smeared frame); False: the detector's
        lit box widened by ``margin_px`` (a frame whose streaks are short, :func:`is_streaked`).
    margin_px : int
        The detector's centroid margin, px.
    frames : array_like (N,) of int, optional
        The frame of each star: a frame's clipped streaks share the solver's one clipped-streak
        error call (their mean streak). None: each star its own frame.

    Returns
    -------
    StreakErrors
        NaN rows for stars whose window holds no light.
    """
    e = np.atleast_1d(np.asarray(electrons, dtype=float))
    xy = np.asarray(centres_px, dtype=float).reshape(-1, 2)
    ls = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    out = [_one(sensor, float(e[i]), xy[i], ls[i], capsule, int(margin_px)) for i in range(len(e))]
    if not out:
        return StreakErrors(np.zeros((0, 2)), *np.zeros((3, 0, 2, 2)))
    bias, cov, solver, spread, clipped_e = (np.array(z) for z in zip(*out, strict=True))
    frames = np.arange(len(e)) if frames is None else np.asarray(frames).reshape(len(e))
    _add_clipping(sensor, solver, clipped_e, ls, frames)
    return StreakErrors(bias, cov, solver, spread)


#: offsets of a neighbour along and across the streak at which its pull is summed
_BLEND_ALONG, _BLEND_ACROSS = 161, 41


def blend_cov_px2(electrons, streak_px, solver_sigma_px: float, *, sigma_px: float, neighbours):
    """Return the covariance of a streak centroid from the catalogue's other stars, px^2.

    Under slew every star of the field is a streak parallel to the target's, as long, and the
    target's capsule (``(1 + SYSTEMATIC) l`` long, ``2.5 sigma + 1`` px half-wide) takes in
    the part of any neighbour's streak that overlaps it, fainter or brighter: a neighbour of
    ``f`` electrons at offset ``(u, v)`` (along, across) puts ``f_in = f f_u f_v`` in the
    window (``f_u`` the overlap of the two segments over ``l``, ``f_v`` its PSF's share of the
    window's width) at the centre ``c_n`` of that overlap, and moves the fixed point of the
    centre of gravity by ``f_in c_n / (N + f_in)`` (along, grown by the window's own move
    where its ends cut the neighbour's streak). Over a Poisson field of neighbours (the
    catalogue's sky-mean density per class) the pulls add in variance: ``sum_k rho_k
    integral of pull pull^T du dv``. A pull of more than ``OUTLIER_SIGMA`` of the solver's
    sigma for the star is left out: the robust fit drops that star
    (:func:`starsense.attitude.robust.robust_attitude`).

    Parameters
    ----------
    electrons : float
        The target's photo-electrons.
    streak_px : array_like (2,)
        Its streak, px.
    solver_sigma_px : float
        The sigma the solver assumes for it, px per axis.
    sigma_px : float
        PSF sigma, px.
    neighbours : (ndarray, ndarray[, ndarray])
        Photo-electrons (B,) and density (B,), px^-2, of the catalogue's classes, and (B,)
        1 for a class the solver does not model (its whole pull), or the relative error of
        the flux ratio it models the class with (default all 1).

    Returns
    -------
    ndarray (2, 2)
        px^2 (x = column, y = row).
    """
    flux, rho, *share = (np.asarray(a, dtype=float) for a in neighbours)
    share = share[0] if share else np.ones(len(flux))
    use = rho > 0
    flux, rho, share = flux[use, None, None], rho[use, None, None], share[use, None, None]
    streak = np.asarray(streak_px, dtype=float)
    length = float(np.hypot(*streak))
    radius = CAPSULE_SIGMAS * sigma_px + CAPSULE_PAD_PX
    # the capsule as a rectangle of its area: half-length (1 + S) l / 2 + pi R / 4
    half_w = 0.5 * (1.0 + SYSTEMATIC) * length + 0.25 * math.pi * radius
    reach_u = half_w + 0.5 * length
    reach_v = radius + 4.0 * sigma_px
    u = np.linspace(-reach_u, reach_u, _BLEND_ALONG)[None, None, :]
    v = np.linspace(-reach_v, reach_v, _BLEND_ACROSS)[None, :, None]
    cell = (u[0, 0, 1] - u[0, 0, 0]) * (v[0, 1, 0] - v[0, 0, 0])
    lo, hi = np.maximum(u - 0.5 * length, -half_w), np.minimum(u + 0.5 * length, half_w)
    f_u = np.where(
        length > 1e-9, np.clip(hi - lo, 0.0, None) / max(length, 1e-9), np.abs(u) <= half_w
    )
    a, b = (-radius - v) / sigma_px, (radius - v) / sigma_px
    f_v = ndtr(b) - ndtr(a)
    c_v = v + sigma_px * (np.exp(-0.5 * a * a) - np.exp(-0.5 * b * b)) / (
        math.sqrt(2.0 * math.pi) * np.maximum(f_v, 1e-300)
    )
    f_in = flux * f_u * f_v
    frac = f_in / (float(electrons) + f_in)
    # the fixed point: a window moved by d along gains (loses) the neighbour's light at its
    # ends where they lie on the neighbour's streak, d f f_v / l at +-half_w each, which
    # moves its centre of gravity by J d: the pull grows by 1 / (1 - J) (J >= 1: the window
    # runs off with the neighbour, an outlier)
    ends = (np.abs(half_w - u) < 0.5 * length).astype(float)
    ends += np.abs(-half_w - u) < 0.5 * length
    gain = flux * f_v / max(length, 1e-9) * half_w * ends / (float(electrons) + f_in)
    held = gain < 1.0
    pull_u = np.where(held, frac * 0.5 * (lo + hi) / np.where(held, 1.0 - gain, 1.0), np.inf)
    pull_u = np.where(frac > 0, pull_u, 0.0)
    pull_v = frac * c_v
    # the part of each pull the solver's model leaves: all of it, or, modelled from fluxes
    # with a relative error e, e d(share of light)/d(ln f) / share = e N / (N + f_in) of it
    left = np.where(share < 1.0, share * (1.0 - frac), 1.0)
    pull_u, pull_v = left * pull_u, left * pull_v
    kept = np.hypot(pull_u, pull_v) <= OUTLIER_SIGMA * solver_sigma_px
    pull_u = np.where(kept, pull_u, 0.0)
    w = rho * cell * kept
    uu, vv, uv = (
        float(np.sum(w * p * q)) for p, q in ((pull_u, pull_u), (pull_v, pull_v), (pull_u, pull_v))
    )
    cov_uv = np.array([[uu, uv], [uv, vv]])
    d = streak / length if length > 1e-9 else np.array([1.0, 0.0])
    rot = np.array([[d[0], -d[1]], [d[1], d[0]]])  # columns: along, across
    return rot @ cov_uv @ rot.T
