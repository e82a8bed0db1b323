"""No wrong attitude on frames that are not a plain view of the sky.

Each frame is rendered by our renderer through the ESA camera's 1024 x 768 detector (100-count
bias) behind a pinhole lens of 20 deg, seeded; the sky is Hipparcos to V = 8 (Orion).

* rotated by 180 deg (``np.rot90(image, 2)``): the same sky, so it solves, to the truth turned by
  180 deg about the boresight (roll + 180);
* mirrored (``image[:, ::-1]``): the handedness of the sky is wrong, no proper rotation fits it;
  the parity check (:mod:`starsense.solve.parity`) solves the mirror image and reports
  "mirrored" with the truth attitude, never "solved";
* the field given wrong by -30 % or +50 %: solved right after the scale search, or not at all;
* pure noise, and random points: no attitude.

Tolerances: a right solution puts the boresight within a fraction of a 70-arcsec pixel (tens of
bright stars centroided to ~0.1 px: measured 0.6 arcsec), so 0.5 px (35 arcsec) is tight for a
right answer while a wrong identification is off by degrees. Roll about the boresight is the
weak axis: ~0.1 px over a lever arm of ~400 px is ~0.015 deg; 0.05 deg (measured 0.0007).
"""

from __future__ import annotations

import dataclasses
import math
from importlib.resources import files

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.geometry.attitude import (
    angular_separation,
    attitude_from_radec_roll,
    radec_roll_from_attitude,
)
from starsense.render.noise import apply_noise
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.parity import MIRRORED, mirror_x
from starsense.solve.solver import Solver

FOV_DEG = 20.0
PIXEL_RAD = math.radians(FOV_DEG) / 1024
TRUTH = attitude_from_radec_roll(*(math.radians(a) for a in (83.8, -5.4, 30.0)))
#: the truth turned by 180 deg about the boresight (camera z): the attitude of rot90(image, 2)
TRUTH_180 = Rotation.from_rotvec([0.0, 0.0, math.pi]) * TRUTH


def _sensor():
    base = load_sensor("esa_blackfly")
    width = base.detector.columns * base.detector.pixel_pitch_m
    focal = width / 2.0 / math.tan(math.radians(FOV_DEG) / 2.0)
    return base.with_(
        optics=dataclasses.replace(base.optics, focal_length_m=focal),
        detector=dataclasses.replace(base.detector, bias_counts=100.0),
    )


@pytest.fixture(scope="module")
def sensor():
    return _sensor()


@pytest.fixture(scope="module")
def image(sensor):
    return render_frame(sensor, TRUTH, load_catalog("hipparcos"), max_mag=8.0, rng=3).image


@pytest.fixture(scope="module")
def solvers(sensor):
    return {"sensor": Solver(sensor), "fov": Solver(fov_rad=math.radians(FOV_DEG))}


def _assert_attitude(sol, truth) -> None:
    boresight = float(
        angular_separation(sol.rotation.inv().apply([0, 0, 1]), truth.inv().apply([0, 0, 1]))
    )
    assert boresight < 0.5 * PIXEL_RAD, boresight / PIXEL_RAD
    droll = (sol.roll_rad - attitude_roll(truth) + math.pi) % (2 * math.pi) - math.pi
    assert abs(droll) < math.radians(0.05), math.degrees(droll)


def attitude_roll(rotation) -> float:
    return float(radec_roll_from_attitude(rotation)[2])


def test_mirror_x_is_the_column_flip():
    # the centroid of column c in image[:, ::-1] is at width - 1 - c (pixel centres at integers)
    cols = np.arange(7)
    flipped = np.zeros((1, 7))
    flipped[0, 2] = 1.0
    assert mirror_x([2.0], 7)[0] == np.flatnonzero(flipped[:, ::-1][0])[0] == 4
    np.testing.assert_array_equal(mirror_x(mirror_x(cols, 7), 7), cols)


@pytest.mark.parametrize("optics", ["sensor", "fov"])
def test_plain_frame_solves_without_the_parity_check(solvers, image, optics):
    sol = solvers[optics](image)
    assert sol.status == "solved", sol.message
    _assert_attitude(sol, TRUTH)


@pytest.mark.parametrize("optics", ["sensor", "fov"])
def test_frame_rotated_180_solves_to_roll_plus_180(solvers, image, optics):
    sol = solvers[optics](np.rot90(image, 2))
    assert sol.status == "solved", sol.message
    _assert_attitude(sol, TRUTH_180)
    droll = math.degrees(sol.roll_rad - attitude_roll(TRUTH)) % 360.0
    assert droll == pytest.approx(180.0, abs=0.05)


