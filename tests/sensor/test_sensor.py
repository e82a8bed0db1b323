"""Sensor model (TOML presets, validation, projection) and sensitivity models."""

from __future__ import annotations

import json
import math
import tomllib
from importlib import resources

import numpy as np
import pytest
from scipy.integrate import quad

from starsense.errors import InputError
from starsense.photometry.sensitivity import (
    REED_PHI0_PHOTONS_M2_S,
    Sensitivity,
    liebe_zero_mag_electron_rate,
)
from starsense.sensor import load_sensor, preset_names, sensor_from_dict


def _st16_dict():
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    return tomllib.loads(text)


def test_presets_load():
    assert {"st16", "esa_blackfly"} <= set(preset_names())
    s = load_sensor("st16")
    assert s.detector.columns == 2592 and s.detector.rows == 1944
    assert s.detector.saturation_counts == 4095


def test_dzamba2014_st16_geometry():
    s = load_sensor("st16")
    # ST-16: 7.5 deg half-axis field across the minor axis (paper Table 1); the f = 16 mm pinhole
    # over 1944 x 2.2 um gives atan(2.1384 / 16) = 7.61 deg: 0.15 deg tolerance.
    assert math.degrees(s.half_fov_rad[1]) == pytest.approx(7.5, abs=0.15)
    # eq. 1: cross-axis streak f tan(w t) / pitch; eq. 2: roll arc (h/2) tan(w t); their ratio at
    # equal rates is 2f/h = 7.5 for the ST-16 (paper sec. 2.1), to the 0.1 % of tan vs angle.
    w = math.radians(1.0)
    assert s.streak_length_px(w) == pytest.approx(16e-3 * math.tan(0.1 * w) / 2.2e-6, rel=1e-12)
    assert s.streak_length_px(w) / s.roll_arc_px(w) == pytest.approx(7.48, rel=1e-3)


def test_esa_blackfly_matches_reference_fov(shared_dir):
    ref = json.loads((shared_dir / "data/images/esa/reference.json").read_text())
    s = load_sensor("esa_blackfly")
    fov_deg = 2 * math.degrees(s.half_fov_rad[0])
    # reference.json: 11.42 deg horizontal field; the frames' own solutions span 11.422-11.425
    assert fov_deg == pytest.approx(ref["camera"]["horizontal_fov_deg"], abs=0.01)
    assert s.detector.columns == ref["camera"]["width_px"]


def test_project_unproject_roundtrip_with_distortion():
    d = _st16_dict()
    d["optics"]["distortion_k1"] = 0.05
    d["optics"]["distortion_k2"] = -0.01
    s = sensor_from_dict(d)
    v = np.random.default_rng(0).normal(size=(200, 3)) * [0.1, 0.1, 0] + [0, 0, 1]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    x, y = s.project(v)
    assert np.allclose(s.unproject(x, y), v, atol=1e-12)


def test_boresight_projects_to_centre():
    s = load_sensor("st16")
    x, y = s.project(np.array([[0.0, 0.0, 1.0]]))
    assert (x[0], y[0]) == ((2592 - 1) / 2, (1944 - 1) / 2)


@pytest.mark.parametrize(
    ("section", "key", "value", "message"),
    [
        (
            "detector",
            "pixel_pitch_m",
            -2.2e-6,
            r"detector.pixel_pitch_m = -2.2e-06 is out of range",
        ),
        (
            "detector",
            "bit_depth",
            0,
            r"detector.bit_depth = 0 is out of range; must be in \[1, 32\]",
        ),
        ("detector", "bit_depth", 33, r"detector.bit_depth = 33 is out of range"),
        ("detector", "columns", 0, r"detector.columns = 0 is out of range"),
        ("detector", "psf_sigma_px", float("nan"), r"detector.psf_sigma_px must be finite"),
        ("detection", "connectivity", 6, r"detection.connectivity must be 4 or 8"),
        ("optics", "focal_length_m", "16mm", r"optics.focal_length_m must be a number"),
    ],
)
def test_bad_values_name_the_field(section, key, value, message):
    d = _st16_dict()
    d[section][key] = value
    with pytest.raises(InputError, match=message):
        sensor_from_dict(d, "mine.toml")


