"""Bad input through the Python API: a :class:`~starsense.errors.InputError` naming the argument
and its value, never an AttributeError, a TypeError or a NumPy warning from deep inside.
"""

from __future__ import annotations

import math
import re
import tomllib

import numpy as np
import pytest
from bad_files import SENSOR_TOML

import starsense.analysis.slew as slew
from starsense.analysis.slew import simulate_slew
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render import render_frame
from starsense.sensor import load_sensor, sensor_from_dict
from starsense.solve.calibration import calibrate
from starsense.solve.solver import Solver
from starsense.solve.tracking import Tracker


def _sensor_data(**optics) -> dict:
    data = tomllib.loads(SENSOR_TOML)
    data["optics"].update(optics)
    return data


@pytest.mark.parametrize("data", [None, ["a"], "st16"])
def test_sensor_from_dict_refuses_what_is_not_a_table(data):
    with pytest.raises(InputError, match=r"^<dict>: a sensor must be a table"):
        sensor_from_dict(data)


@pytest.mark.parametrize(
    ("key", "value"), [("name", ["a"]), ("name", 5), ("description", 1.5), ("description", True)]
)
def test_text_fields_take_text_only(key, value):
    data = {**tomllib.loads(SENSOR_TOML), key: value}
    with pytest.raises(
        InputError, match=rf"^s\.toml: {key} must be text, got {re.escape(repr(value))}"
    ):
        sensor_from_dict(data, "s.toml")


def test_quoted_errors_name_the_file_once():
    data = {**tomllib.loads(SENSOR_TOML), "quoted": {"source": "x", "nea_cross_arcsec": -1.0}}
    with pytest.raises(InputError) as info:
        sensor_from_dict(data, "s.toml")
    assert str(info.value).count("s.toml") == 1


@pytest.mark.parametrize("axis", ["columns", "rows"])
def test_field_beyond_175_deg_is_refused_on_either_axis(axis):
    # 8000 px of 5 um = 40 mm behind 0.5 mm (at f/1): 2 atan(40 mm / 2 / 0.5 mm) = 177.1 deg
    data = _sensor_data(focal_length_m=0.0005)
    data["optics"]["aperture_m"] = 0.0005
    data["detector"][axis] = 8000
    with pytest.raises(InputError, match=rf"177\.1 deg across the {axis}"):
        sensor_from_dict(data)


def test_distortion_fold_is_refused_at_load_and_only_past_the_detector():
    # pure k1 < 0: r_d = r (1 + k1 r^2) turns back where 1 + 3 k1 r^2 = 0. The detector's
    # farthest pixel centre from the principal point sits at r_d = r_c (focal-length units);
    # r_d(r) reaches at most (2/3) r_f with r_f = 1 / sqrt(-3 k1), so the pixel has a
    # direction only while r_c < (2/3) / sqrt(-3 k1), i.e. k1 > -4 / (27 r_c^2)
    data = _sensor_data(focal_length_m=0.01)
    data["detector"].update(columns=1024, rows=1024)
    half = 511.5 * 5e-6 / 0.01
    r_c = math.hypot(half, half)
    k1_fold = -4.0 / (27.0 * r_c**2)
    assert sensor_from_dict(_with_k1(data, 0.95 * k1_fold)).optics.distortion_k1 < 0
    with pytest.raises(InputError, match=r"optics\.distortion_k1 = .* fold the image back"):
        sensor_from_dict(_with_k1(data, 1.05 * k1_fold))


def _with_k1(data: dict, k1: float) -> dict:
    return {**data, "optics": {**data["optics"], "distortion_k1": k1}}


def test_tracker_prior_must_be_a_prior():
    solver = Solver(load_sensor("st16"))
    with pytest.raises(InputError, match=r"prior must be a Prior .*got tuple \(1, 2, 3\)"):
        Tracker(solver, prior=(1, 2, 3))


