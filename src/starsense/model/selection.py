"""Which catalogue stars a frame's fit holds: those the model predicts above the noise.

The forward model's fit and the datasheet's prediction of it hold the same stars, chosen by
the model rather than by a detector: every catalogue star on the detector whose predicted
light exceeds :data:`FITTED_SNR` (5) times the noise of its footprint (read, dark: a dark pixel's
noise summed over the PSF's noise-equivalent area, and over the streak under slew). Its
window is fitted whether or not a detector found it, with its flux free: a star fainter than
predicted adds little information, never a bias, since its position is the catalogue's moved
by the attitude. So the fit's stars, and the prediction's, do not depend on which extraction
(quick threshold, matched filter, the flight software's logic) identified the frame.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.pixels import pixel_variance
from starsense.model.psf import psf_of

__all__ = ["FITTED_SNR", "faintest_mag", "fitted_min_electrons", "psf_noise_e", "streak_px"]

#: a star joins the fit when its predicted electrons exceed this many times its footprint's
#: noise: the solver's matched filter detects at 5 sigma of the filtered noise, which for a
#: star is this signal-to-noise ratio over the PSF's noise-equivalent area, so every star a
#: detector can find (and identify) is among the model's stars, and the prediction counts the
#: identified ones whichever detector found them. A star's position information grows as its
#: SNR squared: the fainter stars left out (SNR 3-5) would sharpen the ST-16's attitude by
#: about 2 % with 1.5 times the stars to fit
FITTED_SNR = 5.0


def streak_px(sensor, rate_rad_s) -> float:
    """Return the length of a star's streak near the boresight at body rate ``rate_rad_s``, px.

    ``rate_rad_s``: a vector (3,) in the camera frame or its magnitude, rad/s.
    """
    rate = float(np.linalg.norm(np.atleast_1d(np.asarray(rate_rad_s, dtype=float))))
    return rate * sensor.exposure_s * sensor.focal_length_px


def psf_noise_e(sensor, rate_rad_s=0.0) -> float:
    """Return a dark pixel's noise summed over a star's footprint, electrons.

    The noise-equivalent area of a Gaussian PSF, ``4 pi sigma^2``; smeared over a streak of
    ``L`` px it grows by ``2 sqrt(pi) sigma L`` (the light spread along the track: a faint star
    under slew puts less in each pixel than at rest).
    """
    sigma = psf_of(sensor).sigma_px
    length = streak_px(sensor, rate_rad_s)
    area = 4.0 * math.pi * sigma**2 + 2.0 * math.sqrt(math.pi) * sigma * length
    return math.sqrt(pixel_variance(sensor.detector, 0.0, sensor.exposure_s) * area)


def fitted_min_electrons(sensor, rate_rad_s=0.0) -> float:
    """Return the fewest predicted electrons of a star the fit holds at ``rate_rad_s``."""
    return FITTED_SNR * psf_noise_e(sensor, rate_rad_s)


def faintest_mag(zero_point_e: float, min_electrons_e: float) -> float:
    """Return the magnitude of a star of ``min_electrons_e`` at a zero point.

    ``zero_point_e``: electrons of a magnitude-0 star. Infinite without a floor.
    """
    if min_electrons_e <= 0:
        return math.inf
    return 2.5 * math.log10(zero_point_e / min_electrons_e)
