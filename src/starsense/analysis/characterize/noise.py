"""The frames' background and noise, and the gain from the photon transfer (variance vs mean).

Each frame is cut into boxes (:data:`BOX_PX`); in each, the pixels minus the frame's smooth
background map (:func:`starsense.detect.background.estimate_background`: the sky glow's gradient
taken out), stars and hot pixels left out (clipped, and faint stars found on the 3 x 3 mean and
grown, :func:`_sources`), give the box's variance as the square of the scaled median absolute
deviation: stars too faint to find add light to a few pixels of a box, more at a longer
exposure, which a sample variance would count as noise (on rendered frames of Hipparcos fields
it steepened the transfer by ~1 %, several of its sigmas) and a median does not. The map gives
the box's mean level. The frame's sky level and per-pixel noise are the medians over its boxes.

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
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from starsense.detect.background import estimate_background

__all__ = ["BOX_PX", "FrameNoise", "PhotonTransfer", "frame_noise", "photon_transfer"]

#: box size of the variance samples, px
BOX_PX = 32
#: clipping of stars and hot pixels in a box, robust sigmas
CLIP_SIGMA = 3.0
#: the variance from a median absolute deviation has the sample variance's variance over this
MAD_EFFICIENCY = 0.37
#: frames needed for a photon transfer...
MIN_EXPOSURES = 2
#: ...whose median levels above the bias differ by at least this factor
MIN_LEVEL_RATIO = 1.5
#: a faint star's pixels: its 3 x 3 mean above this many of that mean's noise sigmas
SOURCE_SIGMA = 4.0
#: ...grown by this many pixels (its wings)
SOURCE_GROW_PX = 4
#: a box is used when at least this fraction of its pixels survive the clipping
MIN_KEPT = 0.5


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
    box_xy : ndarray (B, 2)
        Each usable box's centre (x = column, y = row), px: the noise map.
    """

    level_counts: float
    noise_counts: float
    box_levels: np.ndarray
    box_variances: np.ndarray
    box_pixels: np.ndarray
    clipped_at_zero: bool
    box_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


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

    def boxes(x):
        x = x[: nr * hr, : nc * hc].reshape(nr, hr, nc, hc).transpose(0, 2, 1, 3)
        return x.reshape(nr * nc, hr * hc)

    r = boxes(resid)
    lv = boxes(level).mean(axis=1)
    med = np.median(r, axis=1)
    mad = 1.4826 * np.median(np.abs(r - med[:, None]), axis=1)
    keep = np.abs(r - med[:, None]) <= CLIP_SIGMA * np.maximum(mad, 1e-9)[:, None]
    keep &= ~boxes(_sources(resid, float(np.median(mad))))
    n = keep.sum(axis=1)
    mean = np.where(n > 0, (r * keep).sum(axis=1) / np.maximum(n, 1), 0.0)
    # the boxes that kept a pixel (a box all star or all clipped has none: NaN, not a warning)
    has = n > 0
    masked = np.where(keep[has], r[has], np.nan)
    centre = np.nanmedian(masked, axis=1)
    var = np.full(r.shape[0], np.nan)
    var[has] = (1.4826 * np.nanmedian(np.abs(masked - centre[:, None]), axis=1)) ** 2
    ok = (n >= MIN_KEPT * r.shape[1]) & (mad > 0)
    noise = float(np.sqrt(np.median(var[ok]))) if ok.any() else float(bg.noise)
    level_med = float(np.median(lv))
    k = np.arange(nr * nc)
    centres = np.column_stack([(k % nc + 0.5) * hc - 0.5, (k // nc + 0.5) * hr - 0.5])
    return FrameNoise(
        level_counts=level_med,
        noise_counts=noise,
        box_levels=lv[ok] + mean[ok],
        box_variances=var[ok],
        box_pixels=n[ok],
        clipped_at_zero=bool(level_med < 3.0 * noise),
        box_xy=centres[ok],
    )


def _sources(resid: np.ndarray, noise: float) -> np.ndarray:
    """Pixels of faint stars: the 3 x 3 mean above :data:`SOURCE_SIGMA` of its noise, grown.

    A star too faint to clip in one pixel still adds its light's variance to a box, more at
    a longer exposure, and would steepen the photon transfer: averaging 3 x 3 pixels finds it
    at a third of the noise per pixel.
    """
    mean3 = ndimage.uniform_filter(resid, size=3, mode="nearest")
    lit = mean3 > SOURCE_SIGMA * noise / 3.0
    return ndimage.binary_dilation(lit, iterations=SOURCE_GROW_PX)


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
    keep = np.ones(s.size, dtype=bool)
    for _ in range(5):  # weights from the line itself (a variance's own scatter)
        model = np.maximum(design @ coef, 1e-12)
        w = MAD_EFFICIENCY * (npx - 1.0) / (2.0 * model**2)
        keep = np.abs(v - model) * np.sqrt(w) <= CLIP_SIGMA  # a box with a star's light
        w = w * keep
        a = design.T @ (design * w[:, None])
        coef = np.linalg.solve(a, design.T @ (w * v))
    resid = v - design @ coef
    chi2 = float(np.sum(w * resid**2))
    dof = max(int(keep.sum()) - 2, 1)
    birge = math.sqrt(chi2 / dof)
    cov = np.linalg.inv(a) * max(birge, 1.0) ** 2
    return PhotonTransfer(
        gain_counts_per_e=float(coef[0]),
        gain_sigma=float(math.sqrt(cov[0, 0])),
        floor_counts2=float(coef[1]),
        floor_sigma=float(math.sqrt(cov[1, 1])),
        birge=birge,
        n_boxes=int(keep.sum()),
        n_frames=len(use),
    )
