"""A faint star's elongation from its Gaussian-weighted (adaptive) second moments.

The lit-pixel moments of :func:`starsense.detect.streak.streak_axes` need a star whose pixels
stand above the threshold along its streak; a faint star spread wide (a wide field's large PSF,
smeared further by the body rate) may light fewer than three, and its streak goes unmeasured
while it is long enough to matter. Weighted by a Gaussian matched to the image, the moments
use every pixel of the star at the weight its signal earns (the adaptive moments of
Bernstein & Jarvis 2002, AJ 123, 583, as GalSim's ``FindAdaptiveMom`` computes them): the
weight's covariance ``W`` is iterated to the image's own ``C``, which for a Gaussian image
follows from the weighted moments ``m`` as ``C = (m^-1 - W^-1)^-1`` (``C = 2 m`` at the fixed
point). The anisotropy ``12 (lambda_1 - lambda_2)`` of ``C`` is then ``l l^T`` of a streak
``l`` drawn on a round PSF (its variance along the streak grows by ``|l|^2 / 12``, the round
part cancels in the difference): approximate for a PSF with wings, enough to start the forward
model's fit of the body rate, which decides.
"""

from __future__ import annotations

import numpy as np

from starsense.detect.row_stats import row_nanmedian

__all__ = ["adaptive_axes"]

#: the most iterations of the weight (it settles to 1e-3 of a pixel^2 in under ten on a
#: star of SNR 20)
MAX_ITERATIONS = 30


def adaptive_axes(image, x, y, *, half_px: int, start_sigma_px: float, level=None) -> np.ndarray:
    """Return ``l l^T`` (N, 2, 2), px^2, of the streak through each star, adaptive moments.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame, counts.
    x, y : array_like, shape (N,)
        The stars' centroids, px (x = column).
    half_px : int
        Half-width of the square window about each star, px.
    start_sigma_px : float
        The first weight's sigma (the PSF's), px.
    level : float, optional
        Background level, counts; None: the median of each window's border.

    Returns
    -------
    ndarray, shape (N, 2, 2)
        NaN where the weighted light is not positive or the moments are not those of an image
        (a window off the frame, noise alone).
    """
    a = np.asarray(image)
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    out = np.full((len(x), 2, 2), np.nan)
    if len(x) == 0:
        return out
    ar = np.arange(-half_px, half_px + 1)
    r0, c0 = np.round(y).astype(np.int64), np.round(x).astype(np.int64)
    rr, cc = r0[:, None] + ar, c0[:, None] + ar
    on = ((rr >= 0) & (rr < a.shape[0]))[:, :, None] & ((cc >= 0) & (cc < a.shape[1]))[:, None, :]
    sub = a[np.clip(rr, 0, a.shape[0] - 1)[:, :, None], np.clip(cc, 0, a.shape[1] - 1)[:, None, :]]
    sub = np.where(on, sub.astype(float), np.nan)
    if level is None:  # a window whose border is off the frame: NaN, unmeasured
        border = np.concatenate([sub[:, 0], sub[:, -1], sub[:, :, 0], sub[:, :, -1]], axis=1)
        sub = sub - row_nanmedian(border)[:, None, None]
    else:
        sub = sub - float(level)
    sub = np.nan_to_num(sub, nan=0.0)
    dx0 = ar[None, None, :] - (x - c0)[:, None, None]  # (N, 1, w): column offsets
    dy0 = ar[None, :, None] - (y - r0)[:, None, None]  # (N, w, 1): row offsets
    cov = np.broadcast_to(np.eye(2) * float(start_sigma_px) ** 2, (len(x), 2, 2)).copy()
    shift = np.zeros((len(x), 2))
    good = np.ones(len(x), dtype=bool)
    for _ in range(MAX_ITERATIONS):
        dx, dy = dx0 - shift[:, 0, None, None], dy0 - shift[:, 1, None, None]
        inv = np.linalg.inv(cov)
        q = inv[:, 0, 0, None, None] * dx * dx + inv[:, 1, 1, None, None] * dy * dy
        q = q + 2.0 * inv[:, 0, 1, None, None] * dx * dy
        wi = np.exp(-0.5 * q) * sub
        tot = wi.sum(axis=(1, 2))
        good &= tot > 0.0
        t = np.where(good, tot, 1.0)
        mx, my = (wi * dx).sum(axis=(1, 2)) / t, (wi * dy).sum(axis=(1, 2)) / t
        mxx = (wi * dx * dx).sum(axis=(1, 2)) / t - mx * mx
        myy = (wi * dy * dy).sum(axis=(1, 2)) / t - my * my
        mxy = (wi * dx * dy).sum(axis=(1, 2)) / t - mx * my
        m = np.stack([np.stack([mxx, mxy], -1), np.stack([mxy, myy], -1)], -2)
        good &= (mxx > 0) & (myy > 0) & (mxx * myy > mxy * mxy)
        m = np.where(good[:, None, None], m, np.eye(2))
        # the image's covariance from the weighted moments (Gaussian image and weight)
        prec = np.linalg.inv(m) - inv
        good &= (prec[:, 0, 0] > 0) & (np.linalg.det(prec) > 0)
        new = np.linalg.inv(np.where(good[:, None, None], prec, np.eye(2)))
        shift = shift + np.column_stack([mx, my]) * good[:, None]
        settled = np.abs(new - cov).max(axis=(1, 2)) <= 1e-3
        cov = np.where(good[:, None, None], new, cov)
        if np.all(settled | ~good):
            break
    good &= np.all(np.abs(shift) <= half_px, axis=1)  # the weight stayed on its star
    lam, vec = np.linalg.eigh(cov[good])
    e = vec[:, :, 1]
    out[good] = 12.0 * (lam[:, 1] - lam[:, 0])[:, None, None] * (e[:, :, None] * e[:, None, :])
    return out
