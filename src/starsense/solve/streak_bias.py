"""The centroid error of a saturated streak over where it falls on the pixel grid.

A streak whose ridge is clipped (full well or the ADC's top) loses light where the ridge runs
through the middle of a pixel row or column and keeps it where it runs between two: the light
lost is not spread evenly along the streak, and the centroid over its capsule moves along and
across it by an amount that depends on the streak's sub-pixel phase. A frame meets each star at
a random phase, so to the attitude fit this is a per-star error like the noise; left out, the
brightest stars of a slewing frame (the smallest photon noise) pull the attitude by several of
their sigmas (0.05-0.2 px against 0.03 px on a random 8-bit design at 1 deg/s).

:func:`saturated_streak_bias_px` is its rms over phases: the frame's streak rendered noise-free
(pixel-integrated Gaussians along it) at ``N_PHASE`` x ``N_PHASE`` sub-pixel offsets and
brightnesses from the onset of clipping to far past it, clipped, centroided over the capsule
around the true centre, and the squared error averaged over the phases of each brightness;
each star is then given the error of the brightness whose clipped capsule sum is its own (what
its centroid measured). The counterpart of :func:`starsense.detect.centroid.cog_bias_px` for
frames at rest.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.detect.streak import SYSTEMATIC
from starsense.render.psf import pixel_profile

__all__ = ["N_PHASE", "frame_clipped_bias_px", "saturated_streak_bias_px"]

#: sub-pixel offsets per axis the streak is rendered at
N_PHASE = 4
#: brightnesses from the onset of clipping, log-spaced, up to _PAST times it
_N_BRIGHTNESS, _PAST = 16, 1e3
#: node spacing along the streak, PSF sigmas (pixel-integrated Gaussians that close sum to a
#: smooth streak: the pixel widens each to sqrt(sigma^2 + 1/12))
_NODE_SIGMAS = 0.5


def saturated_streak_bias_px(
    streak_px, electrons, *, sigma_px: float, saturation_e: float, radius_px: float, segment_px
) -> np.ndarray:
    """Return the rms centroid error per axis (px) of clipped streaks (module docstring).

    Parameters
    ----------
    streak_px : array_like, shape (2,)
        The frame's streak, px (x = column, y = row).
    electrons : array_like, shape (N,)
        Each star's sum over its capsule, electrons (clipped light included as measured).
    sigma_px : float
        PSF sigma, px.
    saturation_e : float
        Where a pixel clips, electrons.
    radius_px : float
        The capsule's radius around the segment, px.
    segment_px : float
        The length of the capsule's segment, px.

    Returns
    -------
    ndarray, shape (N,)
        px; 0 for a star whose sum is below the onset of clipping.
    """
    streak = np.asarray(streak_px, dtype=float).reshape(2)
    length = float(np.hypot(*streak))
    sigma = float(sigma_px)
    electrons = np.asarray(electrons, dtype=float)
    if length == 0.0 or not math.isfinite(saturation_e) or len(electrons) == 0:
        return np.zeros(len(electrons))
    u = streak / length
    n_nodes = max(8, math.ceil(length / (_NODE_SIGMAS * sigma)))
    t = ((np.arange(n_nodes) + 0.5) / n_nodes - 0.5) * length
    off = (np.arange(N_PHASE) + 0.5) / N_PHASE - 0.5
    ox, oy = (a.ravel() for a in np.meshgrid(off, off))  # (P,)
    half_x = math.ceil(0.5 * abs(streak[0]) + radius_px + 3.0 * sigma) + 1
    half_y = math.ceil(0.5 * abs(streak[1]) + radius_px + 3.0 * sigma) + 1
    cx = np.arange(-half_x, half_x + 1, dtype=float)
    cy = np.arange(-half_y, half_y + 1, dtype=float)
    # the renderer's pixel-integrated Gaussians at every node, one phase at a time (a long
    # streak's nodes times its window's width would take ~100 MB for all phases at once), and
    # the capsule around each phase's true centre
    unit = np.empty((len(ox), len(cy), len(cx)))
    for p in range(len(ox)):
        px = pixel_profile(-half_x, half_x + 1, ox[p] + t * u[0], sigma_px=sigma)  # (nodes, w)
        py = pixel_profile(-half_y, half_y + 1, oy[p] + t * u[1], sigma_px=sigma)  # (nodes, h)
        unit[p] = py.T @ px / n_nodes  # one electron
    dx = cx[None, None, :] - ox[:, None, None]
    dy = cy[None, :, None] - oy[:, None, None]
    beyond = np.maximum(np.abs(dx * u[0] + dy * u[1]) - 0.5 * float(segment_px), 0.0)
    inside = np.hypot(beyond, -dx * u[1] + dy * u[0]) <= radius_px
    del dx, dy, beyond
    top = float(unit.max())  # where the first phase clips, per electron
    grid = np.geomspace(saturation_e / top, _PAST * saturation_e / top, _N_BRIGHTNESS)
    sums, rms = np.zeros(len(grid)), np.zeros(len(grid))
    for k, n_e in enumerate(grid):
        img = np.where(inside, np.minimum(n_e * unit, saturation_e), 0.0)
        total = img.sum(axis=(1, 2))
        gx = (img.sum(axis=1) * cx).sum(axis=1) / total - ox
        gy = (img.sum(axis=2) * cy).sum(axis=1) / total - oy
        sums[k] = total.mean()
        rms[k] = math.sqrt(float(np.mean(0.5 * (gx * gx + gy * gy))))
    out = np.interp(electrons, sums, rms, left=0.0, right=rms[-1])
    return np.where(electrons >= sums[0], out, 0.0)


def frame_clipped_bias_px(
    streaks_px, electrons, *, sigma_px: float, saturation_e: float, radius_px
):
    """Return :func:`saturated_streak_bias_px` of a frame's clipped stars (N,), px.

    They share one streak, their mean (signs aligned to the first: a rate's streaks are
    parallel, their start and end unknown), over the capsule's segment (``SYSTEMATIC`` longer,
    :mod:`starsense.solve.streaks`).
    """
    streaks = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    if len(streaks) == 0:
        return np.zeros(0)
    typical = (streaks * np.sign(streaks @ streaks[0])[:, None]).mean(axis=0)
    return saturated_streak_bias_px(
        typical,
        electrons,
        sigma_px=sigma_px,
        saturation_e=saturation_e,
        radius_px=radius_px,
        segment_px=float(np.hypot(*typical)) * (1.0 + SYSTEMATIC),
    )
