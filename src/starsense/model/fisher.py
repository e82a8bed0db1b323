"""The forward model's Fisher information: how well a star's pixels fix its position.

For one star of ``F`` electrons, smeared along ``l`` (px) over the exposure, on a background of
``b`` electrons per pixel, the expected pixels ``mu_j = F T_j(x, y) + b`` (the template of
:mod:`starsense.model.windows`) and their variance ``v_j`` (:func:`~starsense.model.fit.
pixel_variance`) give the information of its mid-exposure position with the flux and the
background unknown (the fit's nuisance parameters)::

    I = C - B^T A^-1 B,   C = sum_j g_j g_j^T / v_j,   g_j = F dT_j / d(x, y)
                          A = sum_j h_j h_j^T / v_j,   h_j = (T_j, 1),   B = sum_j h_j g_j^T / v_j

(px^-2), averaged over the star's sub-pixel phase (the information of many stars at random
phases adds up to the mean's). Pixels the ADC or the full well clip carry none (censored, as the
fit treats them); pixels near the ADC's floor, the share a censored one keeps
(:func:`~starsense.model.pixels.censored_information`). This is the per-star term of the
attitude's Cramer-Rao bound that the solver's model fit attains; summed over the stars of a
frame through the projection's Jacobian (:func:`attitude_information`) it is the
noise-equivalent angle. Fialho & Mortari (2019, eq. 19)
is its limit for an ideal sensor: a Gaussian PSF, no background, no read noise, no pixels.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.pixels import censored_information, floor_e, pixel_variance
from starsense.model.psf import PixelPSF, psf_of
from starsense.model.stamps import source_stamps
from starsense.model.tracks import NodePositions, time_nodes
from starsense.model.windows import window_half_px

__all__ = ["attitude_information", "position_information", "position_sigma_px"]


def _one(psf: PixelPSF, sensor, electrons: float, streak, phase, background_e: float):
    """Return the 2 x 2 information of one star's position at one sub-pixel phase."""
    det, te = sensor.detector, sensor.exposure_s
    lx, ly = float(streak[0]), float(streak[1])
    frac, wts = time_nodes(math.hypot(lx, ly), psf.sigma_px)
    x0, y0 = phase
    nx, ny = x0 + frac * lx, y0 + frac * ly
    k = len(frac)
    nodes = NodePositions(
        nx[None, :],
        ny[None, :],
        wts,
        np.broadcast_to(np.eye(2)[0], (1, k, 2)),
        np.broadcast_to(np.eye(2)[1], (1, k, 2)),
    )
    half = window_half_px(psf)
    r0 = math.floor(min(ny.min(), ny.max()) - half + 0.5)
    r1 = math.floor(max(ny.min(), ny.max()) + half + 0.5) + 1
    c0 = math.floor(min(nx.min(), nx.max()) - half + 0.5)
    c1 = math.floor(max(nx.min(), nx.max()) + half + 0.5) + 1
    rows = np.arange(r0, r1)[None, :]
    cols = np.arange(c0, c1)[None, :]
    t, d = source_stamps(psf, nodes, np.array([0]), rows=rows, cols=cols, half_px=half)
    t, g = t[0].ravel(), electrons * d[0].reshape(2, -1)
    mu = electrons * t + background_e
    v = pixel_variance(det, mu, te)
    w = np.where(mu < det.clip_e, 1.0 / v, 0.0)
    floor = floor_e(det, te)
    if floor is not None:  # a background near the ADC's floor: censored pixels tell less
        w = w * censored_information((floor - mu) / np.sqrt(v))
    h = np.vstack([t, np.ones_like(t)])
    a = (h * w) @ h.T
    b = (h * w) @ g.T
    c = (g * w) @ g.T
    # the flux and the background marginalised; where no pixel tells them apart (every pixel
    # of a bright star past the full well: no weight) the pseudo-inverse leaves what is known,
    # none of the position's information where no pixel holds any
    return c - b.T @ np.linalg.pinv(a) @ b


def position_information(
    sensor,
    electrons,
    streaks_px=None,
    *,
    n_phase: int = 3,
    background_e: float = 0.0,
    psf: PixelPSF | None = None,
) -> np.ndarray:
    """Return the information of each star's mid-exposure position, px^-2 (module docstring).

    Parameters
    ----------
    sensor : Sensor
    electrons : array_like, shape (N,)
        Each star's electrons over the exposure.
    streaks_px : array_like, shape (N, 2), optional
        Each star's streak (start to end), px (default: at rest).
    n_phase : int
        Sub-pixel phases per axis averaged over (``n_phase^2``, at the cells' centres).
    background_e : float
        Sky background, electrons per pixel (beyond the dark charge).
    psf : PixelPSF, optional
        Default: the sensor's.

    Returns
    -------
    ndarray, shape (N, 2, 2)
    """
    psf = psf or psf_of(sensor)
    e = np.atleast_1d(np.asarray(electrons, dtype=float))
    streaks = np.zeros((len(e), 2)) if streaks_px is None else np.asarray(streaks_px, float)
    offsets = (np.arange(n_phase) + 0.5) / n_phase - 0.5
    phases = [(float(a), float(b)) for a in offsets for b in offsets]
    out = np.zeros((len(e), 2, 2))
    for i, (n_e, streak) in enumerate(zip(e, streaks, strict=True)):
        if not (np.isfinite(n_e) and n_e > 0):
            continue
        out[i] = np.mean(
            [_one(psf, sensor, n_e, streak, ph, background_e) for ph in phases], axis=0
        )
    return out


def position_sigma_px(sensor, electrons, **kwargs) -> np.ndarray:
    """Return each star's 1-sigma position error per axis at rest, px: ``1 / sqrt(I / 2)``.

    The mean of the two axes' information (a static star's is isotropic over its phases).
    """
    info = position_information(sensor, electrons, **kwargs)
    mean = 0.5 * (info[:, 0, 0] + info[:, 1, 1])
    with np.errstate(divide="ignore"):
        return np.where(mean > 0, 1.0 / np.sqrt(mean), np.inf)


def attitude_information(sensor, v_cam, info_px) -> np.ndarray:
    """Return the attitude information of stars, rad^-2, summed per star: J^T I J (3 x 3).

    ``J`` = d(x, y) / d(theta) of the pinhole projection at each star's camera direction
    ``v_cam`` (N, 3) (a rotation ``theta`` moves it by ``theta x v``), ``info_px`` (N, 2, 2) its
    position information. Sum the result over a frame's stars for its Fisher matrix.
    """
    v = np.asarray(v_cam, dtype=float)
    f = sensor.focal_length_px
    z = v[:, 2]
    # d(x, y)/d(v) of x = f vx / vz (px per unit vector), times d(v)/d(theta) = -[v]_x
    dproj = np.zeros((len(v), 2, 3))
    dproj[:, 0, 0] = f / z
    dproj[:, 0, 2] = -f * v[:, 0] / z**2
    dproj[:, 1, 1] = f / z
    dproj[:, 1, 2] = -f * v[:, 1] / z**2
    skew = np.zeros((len(v), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = v[:, 2], -v[:, 1], v[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = -v[:, 2], v[:, 1], -v[:, 0]
    jac = dproj @ skew  # d(theta x v) = -[v]x theta = skew(v)^T... sign irrelevant in J^T I J
    return np.einsum("nai,nab,nbj->nij", jac, np.asarray(info_px, float), jac)
