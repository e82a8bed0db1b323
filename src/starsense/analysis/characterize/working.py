"""The sensor a frame's pixels are fitted with: its calibrated optics and its measured noise.

The forward model's likelihood (:func:`starsense.model.pixels.pixel_variance`) weighs each pixel
by the variance the sensor's detector gives it. A real frame's background noise is what the
frame says (:mod:`.noise`), whatever the base sensor assumed; so the detector's read noise is
set, for the fit only, to the one that makes a background pixel's variance the measured one:
``read^2 = (noise / g)^2 - (level - bias) / g`` (electrons), ``g`` the gain (measured, else the
base sensor's). The light of the fitted stars keeps its shot noise at that gain.
"""

from __future__ import annotations

import dataclasses
import math

from starsense.analysis.characterize.noise import FrameNoise

__all__ = ["working_sensor"]

#: the fitted read noise is at least this fraction of the measured noise (a gain guessed too
#: low would make the sky's shot noise alone exceed the measured noise)
MIN_READ_FRACTION = 0.1


def working_sensor(sensor, noise: FrameNoise, *, gain_counts_per_e: float | None = None):
    """Return ``sensor`` with a detector whose background variance is the frame's (docstring).

    Parameters
    ----------
    sensor : Sensor
        The calibrated sensor.
    noise : FrameNoise
        The frame's measured level and noise, counts.
    gain_counts_per_e : float, optional
        The gain to use (default: the sensor's).

    Returns
    -------
    Sensor
    """
    det = sensor.detector
    g = det.gain_counts_per_e if gain_counts_per_e is None else float(gain_counts_per_e)
    noise_e = noise.noise_counts / g
    sky_e = max(noise.level_counts - det.bias_counts, 0.0) / g + det.dark_current_e_s * (
        sensor.exposure_s
    )
    floor = MIN_READ_FRACTION * noise_e
    read = math.sqrt(max(noise_e**2 - sky_e - 1.0 / (12.0 * g * g), floor**2))
    new = dataclasses.replace(
        det,
        gain_counts_per_e=g,
        read_noise_e=read,
        dark_current_e_s=0.0,
        dsnu_e=0.0,
        prnu_fraction=0.0,
    )
    return sensor.with_(detector=new)
