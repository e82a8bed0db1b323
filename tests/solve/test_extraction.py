"""The Solver's extraction: the quick one first on a known field, the robust one after it.

On the ESA frames (a known camera, 22-118 stars each) the quick extraction solves every frame
on its own, as accurately as the robust one; frames it cannot solve (noise clipped at zero,
8-bit) go on to the robust extraction, which the zero-clipped 8-bit test exercises.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.geometry.attitude import small_rotation_angles
from starsense.sensor import load_sensor
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 180 / math.pi * 3600


@pytest.fixture(scope="module")
def esa(shared_dir):
    folder = shared_dir / "data" / "images" / "esa"
    return folder, json.loads((folder / "reference.json").read_text())["frames"]


def test_quick_extraction_solves_the_esa_frames_like_the_robust_one(esa):
    folder, reference = esa
    auto, robust = Solver(sensor="esa_blackfly"), Solver(sensor="esa_blackfly", extraction="robust")
    for name in reference:
        a, b = auto.solve_file(folder / name), robust.solve_file(folder / name)
        assert a.solved and b.solved, name
        assert "quick_ms" not in a.stage_ms  # solved by the quick extraction itself
        # both within 6 arcsec of the reference (test_solver.py); of each other, then, within
        # 12 across the boresight, and the roll within 0.05 deg (3 arcmin, the weak axis)
        cross_x, cross_y, roll = small_rotation_angles(a.rotation, b.rotation) * ARCSEC_PER_RAD
        assert math.hypot(cross_x, cross_y) < 12, name
        assert abs(roll) < 180, name


def test_which_solvers_try_the_quick_extraction_first():
    sensor = load_sensor("esa_blackfly")
    assert Solver(sensor=sensor).quick_detector is not None
    assert Solver(fov_rad=math.radians(10)).quick_detector is not None
    # an unknown field: a failed quick attempt would cost the whole scale search
    assert Solver().quick_detector is None
    assert Solver(extraction="quick").quick_detector is not None
    assert Solver(sensor=sensor, extraction="robust").quick_detector is None
    # simulated frames with a known bias use the sensor's own detection logic
    assert Solver(sensor=sensor, background="known").quick_detector is None


def test_a_frame_the_quick_extraction_cannot_solve_goes_to_the_robust_one():
    # an 8-bit frame with noise under 3 counts: declined by the quick extraction, solved by
    # the robust one; the quick attempt's time is reported apart
    sensor = load_sensor("esa_blackfly")
    rng = np.random.default_rng(0)
    image = np.round(rng.normal(20.0, 0.7, (sensor.detector.rows, sensor.detector.columns)))
    sol = Solver(sensor=sensor)(image.astype(np.uint8))
    assert not sol.solved
    assert "quick_ms" in sol.stage_ms and sol.stage_ms["quick_ms"] <= sol.time_ms
    only_quick = Solver(sensor=sensor, extraction="quick")(image.astype(np.uint8))
    assert only_quick.status == "no_stars" and "quick_ms" not in only_quick.stage_ms


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"extraction": "fast"}, "extraction must be 'auto', 'quick' or 'robust'"),
        ({"extraction": "quick", "background": "known"}, "extraction='quick' estimates"),
    ],
)
def test_bad_extraction_options_are_refused_by_name(options, message):
    with pytest.raises(InputError, match=message):
        Solver(sensor="esa_blackfly", **options)


@pytest.mark.slow
def test_a_first_quick_attempt_tries_only_the_field_given(esa):
    # the field given 1.3x too wide: the quick attempt fails at that field without searching
    # the scale (the robust attempt that follows searches it, once), and the frame solves with
    # the field found (the reference fits give 11.422-11.425 deg)
    folder, reference = esa
    name = next(iter(reference))
    sol = Solver(fov_rad=math.radians(1.3 * 11.42)).solve_file(folder / name)
    assert sol.solved and "quick_ms" in sol.stage_ms
    assert sol.fov_deg == pytest.approx(reference[name]["fov_deg"], rel=1e-3)
