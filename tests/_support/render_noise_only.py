"""A closed-shutter frame of a sensor: its read noise, bias and ADC only (render.noise)."""

from __future__ import annotations

import numpy as np

from starsense.render.noise import apply_noise


def dark_frame(sensor, seed: int = 0) -> np.ndarray:
    """Return a frame of no light, counts, as uint8 for 8-bit sensors."""
    det = sensor.detector
    image = apply_noise(np.zeros((det.rows, det.columns)), sensor, rng=seed)
    return image.astype(np.uint8) if det.bit_depth <= 8 else image
