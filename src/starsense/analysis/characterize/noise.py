"""The frames' background and noise, and the gain from the photon transfer (variance vs mean).

Each frame is cut into boxes (:data:`BOX_PX`); in each, the pixels minus the frame's smooth
background map (:func:`starsense.detect.background.estimate_background`: the sky glow's gradient
taken out) are sigma-clipped (stars, hot pixels) and give the box's variance; the map gives its
mean level. The frame's sky level and per-pixel noise are the medians over its boxes.

Photon transfer: a pixel's variance in counts is ``g (S - b) + sigma_0^2`` for a mean ``S``
(counts), gain ``g`` (counts per electron), bias ``b`` and a floor ``sigma_0`` (read noise
and quantisation, counts). A line fitted to the boxes of several exposures (weighted: a sample
variance of n pixels has variance ``2 var^2 / (n - 1)``) gives the gain as its slope, with
the slope's sigma from the fit (raised by the Birge ratio when the boxes scatter more than
their statistics: fixed-pattern noise, unresolved stars). One exposure, whose boxes span only
the glow's gradient, cannot tell the gain from what changes with the level besides the light
(vignetting changes both), so it is not fitted from fewer than :data:`MIN_EXPOSURES` frames
whose levels differ by :data:`MIN_LEVEL_RATIO`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.detect.background import estimate_background

__all__ = ["BOX_PX", "FrameNoise", "PhotonTransfer", "frame_noise", "photon_transfer"]

#: box size of the variance samples, px
BOX_PX = 32
#: clipping of stars and hot pixels in a box, robust sigmas
CLIP_SIGMA = 3.0
#: the variance of a normal sample clipped at +-3 sigma is this fraction of the unclipped one
#: (1 - 2 * 3 * phi(3) / (2 Phi(3) - 1), phi and Phi the normal density and distribution)
CLIPPED_VARIANCE = 0.97333
#: frames needed for a photon transfer...
MIN_EXPOSURES = 2
#: ...whose median levels above the bias differ by at least this factor
MIN_LEVEL_RATIO = 1.5
#: a box is used when at least this fraction of its pixels survive the clipping
MIN_KEPT = 0.8


@dataclass(frozen=True, eq=False)
class FrameNoise:
    """One frame's background.

    Attributes
    ----------
    level_counts : float
        Median sky level over the frame, counts.
    noise_counts : float
        Median per-pixel noise (background removed, stars clipped), counts rms.
    box_levels, box_variances : ndarray (B,)
        Each usable box's mean level (counts) and pixel variance (counts^2).
    box_pixels : ndarray (B,)
        Pixels kept in each box.
    clipped_at_zero : bool
        The background sits within 3 noise sigmas of zero (an 8-bit frame whose sky is clipped):
        its variances are not those of the light.
    """

    level_counts: float
    noise_counts: float
    box_levels: np.ndarray
    box_variances: np.ndarray
    box_pixels: np.ndarray
    clipped_at_zero: bool


def frame_noise(image) -> FrameNoise:
    """Measure a frame's sky level and per-pixel noise (module docstring).

    Parameters
    ----------
    image : ndarray (rows, columns)
        The frame, counts.

    Returns
    -------
    FrameNoise
    """
    a = np.asarray(image, dtype=np.float64)
    bg = estimate_background(a, full_noise_map=False)
    level = np.broadcast_to(np.asarray(bg.level, dtype=np.float64), a.shape)
    resid = a - level
    rows, cols = a.shape
    nr, nc = max(rows // BOX_PX, 1), max(cols // BOX_PX, 1)
    hr, hc = rows // nr, cols // nc
    r = resid[: nr * hr, : nc * hc].reshape(nr, hr, nc, hc).transpose(0, 2, 1, 3)
    r = r.reshape(nr * nc, hr * hc)
    lv = level[: nr * hr, : nc * hc].reshape(nr, hr, nc, hc).mean(axis=(1, 3)).ravel()
    med = np.median(r, axis=1)
    mad = 1.4826 * np.median(np.abs(r - med[:, None]), axis=1)
    keep = np.abs(r - med[:, None]) <= CLIP_SIGMA * np.maximum(mad, 1e-9)[:, None]
    n = keep.sum(axis=1)
    mean = np.where(n > 0, (r * keep).sum(axis=1) / np.maximum(n, 1), 0.0)
    var = ((r - mean[:, None]) ** 2 * keep).sum(axis=1) / np.maximum(n - 1, 1)
    var = var / CLIPPED_VARIANCE
    ok = (n >= MIN_KEPT * r.shape[1]) & (mad > 0)
    noise = float(np.sqrt(np.median(var[ok]))) if ok.any() else float(bg.noise)
    level_med = float(np.median(lv))
    return FrameNoise(
        level_counts=level_med,
        noise_counts=noise,
        box_levels=lv[ok] + mean[ok],
        box_variances=var[ok],
        box_pixels=n[ok],
        clipped_at_zero=bool(level_med < 3.0 * noise),
    )


@dataclass(frozen=True)
class PhotonTransfer:
    """The gain from the photon transfer, or why it could not be told.

    Attributes
    ----------
    gain_counts_per_e, gain_sigma : float
        Slope of variance against mean, counts per electron, and its 1-sigma (NaN: not told).
    floor_counts2, floor_sigma : float
        The intercept at the bias, counts^2 (read noise and quantisation), and its 1-sigma.
    birge : float
        Scatter of the boxes about the line against their statistics (1 when they agree).
    n_boxes, n_frames : int
    reason : str
        Empty when fitted; else why the frames cannot tell the gain.
    """

    gain_counts_per_e: float = math.nan
    gain_sigma: float = math.nan
    floor_counts2: float = math.nan
    floor_sigma: float = math.nan
    birge: float = math.nan
    n_boxes: int = 0
    n_frames: int = 0
    reason: str = ""

    @property
    def told(self) -> bool:
        """Whether the gain was measured."""
        return not self.reason


def photon_transfer(noises: list[FrameNoise], bias_counts: float = 0.0) -> PhotonTransfer:
    """Fit ``var = g (S - bias) + floor`` to the boxes of several exposures (module docstring).

    Parameters
    ----------
    noises : list of FrameNoise
        The frames' boxes.
    bias_counts : float
        The camera's bias (the base sensor's; 0 when unknown), counts.

    Returns
    -------
    PhotonTransfer
    """
    use = [n for n in noises if not n.clipped_at_zero and n.box_levels.size]
    if len(noises) < MIN_EXPOSURES:
        return PhotonTransfer(
            reason="one exposure cannot tell the gain: the photon transfer needs frames of "
            "several sky levels (exposures), and one frame's level changes only with the glow "
            "and the vignetting, which change its noise in other ways too"
        )
    if len(use) < MIN_EXPOSURES:
        return PhotonTransfer(
            reason="the gain cannot be told: fewer than two frames have a background clear of "
            "zero (a sky clipped at zero has no photon transfer)"
        )
    levels = np.array([n.level_counts for n in use]) - bias_counts
    if np.max(levels) < MIN_LEVEL_RATIO * max(np.min(levels), 1e-9):
        return PhotonTransfer(
            reason=f"the gain cannot be told: the frames' sky levels ({np.min(levels):.4g}-"
            f"{np.max(levels):.4g} counts above the bias) differ by less than a factor "
            f"{MIN_LEVEL_RATIO:g}, too little for a photon transfer"
        )
    s = np.concatenate([n.box_levels for n in use]) - bias_counts
    v = np.concatenate([n.box_variances for n in use])
    npx = np.concatenate([n.box_pixels for n in use]).astype(float)
    design = np.column_stack([s, np.ones_like(s)])
    coef = np.linalg.lstsq(design, v, rcond=None)[0]
    for _ in range(3):  # weights from the line itself (a variance's own scatter)
        model = np.maximum(design @ coef, 1e-12)
        w = (npx - 1.0) / (2.0 * model**2)
        a = design.T @ (design * w[:, None])
        coef = np.linalg.solve(a, design.T @ (w * v))
    resid = v - design @ coef
    chi2 = float(np.sum(w * resid**2))
    dof = max(s.size - 2, 1)
    birge = math.sqrt(chi2 / dof)
    cov = np.linalg.inv(a) * max(birge, 1.0) ** 2
    return PhotonTransfer(
        gain_counts_per_e=float(coef[0]),
        gain_sigma=float(math.sqrt(cov[0, 0])),
        floor_counts2=float(coef[1]),
        floor_sigma=float(math.sqrt(cov[1, 1])),
        birge=birge,
        n_boxes=int(s.size),
        n_frames=len(use),
    )