@pytest.mark.parametrize(
    "optics",
    # with only a field given, a frame that fails at it is first searched over every scale
    # (the narrow range loads the Gaia database) before its mirror image is tried
    ["sensor", pytest.param("fov", marks=pytest.mark.slow)],
)
def test_mirrored_frame_is_reported_mirrored_never_solved(solvers, image, optics):
    sol = solvers[optics](image[:, ::-1])
    assert sol.status == MIRRORED and not sol.solved, (sol.status, sol.message)
    assert "mirrored" in sol.message
    _assert_attitude(sol, TRUTH)  # the attitude of the flipped-back frame: the truth
    # an up-down flip is a mirror too; flipped left-right it is the frame turned by 180 deg
    sol = solvers[optics](image[::-1, :])
    assert sol.status == MIRRORED, (sol.status, sol.message)
    _assert_attitude(sol, TRUTH_180)


@pytest.mark.slow  # builds the databases of two more fields and searches the scale
@pytest.mark.parametrize("factor", [0.7, 1.5])
def test_wrong_field_given_never_gives_a_wrong_attitude(image, factor):
    # the given field fails; the scale search around it finds the true one (measured: both
    # solve, boresight 0.7 arcsec, field within 0.1 %)
    sol = Solver(fov_rad=math.radians(FOV_DEG * factor))(image)
    assert sol.rotation is None or sol.status == "solved", sol.status
    assert sol.status == "solved", sol.message
    _assert_attitude(sol, TRUTH)
    assert sol.fov_deg == pytest.approx(FOV_DEG, rel=3e-3)  # 3 px over the 1024 px width


def _noise_frames(sensor, n: int):
    shape = (sensor.detector.rows, sensor.detector.columns)
    return [apply_noise(np.zeros(shape), sensor, rng=np.random.default_rng(s)) for s in range(n)]


def _assert_no_attitude(sol) -> None:
    assert sol.rotation is None and sol.status not in ("solved", MIRRORED), sol.status


def test_pure_noise_frames_give_no_attitude(sensor, solvers):
    for frame in _noise_frames(sensor, 4):
        _assert_no_attitude(solvers["sensor"](frame))


@pytest.mark.slow  # each failure with a field given searches every scale, twice (parity)
def test_pure_noise_frames_at_a_low_threshold_give_no_attitude(sensor):
    # noise alone at a low threshold (3 sigma, matched filter) gives candidates, that reach
    # identification (and the parity check), never an attitude
    loose = Solver(fov_rad=math.radians(FOV_DEG), threshold_sigma=3.0)
    n_candidates = 0
    for frame in _noise_frames(sensor, 2):
        sol = loose(frame)
        _assert_no_attitude(sol)
        n_candidates += sol.n_detections
    assert n_candidates >= 6  # noise did reach identification (3 candidates a frame at least)


@pytest.mark.parametrize("optics", ["sensor", pytest.param("fov", marks=pytest.mark.slow)])
def test_random_points_give_no_attitude(solvers, optics):
    # 20 random centroids, brightest first: the points and their mirror image both fail
    rng = np.random.default_rng(13)
    for _ in range(10 if optics == "sensor" else 3):
        xy = rng.uniform((0, 0), (1023, 767), size=(20, 2))
        _assert_no_attitude(solvers[optics].solve_centroids(xy, (1024, 768)))


def test_cli_prints_mirrored_and_exits_1(image, tmp_path, capsys):
    from PIL import Image

    # the test sensor as a TOML file: the preset with this focal length and bias
    preset = files("starsense.sensor.presets").joinpath("esa_blackfly.toml").read_text()
    sensor = _sensor()
    toml = preset.replace(
        "focal_length_m = 0.03533", f"focal_length_m = {sensor.optics.focal_length_m!r}"
    )
    toml = toml.replace("bias_counts = 0.0", "bias_counts = 100.0")
    (tmp_path / "cam.toml").write_text(toml)
    path = tmp_path / "mirrored.tiff"
    Image.fromarray(np.ascontiguousarray(image[:, ::-1]).astype(np.uint16)).save(path)
    code = main(["solve", str(path), "--sensor", str(tmp_path / "cam.toml")])
    out = capsys.readouterr().out
    assert code == 1
    assert "not solved (mirrored)" in out and "flipped frame: RA 83.8" in out
