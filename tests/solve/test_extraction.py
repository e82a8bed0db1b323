"""The Solver's extraction: the quick one first, the robust one after it.

On the ESA frames (22-118 stars each) the quick extraction solves every frame on its own, the
camera known or not, as accurately as the robust one; frames it cannot solve (noise clipped at
zero, 8-bit) go on to the robust extraction, which the zero-clipped 8-bit test exercises.
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


@pytest.mark.parametrize("known", [True, False], ids=["sensor", "nothing-known"])
def test_quick_extraction_solves_the_esa_frames_like_the_robust_one(esa, known):
    folder, reference = esa
    options = {"sensor": "esa_blackfly"} if known else {}
    auto, robust = Solver(**options), Solver(**options, extraction="robust")
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
    assert Solver().quick_detector is not None  # an unknown field: a pinhole scale search
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


def test_an_unknown_fields_robust_attempt_has_a_budget_of_its_own(shared_dir, monkeypatch):
    # a comet frame that does not solve: its quick attempt searches the scale (patterns spent)
    # and fails; the robust attempt's identifications then start from a fresh work budget,
    # not from what the quick one left
    from starsense.solve.identifiers import FieldIdentifiers

    frame = shared_dir / "data" / "images" / "cedar-bmp" / "big_comet_with_stars.jpg"
    if not frame.is_file():
        pytest.skip(f"{frame} not found")
    spent_at_entry = []
    identify = FieldIdentifiers.identify

    def spy(self, *args, **kwargs):
        spent_at_entry.append(self._spent)
        out = identify(self, *args, **kwargs)
        spent_at_entry.append(("after", self._spent))
        return out

    monkeypatch.setattr(FieldIdentifiers, "identify", spy)
    sol = Solver().solve_file(frame)
    assert not sol.solved and "quick_ms" in sol.stage_ms
    assert spent_at_entry[0] == 0 and spent_at_entry[1][1] > 0  # the quick attempt spent some
    assert spent_at_entry[2] == 0  # the robust attempt's first identification: a fresh budget


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
