"""Fixtures of the identification tests: the bundled Hipparcos and databases built from it."""

from __future__ import annotations

import pytest
from identify_helpers import SYNTH_FOV_RAD, sensor_with_fov

from starsense.catalog import load_catalog
from starsense.identify import build_database
from starsense.sensor import Sensor


@pytest.fixture(scope="session")
def hipparcos():
    return load_catalog("hipparcos")


@pytest.fixture(scope="session")
def db15(hipparcos):
    """Single-scale database for a 15 deg field."""
    return build_database(hipparcos, SYNTH_FOV_RAD)


@pytest.fixture(scope="session")
def synth_sensor() -> Sensor:
    return sensor_with_fov(SYNTH_FOV_RAD)
