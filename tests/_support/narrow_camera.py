"""A narrow-field camera exposing 1 s, for streaks hundreds of pixels long at 1 deg/s.

5 deg across 2048 x 1536 pixels of 16 um (a 375 mm lens at f/3.2), PSF sigma 1 px, gain 0.5
counts/e- and 2 e- of read noise: at 8 bits its ADC clips at ~510 e-, so a bright star's streak
clips along its length; at 12 bits it does not.
"""

from __future__ import annotations

import math

from starsense.sensor import DetectionThresholds, Sensor
from starsense.sensor.detector import Detector
from starsense.sensor.optics import Optics


def narrow_camera(bit_depth: int = 12) -> Sensor:
    """Return the camera (module docstring) at ``bit_depth`` bits."""
    det = Detector(
        columns=2048,
        rows=1536,
        pixel_pitch_m=16e-6,
        gain_counts_per_e=0.5,
        read_noise_e=2.0,
        bit_depth=bit_depth,
        psf_sigma_px=1.0,
        qe_mean=0.55,
        passband_nm=(400.0, 900.0),
        full_well_e=384_000.0,
    )
    focal = 0.5 * 2048 * 16e-6 / math.tan(math.radians(2.5))
    optics = Optics(focal_length_m=focal, aperture_m=focal / 3.2, transmission=0.8)
    logic = DetectionThresholds(lit_pixel_counts=5.0, min_pixels=3, min_integrated_counts=15.0)
    return Sensor(
        name=f"narrow{bit_depth}", optics=optics, detector=det, exposure_s=1.0, detection=logic
    )
