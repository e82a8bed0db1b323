"""A background clipped at the ADC's zero: an empty pixel's moments.

At a bias of a few sigma of the read noise or less the ADC clips the noise below zero: the
background is a rectified, rounded Gaussian. Its moments (render.noise.empty_pixel_moments,
which the datasheet's warning quotes) are checked against the renderer's own pixels
(apply_noise, seeded) and the closed form of a rectified Gaussian.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.render.noise import apply_noise, empty_pixel_moments
from starsense.sensor import DetectionThresholds, Sensor
from starsense.sensor.detector import Detector
from starsense.sensor.optics import Optics


def _sensor(*, bias_counts: float, read_noise_e: float = 10.0, gain: float = 0.1, **det):
    """A 1024 x 768 camera of 5.5 um pixels; the detection logic at 5 sigma of the noise."""
    detector = Detector(
        columns=1024,
        rows=768,
        pixel_pitch_m=5.5e-6,
        gain_counts_per_e=gain,
        read_noise_e=read_noise_e,
        bit_depth=det.pop("bit_depth", 16),
        psf_sigma_px=det.pop("psf_sigma_px", 1.0),
        full_well_e=det.pop("full_well_e", 45000.0),
        bias_counts=bias_counts,
        **det,
    )
    sigma = math.sqrt((gain * read_noise_e) ** 2 + 1.0 / 12.0)
    # 5 sigma, or what the ADC leaves above a bias near its top
    lit = min(5.0 * sigma, detector.saturation_counts - bias_counts - 1.0)
    n_pix = 2 if detector.psf_sigma_px < 0.8 else 3
    area = max(4.0 * math.pi * detector.psf_sigma_px**2, 1.0)
    return Sensor(
        name="clip",
        optics=Optics(focal_length_m=0.025, aperture_m=0.0125, transmission=0.8),
        detector=detector,
        exposure_s=0.1,
        detection=DetectionThresholds(
            lit_pixel_counts=lit,
            min_pixels=n_pix,
            min_integrated_counts=max(5.0 * sigma * math.sqrt(area), lit * n_pix),
        ),
    )


@pytest.mark.parametrize(
    ("bias", "read_noise_e", "gain", "bits"),
    [
        (0.0, 10.0, 0.1, 16),  # 1 count of noise at 0: half the pixels read 0
        (1.0, 6.0, 0.25, 12),  # 1.5 counts at 0.67 sigma
        (0.0, 49.0, 1.0, 16),  # 49 counts at 0
        (0.0, 3.0, 0.1, 12),  # 0.3 counts: the rounding dominates
        (8.0, 10.0, 0.1, 16),  # 8 sigma: a rounded Gaussian
        (252.0, 1.0, 2.0, 8),  # 8-bit, 1.5 sigma below its top count (255): clipped there
    ],
)
def test_empty_pixel_moments_match_the_rendered_pixels(bias, read_noise_e, gain, bits):
    # one million empty pixels of the renderer: the sample mean is known to sqrt(var / n)
    # (4 standard errors allowed), the sample variance to var sqrt((kurtosis - 1) / n), at
    # most 0.3 % for these clipped Gaussians (1 % allowed: the old model, the unclipped
    # variance, is 2.5 x too large at a bias of 0)
    sensor = _sensor(bias_counts=bias, read_noise_e=read_noise_e, gain=gain, bit_depth=bits)
    pixels = apply_noise(np.zeros((1000, 1000)), sensor, rng=11).astype(float)
    mean, var = empty_pixel_moments(sensor.detector)
    assert pixels.mean() == pytest.approx(mean, abs=4.0 * math.sqrt(var / pixels.size))
    assert pixels.var() == pytest.approx(var, rel=0.01)


def test_empty_pixel_moments_closed_forms():
    # far above zero: the mean is the bias, the variance s^2 + 1/12 (Sheppard's correction of
    # the rounding, exact to exp(-2 pi^2 s^2) ~ 1e-34 at s = 2 counts)
    mean, var = empty_pixel_moments(_sensor(bias_counts=40.0, read_noise_e=20.0).detector)
    assert mean == pytest.approx(40.0, abs=1e-9)
    assert var == pytest.approx(4.0 + 1.0 / 12.0, rel=1e-9)
    # at a bias of 0 and 50 counts of noise: the rectified Gaussian, mean s / sqrt(2 pi),
    # variance s^2 (1/2 - 1/(2 pi)) + 1/24 (half the pixels rounded); the rounding near zero
    # (the values in [0, 0.5) read 0) moves the mean by < 0.25 P(0 < X < 0.5) = 0.001 counts
    s = 50.0
    mean, var = empty_pixel_moments(_sensor(bias_counts=0.0, read_noise_e=500.0).detector)
    assert mean == pytest.approx(s / math.sqrt(2.0 * math.pi), abs=2e-3)
    assert var == pytest.approx(s * s * (0.5 - 0.5 / math.pi) + 1.0 / 24.0, rel=1e-4)
    # dark signal: its mean adds to the bias and its shot noise to the variance
    sensor = _sensor(bias_counts=40.0, read_noise_e=20.0, dark_current_e_s=100.0)
    mean, var = empty_pixel_moments(sensor.detector, dark_e=300.0)
    assert mean == pytest.approx(40.0 + 0.1 * 300.0, abs=1e-9)
    assert var == pytest.approx(0.01 * (400.0 + 300.0) + 1.0 / 12.0, rel=1e-9)
