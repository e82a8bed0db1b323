"""Centroids of detected stars: centre of gravity, intensity-weighted CoG, Gaussian fit.

All methods work on a window around the detection (its bounding box grown by ``margin_px``), on
background-subtracted counts, in the pixel-centre convention of :mod:`starsense.detect`.

* ``cog``: sum(w x) / sum(w) with w the background-subtracted counts of the window. For a star
  wholly inside the window it is unbiased: the CoG of a pixel-integrated Gaussian differs from its
  centre only by a pixel-phase term of order exp(-2 pi^2 sigma^2), 1e-19 px at sigma = 1.5 px.
* ``iwcog``: weights w^2 (w clipped at zero): less sensitive to noise in the wings, slightly
  biased towards the brightest pixel for undersampled stars.
* ``gauss``: least-squares fit of a pixel-integrated symmetric Gaussian plus a constant, started
  from the CoG; falls back to the CoG (``fit_ok`` False) when the fit fails.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import erf

METHODS = ("cog", "iwcog", "gauss")

#: sub-pixel phases per axis over which the centre of gravity's deterministic error is averaged
_N_PHASE = 8
#: brightness points of that table (log-spaced), and its reach past the onset of saturation
_N_BRIGHTNESS = 120
_PAST_SATURATION = 1e4
#: the table's step in lit sum, and the half-width of the lit sums averaged at each step, dex
_STEP_DEX = 0.05
_SMOOTH_DEX = 0.03
#: the lit threshold assumed for the window of the table, in background noise sigmas
_LIT_SIGMAS = 5.0


def _grid(window: np.ndarray, row0: int, col0: int):
    rows, cols = window.shape
    y = np.arange(row0, row0 + rows, dtype=float)[:, None]
    x = np.arange(col0, col0 + cols, dtype=float)[None, :]
    return x, y


def cog(window: np.ndarray, row0: int, col0: int, *, power: int = 1) -> tuple[float, float]:
    """(Intensity-weighted) centre of gravity of a background-subtracted window."""
    w = np.asarray(window, dtype=float)
    if power != 1:
        w = np.clip(w, 0.0, None) ** power
    total = w.sum()
    if not total > 0:
        return np.nan, np.nan
    x, y = _grid(w, row0, col0)
    return float((w * x).sum() / total), float((w * y).sum() / total)


def _pixel_gauss(x, y, x0, y0, sigma, flux, offset):
    s = np.sqrt(2.0) * sigma
    gx = 0.5 * (erf((x + 0.5 - x0) / s) - erf((x - 0.5 - x0) / s))
    gy = 0.5 * (erf((y + 0.5 - y0) / s) - erf((y - 0.5 - y0) / s))
    return flux * gx * gy + offset


def gauss_fit(window: np.ndarray, row0: int, col0: int, *, sigma0: float = 1.5):
    """Fit a pixel-integrated symmetric Gaussian + constant; returns (x, y, sigma, ok)."""
    from scipy.optimize import least_squares

    w = np.asarray(window, dtype=float)
    x0, y0 = cog(w, row0, col0)
    if not np.isfinite(x0):
        return np.nan, np.nan, np.nan, False
    x, y = _grid(w, row0, col0)
    xx, yy = np.broadcast_arrays(x, y)

    def residual(p):
        return (_pixel_gauss(xx, yy, *p) - w).ravel()

    p0 = [x0, y0, sigma0, max(w.sum(), 1.0), 0.0]
    lo = [col0 - 0.5, row0 - 0.5, 0.2, 0.0, -np.inf]
    hi = [col0 + w.shape[1] - 0.5, row0 + w.shape[0] - 0.5, max(w.shape), np.inf, np.inf]
    try:
        res = least_squares(residual, p0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
    except (ValueError, np.linalg.LinAlgError):
        return x0, y0, np.nan, False
    if not res.success:
        return x0, y0, np.nan, False
    return float(res.x[0]), float(res.x[1]), float(res.x[2]), True


def _profiles(centres: np.ndarray, offsets: np.ndarray, sigma: float) -> np.ndarray:
    """Pixel-integrated 1-d Gaussians (P, C) of unit flux centred at ``offsets`` (P,)."""
    s = math.sqrt(2.0) * sigma
    d = centres[None, :] - offsets[:, None]
    return 0.5 * (erf((d + 0.5) / s) - erf((d - 0.5) / s))


def _phase_errors(n_e: float, ox, oy, sigma: float, saturation_e: float, lit_e: float, margin):
    """Lit sums (e-) and squared CoG errors (px^2, mean of the axes) of a star at phases ox, oy."""
    reach = sigma * math.sqrt(2.0 * math.log(max(n_e / lit_e, 1.0)))
    half = math.ceil(reach + 3.0 * sigma) + margin + 2
    c = np.arange(-half, half + 1, dtype=float)
    img = n_e * _profiles(c, oy, sigma)[:, :, None] * _profiles(c, ox, sigma)[:, None, :]
    img = np.minimum(img, saturation_e)
    lit = img > lit_e
    idx = np.arange(len(c))
    rows, cols = lit.any(axis=2), lit.any(axis=1)
    r0 = np.where(rows, idx, len(c)).min(axis=1) - margin
    r1 = np.where(rows, idx, -1).max(axis=1) + margin
    c0 = np.where(cols, idx, len(c)).min(axis=1) - margin
    c1 = np.where(cols, idx, -1).max(axis=1) + margin
    inr = (idx[None, :] >= r0[:, None]) & (idx[None, :] <= r1[:, None])
    inc = (idx[None, :] >= c0[:, None]) & (idx[None, :] <= c1[:, None])
    w = img * (inr[:, :, None] & inc[:, None, :])
    total = w.sum(axis=(1, 2))
    safe = np.where(total > 0, total, 1.0)
    bx = (w.sum(axis=1) @ c) / safe - ox
    by = (w.sum(axis=2) @ c) / safe - oy
    return np.where(lit, img, 0.0).sum(axis=(1, 2)), 0.5 * (bx * bx + by * by)


@functools.lru_cache(maxsize=32)
def _bias_table(
    psf_sigma_px: float, saturation_e: float, lit_e: float, margin_px: int
) -> tuple[np.ndarray, np.ndarray]:
    """Return the windowed CoG's deterministic error of a noise-free star against its lit sum.

    Stars of ``n`` electrons (log-uniform from the lit level to ``_PAST_SATURATION`` times the
    onset of saturation) at sub-pixel phases ``(ox, oy)`` (``_N_PHASE`` per axis, uniform over
    the pixel), pixels clipped at ``saturation_e`` (a flat-topped profile: full well or ADC
    top), lit where above ``lit_e``; the window is the lit box grown by ``margin_px``, as the
    detector's (:func:`starsense.detect.regions.region_centroids`). The squared error
    ``CoG - true centre`` is averaged over the stars whose clipped sum over the lit pixels
    (what a detection's integrated counts measure) lies within ``_SMOOTH_DEX`` of each table
    point: the error a star of that lit sum has, whatever its brightness and phase, as a
    frame meets it. Returns the table's lit sums (electrons, increasing, ``_STEP_DEX``
    apart) and rms errors per axis (px): the pixel-phase error of an undersampled PSF, and
    the far larger one of a saturated core.
    """
    peak = math.erf(0.5 / (math.sqrt(2.0) * psf_sigma_px)) ** 2
    top = saturation_e / peak if math.isfinite(saturation_e) else 1e9 * lit_e
    n_grid = np.geomspace(2.0 * lit_e, max(_PAST_SATURATION * top, 4.0 * lit_e), _N_BRIGHTNESS)
    off = (np.arange(_N_PHASE) + 0.5) / _N_PHASE - 0.5
    ox, oy = (a.ravel() for a in np.meshgrid(off, off))
    got = [
        _phase_errors(float(n), ox, oy, psf_sigma_px, saturation_e, lit_e, margin_px)
        for n in n_grid
    ]
    obs = np.concatenate([g[0] for g in got])
    err2 = np.concatenate([g[1] for g in got])
    seen = obs > 0  # the faintest light no pixel
    log_obs, err2 = np.log10(obs[seen]), err2[seen]
    # each point: the stars within a factor 10^_SMOOTH_DEX of its lit sum. The bias of a
    # saturated star swings as its plateau grows pixel by pixel; the lit sum follows that
    # growth, so a narrow average keeps what it tells (a 0.15 dex average left a saturated
    # zoo design's attitude 20 % worse)
    mid = np.arange(log_obs.min(), log_obs.max() + _STEP_DEX, _STEP_DEX)
    near = np.abs(log_obs[None, :] - mid[:, None]) <= _SMOOTH_DEX
    held = near.any(axis=1)
    near = near[held]
    rms = np.sqrt((near * err2[None, :]).sum(axis=1) / near.sum(axis=1))
    return 10.0 ** mid[held], rms


def cog_bias_px(det, index, *, detector, margin_px: int) -> np.ndarray:
    """Return the deterministic error (px rms per axis) of the CoG centroids of ``index``.

    The centre of gravity of a symmetric PSF integrated over pixels is off its centre by an
    amount that depends on where in its pixel the star falls: negligible for a well-sampled
    PSF, a few hundredths of a pixel for an undersampled one cut by its lit window, and up to
    a tenth of a pixel for a saturated star, whose flat top no longer follows the PSF. A frame
    meets each star at a random phase, so to the attitude fit this is a per-star error like
    the noise. It is the rms over phases of a noise-free star of the same lit sum
    (:func:`_bias_table`, cached per detector), clipped at the full well or the ADC's top.

    Parameters
    ----------
    det : Detections
        The frame's detections (integrated counts, noise).
    index : array_like of int, shape (N,)
        The detections to evaluate.
    detector : starsense.sensor.Detector
        The camera's detector: gain, read noise, full well, ADC range, PSF sigma.
    margin_px : int
        The CoG window's margin around each bounding box, px.

    Returns
    -------
    ndarray, shape (N,)
        Per-axis rms error over sub-pixel phases, px.
    """
    g = detector.gain_counts_per_e
    sat_e = detector.clip_e
    noise = det.noise_counts if det.noise_counts > 0 else detector.read_noise_e * g
    lit = max(_LIT_SIGMAS * noise, 1.0) / g
    # cached per detector: the lit level rounded to 1/8 of a decade (a frame's noise estimate)
    lit = float(10.0 ** (round(8.0 * math.log10(lit)) / 8.0))
    obs, rms = _bias_table(float(detector.psf_sigma_px), float(sat_e), lit, int(margin_px))
    n_e = np.maximum(np.asarray(det.integrated_counts[index], dtype=float) / g, obs[0])
    return np.interp(np.log(n_e), np.log(obs), rms)


def edge_bias_px(x, y, shape, *, psf_sigma_px: float) -> np.ndarray:
    """Return how far the frame's edge pulls the centroid of each star inwards, px.

    A star whose PSF is cut by the edge of the frame has its centre of gravity pulled inwards
    by the light it lost: for a Gaussian of sigma s (the PSF widened by the pixel,
    ``s^2 = sigma^2 + 1/12``) centred d px inside the edge, ``s phi(d/s) / Phi(d/s)`` (the mean
    of a normal truncated at -d). The centroid given is already pulled inwards, so d is solved
    from it (``d = d_measured - pull(d)``, a few steps of the contraction). Zero for a star
    more than about 4 s from every edge; the pulls of the two axes are added in quadrature.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Centroids (x = column, y = row), px, pixel-centre convention.
    shape : (int, int)
        Rows and columns of the frame.
    psf_sigma_px : float
        PSF sigma, px.

    Returns
    -------
    ndarray, shape (N,)
        px.
    """
    rows, cols = shape
    s = math.sqrt(float(psf_sigma_px) ** 2 + 1.0 / 12.0)
    total = np.zeros(np.shape(x), dtype=float)
    for c, n in ((np.asarray(x, dtype=float), cols), (np.asarray(y, dtype=float), rows)):
        measured = np.minimum(c + 0.5, n - 0.5 - c)  # to the nearer edge, px
        near = measured < 6.0 * s  # elsewhere the pull is below 1e-8 s
        if not near.any():
            continue
        d = measured[near]
        pull = _truncation_pull(d, s)
        for _ in range(6):  # a centre up to one s past the edge
            pull = _truncation_pull(np.maximum(d - pull, -s), s)
        total[near] += pull**2
    return np.sqrt(total)


def _truncation_pull(d: np.ndarray, s: float) -> np.ndarray:
    """Mean of a normal of sigma ``s`` truncated ``d`` below its centre: s phi(d/s) / Phi(d/s)."""
    z = d / s
    phi = np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    big_phi = 0.5 * (1.0 + erf(z / math.sqrt(2.0)))
    return s * phi / big_phi


def cog_sigma_px(det, index, *, detector, margin_px: int, shape=None) -> np.ndarray:
    """Return the per-axis error of a centre-of-gravity centroid, pixels, of detections ``index``.

    Photon noise: sigma_psf^2 / N_e (N_e = integrated counts / gain). Read noise and the ADC's
    quantisation (1/12 count^2): each pixel of the CoG window adds their variance times
    (x - x_c)^2 / N_e^2; over a w x h window centred on the star the sum of (x - x_c)^2 is
    h w (w^2 - 1) / 12 (the mean of the two axes is used). The centroider's deterministic
    error over the sub-pixel phase (:func:`cog_bias_px`: undersampled and saturated stars) is
    added in quadrature: it is how far such a star's centroid is from the truth in a frame,
    which the attitude fit's weights ``1 / sigma^2`` and its outlier test need to know.

    Parameters
    ----------
    det : Detections
        The frame's detections (integrated counts, bounding boxes).
    index : array_like of int, shape (N,)
        The detections to evaluate.
    detector : starsense.sensor.Detector
        The camera's detector: gain, read noise, PSF sigma, full well and ADC range.
    margin_px : int
        The CoG window's margin around each bounding box, px.
    shape : (int, int), optional
        Rows and columns of the frame the detections come from: a star cut by its edge adds
        the pull of :func:`edge_bias_px` in quadrature (a bright star on the edge would
        otherwise weigh as if exact and pull the attitude by its bias).

    Returns
    -------
    ndarray, shape (N,)
        Centroid error per axis, px.
    """
    g = detector.gain_counts_per_e
    n_e = np.maximum(det.integrated_counts[index] / g, 1.0)
    r0, r1, c0, c1 = det.bbox[index].T
    w = (c1 - c0 + 2 * margin_px).astype(float)
    h = (r1 - r0 + 2 * margin_px).astype(float)
    spread = 0.5 * (h * w * (w**2 - 1) + w * h * (h**2 - 1)) / 12.0
    pixel_var = detector.read_noise_e**2 + 1.0 / (12.0 * g * g)
    var = detector.psf_sigma_px**2 / n_e + pixel_var * spread / n_e**2
    bias = cog_bias_px(det, index, detector=detector, margin_px=margin_px)
    if shape is not None:
        edge = edge_bias_px(det.x[index], det.y[index], shape, psf_sigma_px=detector.psf_sigma_px)
        var = var + edge**2
    return np.sqrt(var + bias**2)