def test_unknown_and_missing_keys(tmp_path):
    d = _st16_dict()
    d["detector"]["pixel_pich_m"] = 1e-6
    with pytest.raises(
        InputError, match=r"mine.toml: unknown key\(s\) pixel_pich_m in \[detector\]"
    ):
        sensor_from_dict(d, "mine.toml")
    d = _st16_dict()
    del d["detector"]["rows"]
    with pytest.raises(InputError, match=r"missing key\(s\) rows in \[detector\]"):
        sensor_from_dict(d, "mine.toml")
    d = _st16_dict()
    d["exposure"] = 1
    with pytest.raises(InputError, match=r"unknown top-level key\(s\) exposure"):
        sensor_from_dict(d, "mine.toml")


def test_load_sensor_errors(tmp_path):
    with pytest.raises(InputError, match="unknown sensor 'nosuch'"):
        load_sensor("nosuch")
    bad = tmp_path / "bad.toml"
    bad.write_text("exposure_s = = 1\n")
    with pytest.raises(InputError, match=r"bad\.toml: not valid TOML"):
        load_sensor(bad)
    with pytest.raises(InputError, match="sensor file not found"):
        load_sensor(tmp_path / "absent.toml")


def test_user_toml_copy_of_preset(tmp_path):
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    path = tmp_path / "mine.toml"
    path.write_text(text.replace("exposure_s = 0.100", "exposure_s = 0.05"))
    assert load_sensor(path).exposure_s == 0.05


def test_dzamba2014_reed_eq8_by_hand():
    # eq. 8 for the ST-16 at m = 0: 1/4 * 0.40 * 0.1 s * pi * (0.012 m)^2 * 1.8e10 = 81,430 e-
    s = load_sensor("st16")
    e = Sensitivity.for_sensor(s, "reed").electrons(0.0)
    assert e == pytest.approx(0.25 * 0.40 * 0.1 * math.pi * 0.012**2 * REED_PHI0_PHOTONS_M2_S)
    # five magnitudes are a factor 100 exactly (10^(-0.4 m))
    assert Sensitivity.for_sensor(s, "reed").electrons(5.0) == pytest.approx(e / 100, rel=1e-12)


def test_dzamba2014_liebe_about_twice_reed():
    # Paper sec. 2.2: "The Liebe sensitivity model predicts integrated intensities approximately
    # twice that of the Reed sensitivity model." Ours: 2.24 at m = 0 (same mean QE of 0.40).
    s = load_sensor("st16")
    ratio = Sensitivity.for_sensor(s, "liebe").electrons(0.0) / Sensitivity.for_sensor(
        s, "reed"
    ).electrons(0.0)
    assert 1.7 < ratio < 2.7


def test_liebe_flat_qe_equals_photon_count_of_scaled_blackbody():
    # Independent computation: photons of a 5800 K black body carrying 2.96e-8 W m^-2 in total,
    # between 400 and 800 nm, by a separate quadrature (QE = 1).
    h, c, k = 6.62607015e-34, 299792458.0, 1.380649e-23

    def planck(lam):
        return 2 * math.pi * h * c**2 / lam**5 / math.expm1(h * c / (lam * k * 5800.0))

    sigma_t4 = 5.670374419e-8 * 5800.0**4
    n, _ = quad(lambda lam: planck(lam) * lam / (h * c), 400e-9, 800e-9)
    expected = n * 2.96e-8 / sigma_t4
    got = liebe_zero_mag_electron_rate(lambda lam: np.ones_like(lam))
    assert got == pytest.approx(expected, rel=1e-5)


def test_blackbody_model_needs_colour_and_rejects_unknown_model():
    s = load_sensor("st16")
    with pytest.raises(InputError, match="needs each star's colour index"):
        Sensitivity.for_sensor(s, "blackbody").electrons(3.0)
    with pytest.raises(InputError, match="unknown sensitivity model 'foo'"):
        Sensitivity.for_sensor(s, "foo")
    e = Sensitivity.for_sensor(s, "blackbody").electrons(3.0, 0.65)
    assert e > 0
