"""Frames of an 8-bit science camera rendered by starsense.render: dark, quantised, clipped.

A 6 deg x 4.5 deg camera (1024 x 768 pixels of 5 um behind a 48.8 mm lens, 15 mm aperture),
8-bit ADC, gain 0.05 counts/e-: the read noise of 12-16 e- is 0.6-0.8 counts and the bias 0-2
counts, so the background sits at 0-2 counts with its noise clipped at zero. Sky
glow, a gradient and vignetting are added to the expected electrons before the noise; hot pixels
and JPEG compression after it.
"""

from __future__ import annotations

import io
import math

import numpy as np

from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render.noise import apply_noise
from starsense.render.scene import render_frame
from starsense.sensor.load import sensor_from_dict

COLUMNS, ROWS, PITCH_M = 1024, 768, 5e-6
FOV_RAD = math.radians(6.0)
FOCAL_M = COLUMNS * PITCH_M / (2 * math.tan(FOV_RAD / 2))


def camera8(bias_counts: float = 1.0, read_noise_e: float = 14.0, aperture_m: float = 0.015):
    """The 8-bit camera as a Sensor."""
    return sensor_from_dict(
        {
            "name": "camera8",
            "exposure_s": 0.5,
            "optics": {"focal_length_m": FOCAL_M, "aperture_m": aperture_m, "transmission": 1.0},
            "detector": {
                "columns": COLUMNS,
                "rows": ROWS,
                "pixel_pitch_m": PITCH_M,
                "bit_depth": 8,
                "gain_counts_per_e": 0.05,
                "read_noise_e": read_noise_e,
                "psf_sigma_px": 1.0,
                "qe_mean": 0.5,
                "bias_counts": bias_counts,
                "full_well_e": 20000.0,
            },
            "detection": {"lit_pixel_counts": 1.0, "min_pixels": 3, "min_integrated_counts": 0.0},
        }
    )


def frame8(
    sensor,
    catalog,
    ra_deg: float,
    dec_deg: float,
    roll_deg: float,
    *,
    seed: int = 0,
    sky_e: float = 0.0,
    gradient_e: float = 0.0,
    vignetting: float = 0.0,
    hot_pixels: int = 0,
    jpeg_quality: int | None = None,
):
    """Render one 8-bit frame; return (uint8 image, truth attitude, rendered frame).

    ``sky_e`` is a flat glow and ``gradient_e`` a glow rising across the columns, electrons per
    pixel; ``vignetting`` the fractional loss of light at the corners (cos^4-like, quadratic in
    the radius); ``hot_pixels`` pixels set to random values of 60-255 counts.
    """
    att = attitude_from_radec_roll(*np.radians([ra_deg, dec_deg, roll_deg]))
    fr = render_frame(sensor, att, catalog, rng=seed, noise=False)
    y, x = np.mgrid[0:ROWS, 0:COLUMNS].astype(np.float32)
    r2 = ((x - COLUMNS / 2) ** 2 + (y - ROWS / 2) ** 2) / ((COLUMNS / 2) ** 2 + (ROWS / 2) ** 2)
    expected = (fr.expected_e + sky_e + gradient_e * x / COLUMNS) * (1 - vignetting * r2)
    rng = np.random.default_rng(seed + 1000)
    image = apply_noise(expected, sensor, rng=rng).astype(np.uint8)
    if hot_pixels:
        rr = rng.integers(0, ROWS, hot_pixels)
        cc = rng.integers(0, COLUMNS, hot_pixels)
        image[rr, cc] = rng.integers(60, 256, hot_pixels)
    if jpeg_quality is not None:
        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(image).save(buf, format="JPEG", quality=jpeg_quality)
        buf.seek(0)
        image = np.array(Image.open(buf))
    return image, att, fr
