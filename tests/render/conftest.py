"""Fixtures of the render tests: the ST-16 sensor and small synthetic catalogues."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.catalog.table import Catalog
from starsense.geometry.attitude import attitude_from_radec_roll, radec_to_vectors
from starsense.sensor import load_sensor

#: boresight of the synthetic field, rad
RA0, DEC0, ROLL0 = math.radians(120.0), math.radians(-30.0), math.radians(20.0)


@pytest.fixture(scope="session")
def st16():
    return load_sensor("st16")


@pytest.fixture(scope="session")
def attitude():
    return attitude_from_radec_roll(RA0, DEC0, ROLL0)


def synthetic_catalog(n: int = 60, radius_deg: float = 14.0, seed: int = 5) -> Catalog:
    """Stars uniform within ``radius_deg`` of the synthetic boresight, V 2-6, B-V 0-1.5.

    Star 0 sits exactly on the boresight (id 1000), with V = 3.
    """
    rng = np.random.default_rng(seed)
    centre = radec_to_vectors(RA0, DEC0)
    # uniform on the spherical cap, then rotated from the pole to the centre
    cos_r = rng.uniform(math.cos(math.radians(radius_deg)), 1.0, n)
    phi = rng.uniform(0.0, 2 * math.pi, n)
    sin_r = np.sqrt(1 - cos_r**2)
    local = np.stack([sin_r * np.cos(phi), sin_r * np.sin(phi), cos_r], axis=1)
    local[0] = (0.0, 0.0, 1.0)
    z = centre
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    v = local @ np.stack([x, y, z])
    ra = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2 * math.pi)
    dec = np.arcsin(np.clip(v[:, 2], -1, 1))
    vmag = rng.uniform(2.0, 6.0, n)
    vmag[0] = 3.0
    bv = rng.uniform(0.0, 1.5, n)
    return Catalog(
        name="synthetic",
        source="tests/render/conftest.py",
        epoch_yr=2000.0,
        ids=np.arange(1000, 1000 + n),
        ra_rad=ra,
        dec_rad=dec,
        mags={"V": vmag, "B": vmag + bv},
        colours={"B-V": bv},
    )


@pytest.fixture(scope="session")
def catalog() -> Catalog:
    return synthetic_catalog()


@pytest.fixture(scope="session")
def make_catalog():
    """The :func:`synthetic_catalog` factory."""
    return synthetic_catalog


@pytest.fixture(scope="session")
def pointing() -> tuple[float, float, float]:
    """(RA, Dec, roll) of the synthetic boresight, rad."""
    return RA0, DEC0, ROLL0
