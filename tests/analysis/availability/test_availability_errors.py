"""Bad input: specific InputError messages that name the option and the value."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.analysis.availability import (
    AvailabilityAnalysis,
    FieldStars,
    ThresholdCurve,
    catalog_stars,
    field_of_view,
    sky_attitudes,
    track_family_attitudes,
)
from starsense.errors import InputError
from starsense.geometry.fov import CircularFov
from starsense.sensor import load_sensor


@pytest.fixture(scope="module")
def analysis():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(500, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    return AvailabilityAnalysis(
        v, rng.uniform(0, 6, 500), CircularFov(0.15), max_mag=6.0, n_orientations=200
    )


FLAT = ThresholdCurve.constant(5.0)


@pytest.mark.parametrize("n_min", [0, -1])
def test_n_min_below_one(analysis, n_min):
    with pytest.raises(InputError, match=rf"n_min must be >= 1, got {n_min}"):
        analysis.static(n_min)
    with pytest.raises(InputError, match=r"n_min"):
        analysis.dynamic(FLAT, np.radians([1.0]), n_min)
    with pytest.raises(InputError, match=r"n_min"):
        analysis.track(FLAT, np.radians(1.0), n_min=n_min, n_samples=10)


@pytest.mark.parametrize("n_min", [2.5, "3", True])
def test_n_min_not_an_integer(analysis, n_min):
    with pytest.raises(InputError, match=r"n_min must be an integer"):
        analysis.static(n_min)


def test_negative_rate(analysis):
    with pytest.raises(InputError, match=r"rates_rad_s = -0.01745\d* is negative"):
        analysis.dynamic(FLAT, np.radians([1.0, -1.0]))
    with pytest.raises(InputError, match=r"rate_rad_s = -0.00872\d* is negative"):
        analysis.track(FLAT, np.radians(-0.5), n_samples=10)
    with pytest.raises(InputError, match=r"must be finite"):
        analysis.dynamic(FLAT, [float("nan")])
    with pytest.raises(InputError, match=r"negative"):
        FLAT([-2.0])


def test_zero_samples(analysis):
    with pytest.raises(InputError, match=r"n_orientations must be >= 1, got 0"):
        AvailabilityAnalysis(analysis.vectors, analysis.magnitudes, analysis.fov, n_orientations=0)
    with pytest.raises(InputError, match=r"n_orientations"):
        sky_attitudes(0)
    with pytest.raises(InputError, match=r"n_samples must be >= 1, got 0"):
        analysis.track(FLAT, np.radians(1.0), n_samples=0)
    with pytest.raises(InputError, match=r"n_samples"):
        track_family_attitudes([0.0], 0)


def test_magnitude_limit_leaving_no_stars(analysis):
    catalog = SimpleNamespace(
        name="tiny", vectors=np.eye(3), mags={"V": np.array([1.0, 2.0, np.nan])}
    )
    with pytest.raises(
        InputError, match=r"max_mag -3 leaves no stars of catalogue 'tiny' \(brightest V = 1.00"
    ):
        catalog_stars(catalog, -3.0)
    with pytest.raises(InputError, match=r"max_mag -3 leaves no stars"):
        AvailabilityAnalysis.from_catalog(catalog, CircularFov(0.1), -3.0)
    with pytest.raises(InputError, match=r"max_mag -3 leaves no stars"):
        AvailabilityAnalysis(analysis.vectors, analysis.magnitudes, analysis.fov, max_mag=-3)
    with pytest.raises(InputError, match=r"max_mag must be finite"):
        catalog_stars(catalog, float("nan"))
    with pytest.raises(InputError, match=r"no B magnitudes"):
        catalog_stars(catalog, 5.0, band="B")


def test_bad_field_options():
    st16 = load_sensor("st16")
    with pytest.raises(InputError, match=r"kind must be 'circular' or 'rectangular'"):
        field_of_view(st16, "hexagonal")
    with pytest.raises(InputError, match=r"half_fov sets the circular field only"):
        field_of_view(st16, "rectangular", math.radians(7.5))
    with pytest.raises(InputError, match=r"half_fov = 0.0 is out of range"):
        field_of_view(st16, "circular", 0.0)
    assert math.degrees(field_of_view(st16).half_angle_rad) == pytest.approx(7.61, abs=0.01)
    assert field_of_view(st16, half_fov=math.radians(7.5)).half_angle_rad == math.radians(7.5)


def test_bad_threshold_curves():
    with pytest.raises(InputError, match=r"strictly increasing"):
        ThresholdCurve([0.0, 2.0, 1.0], [5, 4, 3])
    with pytest.raises(InputError, match=r"one magnitude per rate"):
        ThresholdCurve([0.0, 1.0], [5.0])
    with pytest.raises(InputError, match=r"max_mag must be finite"):
        ThresholdCurve([0.0], [np.inf])
    with pytest.raises(InputError, match=r"no magnitude is detected even at rest"):
        ThresholdCurve.from_tolerance([4.0, 5.0], [None, None])
    with pytest.raises(InputError, match=r"tolerance JSON: expected the output"):
        ThresholdCurve.from_tolerance_dict({"rates": []})


def test_field_stars_rejects_bad_arrays():
    with pytest.raises(InputError, match=r"magnitudes must be finite"):
        FieldStars.build(CircularFov(0.1), Rotation.random(2), np.eye(3), [1, 2, np.nan])
    with pytest.raises(InputError, match=r"vectors must be \(N, 3\)"):
        FieldStars.build(CircularFov(0.1), Rotation.random(2), np.eye(3), [1, 2])
