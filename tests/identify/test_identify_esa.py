"""The eight ESA night-sky frames (shared/data/images/esa) must solve, with the field known and
unknown, to within 15 arcsec of the reference boresights (reference.json: cedar-solve, its own
fit residual 5-7 arcsec RMS; LOST agrees within ~10 arcsec)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from identify_helpers import sensor_with_fov

from starsense.detect import StarDetector
from starsense.geometry.attitude import (
    angular_separation,
    radec_roll_from_attitude,
    radec_to_vectors,
)
from starsense.identify import HashIdentifier, TriangleIdentifier, build_database
from starsense.sensor import load_sensor

ARCSEC = math.radians(1.0 / 3600.0)
ESA_FOV_RAD = math.radians(11.42)


@pytest.fixture(scope="module")
def esa(shared_dir):
    """(reference frames, {name: vectors_cam}, {name: (x, y)}) of the eight frames."""
    from PIL import Image

    folder = shared_dir / "data" / "images" / "esa"
    reference = json.loads((folder / "reference.json").read_text())["frames"]
    sensor = load_sensor("esa_blackfly")
    detector = StarDetector(sensor.detection, background="auto", threshold_sigma=5)
    pixels = {}
    for name in reference:
        det = detector(np.array(Image.open(folder / name)))
        pixels[name] = (det.x, det.y)
    return reference, sensor, pixels


def _boresight_error_rad(result, ref) -> float:
    ra, dec, _ = radec_roll_from_attitude(result.rotation)
    truth = radec_to_vectors(math.radians(ref["ra_deg"]), math.radians(ref["dec_deg"]))
    return float(angular_separation(radec_to_vectors(ra, dec), truth))


def test_esa_frames_known_fov(esa, hipparcos):
    reference, sensor, pixels = esa
    fov = 2.0 * sensor.half_fov_rad[0]
    identify = HashIdentifier(build_database(hipparcos, fov))
    for name, ref in reference.items():
        result = identify(sensor.unproject(*pixels[name]), fov)
        assert result.solved, f"{name}: {result}"
        assert _boresight_error_rad(result, ref) < 15 * ARCSEC, name
        _, _, roll = radec_roll_from_attitude(result.rotation)
        droll = (math.degrees(roll) - ref["roll_deg"] + 180.0) % 360.0 - 180.0
        assert abs(droll) < 0.05, name
        assert result.n_matches >= 0.8 * ref["matched_stars"], name
        assert result.residual_rms_rad < 30 * ARCSEC
        assert result.false_match_probability < 1e-20


def test_esa_frames_triangle(esa, hipparcos):
    reference, sensor, pixels = esa
    fov = 2.0 * sensor.half_fov_rad[0]
    identify = TriangleIdentifier(build_database(hipparcos, fov))
    for name, ref in reference.items():
        result = identify(sensor.unproject(*pixels[name]), fov)
        assert result.solved, f"{name}: {result}"
        assert _boresight_error_rad(result, ref) < 15 * ARCSEC, name


@pytest.mark.parametrize("assumed_deg", [9.0, 14.0])
def test_esa_frames_unknown_fov(esa, hipparcos, assumed_deg):
    """Centroids unprojected with a lens 20 % off; a 5-30 deg database finds the field."""
    reference, _, pixels = esa
    db = build_database(hipparcos, math.radians(30), math.radians(5), patterns_per_field=50)
    identify = HashIdentifier(db)
    assumed = math.radians(assumed_deg)
    wrong = sensor_with_fov(assumed)
    for name, ref in reference.items():
        result = identify(wrong.unproject(*pixels[name]), None, assumed_fov_rad=assumed)
        assert result.solved, f"{name}: {result}"
        assert result.fov_rad == pytest.approx(ESA_FOV_RAD, rel=0.01), name
        assert result.fov_rad == pytest.approx(math.radians(ref["fov_deg"]), rel=0.002), name
        assert _boresight_error_rad(result, ref) < 15 * ARCSEC, name
