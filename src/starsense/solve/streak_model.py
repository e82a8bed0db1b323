"""The body rate of a smeared frame, from the streaks of its brightest matched stars.

At a body rate ``w`` a star draws a streak ``l`` during the exposure; to first order in the angle
turned it is linear in the rate, ``l_i = A_i w`` (the model of
:mod:`~starsense.solve.tracking.streak_rate`). :func:`streak_model` measures the streaks of the
brightest matched stars (the second moments of their lit pixels,
:func:`starsense.detect.streak.streak_axes`, the collinear pieces of a faint streak broken by the
noise bridged into it) and fits the rate, up to its sign, to the longest whole ones, solved for
every choice of the streaks' unknown signs: a piece of a streak is shorter than the streak and a
blend of two streaks longer (at most twice) or turned, so the reference is the streak the most
others confirm (as long within the lit pixels' shortfall, ``SYSTEMATIC``, and as turned within
the PSF's width), counting the brightest ``N_RATE_STARS`` first (a bright streak is whole; the
pieces of faint ones, broken alike where their ridges cross the pixel rows, can outnumber
them), of those at least half as long as the longest; only streaks within that shortfall of it
take part, and a streak the fitted rate does not predict is dropped and the rate refitted (with
fewer than 3 of them, their mean streak stands for every star's). A frame whose streaks, as the
fitted rate draws them, are all shorter than 2 PSF sigmas plus the centroid margin on each side
is taken as at rest.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.detect.adaptive_moments import adaptive_axes
from starsense.detect.streak import SYSTEMATIC, streak_axes
from starsense.model.psf import psf_of

__all__ = [
    "CAPSULE_PAD_PX",
    "CAPSULE_SIGMAS",
    "MIN_STREAK_SIGMAS",
    "N_RATE_STARS",
    "less_psf",
    "streak_body_rate",
    "streak_model",
    "streaks_at",
]

#: a frame whose measured streaks are shorter than this many PSF sigmas (plus the centroid
#: window's margins) is not re-centroided
MIN_STREAK_SIGMAS = 2.0
#: the capsule each streak is centroided over: within CAPSULE_SIGMAS PSF sigmas plus
#: CAPSULE_PAD_PX px of the streak (the tracking windows' capsule)
CAPSULE_SIGMAS, CAPSULE_PAD_PX = 2.5, 1.0
#: the brightest matched stars whose streaks give the rate (a faint streak breaks into pieces)
N_RATE_STARS = 5


def streaks_at(sensor, x, y, *, rate_rad_s) -> np.ndarray:
    """Streak (start to end) of the stars at (x, y) at a body rate, px, shape (N, 2)."""
    b = sensor.unproject(x, y)
    half = Rotation.from_rotvec(np.asarray(rate_rad_s) * sensor.exposure_s / 2.0)
    xs, ys = sensor.project(half.apply(b))
    xe, ye = sensor.project(half.inv().apply(b))
    return np.column_stack([xe - xs, ye - ys])


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
    a = np.stack([streaks_at(sensor, x, y, rate_rad_s=eps * e) / eps for e in np.eye(3)], axis=2)
    meas = _measured(axes)
    a2 = a.reshape(-1, 3)
    signs = np.array([(1.0, *c) for c in itertools.product((1.0, -1.0), repeat=len(x) - 1)])
    rhs = (signs[:, :, None] * meas[None, :, :]).reshape(len(signs), -1)  # (choices, 2N)
    w = rhs @ np.linalg.pinv(a2).T  # every choice's least squares at once
    cost = np.sum((w @ a2.T - rhs) ** 2, axis=1)
    return w[int(np.argmin(cost))]


def streak_model(sensor, image, xy, *, order, counts=None, **measure):
    """Return the streaks of stars ``xy = (x, y)`` -> (N, 2) px, and the rate they suggest.

    Returns ``(model, rate)``: ``model`` the streaks from the brightest ones, or None when
    fewer than 3 streaks are measured or they are short (module docstring: the longest the
    fitted rate draws decides, as the datasheet's prediction does on the true ones); ``rate``
    (3,), camera frame, rad/s, up to its sign: the rate the model draws, or, where the streaks
    are too short to re-centroid, the rate the brightest ones' measured streaks suggest (where
    at least 3 were measured; else None), which starts the forward model's fit of the rate
    when the frame at rest does not fit (:mod:`starsense.solve.refine`).
    ``counts``: the stars' lit sums; with them, a sensor whose PSF is not a Gaussian has the
    elongation its own PSF shows at rest taken out of each measured streak (:func:`less_psf`).
    """
    x, y = xy
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
    if counts is not None and not sensor.psf.is_gaussian:  # an elongated PSF is no streak
        first = less_psf(first, _psf_axes(sensor, (x, y), counts, bright, half, measure))
    first2 = first[:, 0, 0] + first[:, 1, 1]
    measured = np.isfinite(first2)
    hint = None  # the rate the brightest streaks suggest, however short
    if np.count_nonzero(measured) >= 3:
        hint = _rate(sensor, x[bright][measured], y[bright][measured], first[measured])
    else:  # too faint to light their streaks: their weighted moments suggest it
        hint = _faint_hint(sensor, image, (x[bright], y[bright]), half, measure.get("level"))
    first2, screen = first2[measured], 0.5 * shortest
    if len(first2) == 0 or np.median(first2) < screen**2:
        return None, hint
    rest = streak_axes(image, x[use[N_RATE_STARS:]], y[use[N_RATE_STARS:]], half_px=half, **measure)
    if counts is not None and not sensor.psf.is_gaussian:
        rest = less_psf(rest, _psf_axes(sensor, (x, y), counts, use[N_RATE_STARS:], half, measure))
    axes = np.concatenate([first, rest])
    length2 = axes[:, 0, 0] + axes[:, 1, 1]  # |l|^2
    ok = np.flatnonzero(np.isfinite(length2))
    if len(ok) < 3:
        return None, hint
    # the rate: the streaks within SYSTEMATIC of the reference one (_confirmed), longest first
    ok = ok[np.argsort(-length2[ok], kind="stable")]
    if np.median(length2[ok[:N_RATE_STARS]]) < screen**2:
        return None, hint
    low = (1.0 - SYSTEMATIC) ** 2
    top = _confirmed(axes[ok], length2[ok], low, 2.0 * sigma + 1.0, ok < N_RATE_STARS)
    typical2 = float(length2[ok[top]])
    ok = ok[top:][length2[ok[top:]] >= low * typical2]
    ok = ok[np.argsort(-length2[ok], kind="stable")][:N_RATE_STARS]
    if len(ok) < 3:  # one or two whole streaks (or a blend): the brightest measured decide
        if np.median(first2) < shortest**2:
            return None, hint
        m = axes[ok].sum(axis=0)
        vec = np.linalg.eigh(m)[1][:, -1] * math.sqrt(float(np.trace(m)) / len(ok))
        model = lambda xs, _ys: np.broadcast_to(vec, (len(xs), 2))  # noqa: E731
    else:
        hint = _consensus_rate(sensor, x[use[ok]], y[use[ok]], axes[ok], math.sqrt(typical2))
        model = functools.partial(_streaks_of, sensor, hint)
    drawn = model(x, y)
    if float(np.max(np.hypot(drawn[:, 0], drawn[:, 1]))) < shortest:
        return None, hint
    return model, hint


def _faint_hint(sensor, image, xy, half: int, level) -> np.ndarray | None:
    """Return the rate the adaptive moments of stars ``xy`` suggest (at least 3), or None.

    :func:`starsense.detect.adaptive_moments.adaptive_axes`, less what the sensor's PSF shows
    on its own at each star's phase (:func:`_psf_adaptive`; a round PSF shows nothing).
    """
    x, y = xy
    axes = adaptive_axes(
        image, x, y, half_px=half, start_sigma_px=psf_of(sensor).sigma_px, level=level
    )
    if not sensor.psf.is_gaussian:
        axes = less_psf(axes, _psf_adaptive(sensor, xy, half))
    ok = np.isfinite(axes).all(axis=(1, 2))
    if np.count_nonzero(ok) < 3:
        return None
    return _rate(sensor, x[ok], y[ok], axes[ok])


def _psf_adaptive(sensor, xy, half: int) -> np.ndarray:
    """Return :func:`adaptive_axes` of the sensor's PSF alone at stars ``xy``' phases."""
    psf = psf_of(sensor)
    fx, fy = (np.asarray(v, float) - np.round(v) for v in xy)
    side = 2 * half + 1
    tmpl = psf.grid(-half - fx, -half - fy, (side, side), gradient=False)  # (K, rows, columns)
    strip = np.concatenate(list(tmpl), axis=1)  # the stars side by side, each in its window
    return adaptive_axes(
        strip,
        half + fx + side * np.arange(len(fx)),
        half + fy,
        half_px=half,
        start_sigma_px=psf.sigma_px,
        level=0.0,
    )


def _streaks_of(sensor, rate, xs, ys) -> np.ndarray:
    """Return the streaks of stars (xs, ys) at body rate ``rate``, px (N, 2)."""
    return streaks_at(sensor, xs, ys, rate_rad_s=rate)


def less_psf(axes, rest) -> np.ndarray:
    """Return the streaks ``l l^T`` (N, 2, 2) of ``axes`` less the elongation ``rest`` at rest.

    An astigmatic or coma-shaped PSF is elongated at rest, and :func:`~starsense.detect.streak.
    streak_axes` reads the anisotropy of a star's second moments: that of the PSF adds to the
    streak's. Both enter the moments' trace-free part linearly, so the streak is the
    anisotropy (larger less smaller eigenvalue, along the larger's axis) of the difference; a
    star whose elongation its PSF explains measures a streak of zero length.
    """
    d = np.where(np.isfinite(rest), axes - rest, axes)
    bad = ~np.isfinite(d).all(axis=(1, 2))
    lam, vec = np.linalg.eigh(np.where(bad[:, None, None], 0.0, d))
    e = vec[:, :, 1]
    out = (lam[:, 1] - lam[:, 0])[:, None, None] * (e[:, :, None] * e[:, None, :])
    out[bad] = np.nan
    return out


def _psf_axes(sensor, xy, counts, which, half: int, measure: dict) -> np.ndarray:
    """Return what :func:`streak_axes` reads on stars ``which`` at rest, noise-free (K, 2, 2).

    Each star is the sensor's pixel-integrated PSF (:func:`starsense.model.psf.psf_of`) at its
    sub-pixel phase, scaled so that its lit pixels (above the measure's threshold) sum to its
    lit sum ``counts``, and measured with the same threshold and bridge.
    """
    psf = psf_of(sensor)
    x, y = (np.asarray(v, float)[which] for v in xy)
    lit_sum = np.asarray(counts, float)[which]
    thr = float(measure.get("threshold", 0.0))
    ar = np.arange(-half, half + 1, dtype=float)
    fx, fy = x - np.round(x), y - np.round(y)
    side = len(ar)
    tmpl = psf.grid(ar[0] - fx, ar[0] - fy, (side, side), gradient=False)  # (K, rows, columns)
    scale = lit_sum.copy()  # counts per unit of light: the lit fraction, found in two passes
    for _ in range(2):
        lit = tmpl * scale[:, None, None] > thr
        frac = np.where(lit, tmpl, 0.0).sum(axis=(1, 2))
        scale = np.where(frac > 0, lit_sum / np.where(frac > 0, frac, 1.0), lit_sum)
    w = 2 * half + 1
    strip = np.zeros((w, w * len(x)))  # the stars side by side, each in its own window
    for i in range(len(x)):
        strip[:, i * w : (i + 1) * w] = tmpl[i] * scale[i]
    kw = {k: v for k, v in measure.items() if k in ("threshold", "bridge_px")}
    return streak_axes(strip, half + fx + w * np.arange(len(x)), half + fy, half_px=half,
                       level=0.0, **kw)  # fmt: skip


def _confirmed(axes, length2, low: float, width_px: float, bright) -> int:
    """Return the reference streak of :func:`streak_model` (index into length-sorted ones).

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
        model = streaks_at(sensor, x[keep], y[keep], rate_rad_s=rate)
        meas = _measured(axes[keep])
        miss = np.minimum(np.hypot(*(meas - model).T), np.hypot(*(meas + model).T))
        worst = int(np.argmax(miss))
        if miss[worst] <= tol:
            return rate
        keep = np.delete(keep, worst)


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
