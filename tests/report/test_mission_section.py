"""The report's mission section, from a sensor TOML with a [mission] table."""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.photometry.stars import BlackBodyStars
from starsense.report.mission import mission_section
from starsense.report.section import ReportContext
from starsense.sensor import load_sensor

MISSION = """
[mission]
name = "test"
orbit = "sso:550:6"
attitude = "nadir"
heads = ["x:180=zenith", "0.7071068,0,0,0.7071068=+Y", ""]
start = "2025-03-20T00:00:00"
duration_h = 2.0
step_s = 20.0
"""


def _toml(tmp_path, extra: str):
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    path = tmp_path / "st16_mission.toml"
    path.write_text(text + extra)
    return path


def _stars(n=6000, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    ones = np.ones(n)
    return BlackBodyStars(v, 6000 * ones, 1e-16 * ones, 6.3 - rng.exponential(1.1, n), "B-V")


def _ctx(tmp_path, sensor):
    return ReportContext(
        work_dir=tmp_path,
        catalog_name="synthetic",
        n_catalog=6000,
        stars={"B-V": _stars()},
        diameter_m=0.1,
        exposure_s=0.01,
        sensor=sensor,
        slew_trials=2,
    )


def test_mission_section_from_toml(tmp_path):
    sensor = load_sensor(_toml(tmp_path, MISSION))
    assert sensor.mission.heads == ("x:180=zenith", "0.7071068,0,0,0.7071068=+Y", "")
    sec = mission_section(_ctx(tmp_path, sensor))
    assert sec.key == "mission" and (tmp_path / sec.figures[0]).stat().st_size > 10_000
    heads = {h["name"]: h for h in sec.data["heads"]}
    assert set(heads) == {"zenith", "+Y", "st16"}
    # a horizontal boresight at 550 km is 90 - asin(6478/6928) = 20.8 deg above the limb
    # raised by 100 km: inside the preset's 25 deg; the zenith head never sees the Earth and
    # the nadir (body +z, no mounting) head always does
    assert heads["+Y"]["earth_blinded_fraction"] == 1.0
    assert heads["zenith"]["earth_blinded_fraction"] == 0.0
    assert heads["st16"]["earth_blinded_fraction"] == 1.0
    assert sec.data["steps"] == 360
    assert "Mission availability" in sec.summary[0][0]
    assert math.isfinite(sec.data["combined"]["available_fraction"])


def test_no_mission_placeholder(tmp_path):
    sec = mission_section(_ctx(tmp_path, load_sensor("st16")))
    assert sec.figures == () and "names no mission" in sec.html


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ('[mission]\norbit = "sso:550"\nspin = 1\n', r"unknown key\(s\) spin"),
        ('[mission]\nattitude = "nadir"\n', "needs orbit"),
        ('[mission]\norbit = "sso:550"\nstep_s = 0\n', r"mission\.step_s = 0 is out of range"),
        ('[mission]\norbit = "sso:550"\nheads = []\n', "heads must be a non-empty list"),
    ],
)
def test_mission_table_errors_name_file_and_key(tmp_path, extra, message):
    path = _toml(tmp_path, extra)
    with pytest.raises(InputError, match=message) as info:
        load_sensor(path)
    assert str(path) in str(info.value)