@pytest.mark.parametrize("interval_s", [1e-300, 0.0, -1.0, math.inf])
def test_tracker_interval_is_bounded(interval_s):
    with pytest.raises(InputError, match=r"interval_s"):
        Tracker(Solver(load_sensor("st16")), interval_s=interval_s)


@pytest.mark.parametrize("sigma", [True, False, math.nan, math.inf, -0.3, "3"])
def test_centroid_sigma_must_be_a_positive_number(sigma):
    with pytest.raises(InputError, match=r"centroid_sigma_px must be > 0 or 'snr'"):
        Solver(load_sensor("st16"), centroid_sigma_px=sigma)


def test_calibrate_fit_names_a_parameter_listed_twice():
    with pytest.raises(InputError, match=r"fit lists focal_length twice"):
        calibrate([], "st16", fit=("focal_length", "k1", "focal_length"))


def test_render_refuses_a_frame_too_large_before_allocating_it():
    data = _sensor_data(focal_length_m=5.0)
    data["detector"].update(columns=100_000, rows=100_000)
    sensor = sensor_from_dict(data)
    with pytest.raises(InputError, match=r"10,000,000,000 pixels: more than the 67,108,864"):
        render_frame(sensor, attitude_from_radec_roll(0.0, 0.0, 0.0), "hipparcos")


def test_coincident_centroids_still_solve_without_a_warning():
    # a star listed twice (two centroiders merged, a duplicated row) is a zero-length pattern
    # edge; the solve must skip such patterns (warnings are errors here) and find the same
    # attitude as without the duplicate
    sensor = load_sensor("st16")
    att = attitude_from_radec_roll(math.radians(80.0), math.radians(20.0), 0.3)
    frame = render_frame(sensor, att, "hipparcos", noise=False, rng=1)
    s = frame.truth.stars
    order = np.argsort(s.mag)[:12]
    xy = np.column_stack([s.x_mid[order], s.y_mid[order]])
    size = (sensor.detector.columns, sensor.detector.rows)
    solver = Solver(sensor)
    clean = solver.solve_centroids(xy, size)
    doubled = solver.solve_centroids(np.vstack([xy[:1], xy]), size)
    assert clean.solved and doubled.solved
    # same stars, same estimator: the attitudes agree to far below a pixel (0.3 arcsec)
    err = (clean.rotation * doubled.rotation.inv()).magnitude()
    assert err < 0.1 * sensor.detector.pixel_pitch_m / sensor.optics.focal_length_m


def test_slew_batches_stay_within_the_budget(monkeypatch):
    sensor = load_sensor("st16")
    kwargs = {
        "magnitudes": [3.0, 12.0],
        "rates_rad_s": [0.0, math.radians(0.5)],
        "n_trials": 4,
        "rng": 3,
    }
    batches = []
    real = slew.detect_stack

    def counted(counts, *args, **kw):
        batches.append(counts.shape)
        return real(counts, *args, **kw)

    monkeypatch.setattr(slew, "detect_stack", counted)
    whole = simulate_slew(sensor, **kwargs)
    assert [b[0] for b in batches] == [8, 8]  # both magnitudes x 4 trials in one batch
    largest = max(4 * b[1] * b[2] * 8 for b in batches)  # float64 stamps of one magnitude
    monkeypatch.setattr(slew, "STACK_BUDGET_BYTES", largest - 1)
    with pytest.raises(InputError, match=r"4 trial stamps of \d+ x \d+ px need .* GiB, more than"):
        simulate_slew(sensor, **kwargs)
    batches.clear()
    monkeypatch.setattr(slew, "STACK_BUDGET_BYTES", largest)
    split = simulate_slew(sensor, **kwargs)
    assert [b[0] for b in batches] == [4, 4, 4, 4]  # one magnitude per batch
    # the split run draws its noise in another order: a bright star is still always found and
    # a faint one never, as in the whole run
    for result in (whole, split):
        assert result.detected_fraction.tolist() == [[1.0, 1.0], [0.0, 0.0]]
