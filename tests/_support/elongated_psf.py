"""A sensor whose PSF is an elliptical Gaussian: an astigmatic lens's image, as an empirical PSF."""

from __future__ import annotations

import numpy as np

from starsense.sensor.psf_spec import PSFSpec


def elongated(sensor, sigma_major, sigma_minor, turn_rad, oversampling=8):
    """Return ``sensor`` with an empirical PSF: an elliptical Gaussian turned by ``turn_rad``."""
    half = 12 * oversampling
    g = (np.arange(2 * half + 1) - half) / oversampling
    x, y = np.meshgrid(g, g)
    c, s = np.cos(turn_rad), np.sin(turn_rad)
    u, w = c * x + s * y, -s * x + c * y
    samples = np.exp(-0.5 * (u / sigma_major) ** 2 - 0.5 * (w / sigma_minor) ** 2)
    spec = PSFSpec(kind="empirical", samples=samples / samples.sum(), oversampling=oversampling,
                   source="elliptical Gaussian")  # fmt: skip
    return sensor.with_(psf=spec)
