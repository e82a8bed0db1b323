"""The Python API with arguments of the wrong type: an InputError at the front door naming the
argument and what it got, never an AttributeError or "not iterable" from deep inside.
"""

from __future__ import annotations

import numpy as np
import pytest

import starsense
from starsense.errors import InputError
from starsense.solve import Solver, Tracker

ATT = starsense.attitude_from_radec_roll(0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: starsense.render_frame(5, ATT), r"sensor must be a Sensor.*got int 5"),
        (lambda: starsense.render_frame(None, ATT), r"sensor must be a Sensor.*got NoneType"),
        (lambda: starsense.load_sensor(3.5), r"sensor must be a Sensor.*got float 3\.5"),
        (lambda: Tracker("st16"), r"Tracker needs a Solver.*got str 'st16'"),
        (lambda: Tracker(None), r"Tracker needs a Solver.*got NoneType None"),
        (lambda: starsense.compare(5), r"sensors must be a list of sensors.*got int 5"),
        (lambda: starsense.compare("st16"), r"sensors must be a list.*got str 'st16'"),
        (lambda: starsense.compare([]), "sensors is empty"),
        (lambda: starsense.calibrate(5, "st16"), r"frames must be a list of solved frames.*int 5"),
        (lambda: starsense.calibrate([], "st16", fit=5), r"fit must name some of focal_length"),
        (
            lambda: starsense.montecarlo("st16", n_trials=float("nan")),
            "n_trials must be an integer",
        ),
        (lambda: starsense.slew_tolerance("st16", n_trials=float("nan")), "n_trials must be an"),
        (lambda: starsense.datasheet("st16", n_trials="many"), "n_trials must be an integer"),
    ],
)
def test_wrong_type_is_an_input_error(call, match):
    with pytest.raises(InputError, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_render_frame_takes_a_preset_name_as_the_other_entry_points_do():
    by_name = starsense.render_frame("st16", ATT, max_mag=4.0, rng=3)
    by_object = starsense.render_frame(starsense.load_sensor("st16"), ATT, max_mag=4.0, rng=3)
    assert np.array_equal(by_name.image, by_object.image)


def test_tracker_still_takes_a_solver():
    assert Tracker(Solver("st16")).solver.sensor.name == "st16"
