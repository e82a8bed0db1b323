"""Synthetic star fields for the attitude-estimator tests (imported by the tests; no tests here)."""

from __future__ import annotations

import numpy as np

ARCSEC = np.pi / (180.0 * 3600.0)


def star_field(rng: np.random.Generator, n: int, fov_deg: float) -> np.ndarray:
    """``n`` camera-frame unit vectors uniform on the cap of full angle ``fov_deg`` about +z."""
    half = np.radians(fov_deg / 2.0)
    cos_z = rng.uniform(np.cos(half), 1.0, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    sin_z = np.sqrt(1.0 - cos_z**2)
    return np.column_stack([sin_z * np.cos(phi), sin_z * np.sin(phi), cos_z])


def add_noise(rng: np.random.Generator, vectors: np.ndarray, sigma_rad) -> np.ndarray:
    """Displace unit vectors in their tangent planes by isotropic Gaussian noise of sigma rad
    per axis (the QUEST measurement model), then renormalise."""
    e = rng.normal(size=vectors.shape) * np.reshape(sigma_rad, (-1, 1))
    e -= np.sum(e * vectors, axis=1)[:, None] * vectors
    v = vectors + e
    return v / np.linalg.norm(v, axis=1)[:, None]
