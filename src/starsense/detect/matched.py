"""Matched filtering of a background-subtracted frame: detect stars, not noise spikes.

A star spreads its light over a PSF; a noise spike, a hot pixel or a cosmic ray sits on one
pixel. Correlating the frame with the PSF (a Gaussian of the PSF's sigma, normalised to unit
sum) is the matched filter for a point source in white noise: it maximises the signal-to-noise
ratio of the peak, by sqrt(4 pi) sigma_psf over a single pixel (3.5 for sigma = 1 px), while a
one-pixel spike is spread to 1 / (2 pi sigma^2) of its height (16 % at 1 px). Thresholds are
then set in units of the noise of the *filtered* frame.

The noise of the filtered frame is measured, not assumed: for white noise it is the pixel noise
times sqrt(sum k^2) = 1 / (2 sqrt(pi) sigma), but JPEG compression, demosaicing and binning
correlate neighbouring pixels and make it larger. It is taken as 1.4826 MAD of the filtered
frame over the pixel noise map (on a subsample of pixels, where stars are a negligible
fraction), and never below the white-noise value.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["matched_filter"]

#: 1 / Phi^-1(3/4)
_MAD_TO_SIGMA = 1.482602218505602
#: the kernel is cut at this many sigma
_TRUNCATE = 3.0


def matched_filter(sub: np.ndarray, noise, psf_sigma_px: float):
    """Correlate a frame with its PSF and return it with the noise of the result.

    Parameters
    ----------
    sub : ndarray, shape (rows, columns)
        Background-subtracted frame, counts.
    noise : float or ndarray, shape (rows, columns)
        Pixel noise of the background, counts rms (a number or a map).
    psf_sigma_px : float
        Sigma of the (Gaussian) PSF, pixels.

    Returns
    -------
    filtered : ndarray, shape (rows, columns), float32
        The frame correlated with the unit-sum Gaussian of sigma ``psf_sigma_px``, counts.
    filtered_noise : float or ndarray
        Noise of ``filtered``, counts rms (same form as ``noise``).
    ratio : float
        ``filtered_noise / noise``.
    """
    filtered = ndimage.gaussian_filter(
        np.asarray(sub, dtype=np.float32), psf_sigma_px, mode="nearest", truncate=_TRUNCATE
    )
    white = 1.0 / (2.0 * np.sqrt(np.pi) * psf_sigma_px)
    noise_arr = np.asarray(noise, dtype=np.float32)
    step = 3
    if noise_arr.ndim:
        n_s = noise_arr[::step, ::step]
    else:
        n_s = noise_arr
    f_s = filtered[::step, ::step]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (f_s / np.maximum(n_s, np.float32(1e-12))).ravel()
    z = z[np.isfinite(z)]
    measured = _MAD_TO_SIGMA * float(np.median(np.abs(z - np.median(z)))) if z.size else 0.0
    ratio = max(measured, white)
    return filtered, noise_arr * np.float32(ratio), ratio
