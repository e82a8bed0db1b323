"""Slew tolerance (Dzamba & Enright 2014, sec. 3.1, Figs. 9-10)."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.analysis.slew import (
    SlewResult,
    _tolerable,
    default_magnitudes,
    magnitude_threshold,
    simulate_slew,
)
from starsense.errors import InputError
from starsense.sensor import load_sensor


def test_default_grid_contains_the_quoted_magnitudes():
    mags = default_magnitudes()
    assert len(mags) == 20
    for m in (3.0, 4.0, 5.0, 5.75):
        assert np.any(np.isclose(mags, m))


def test_tolerable_rate_rule():
    rates = np.array([0.0, 1.0, 2.0, 3.0])
    # detected at 0 and 1, fraction 0.75 -> 0.25 between 1 and 2: crosses 0.5 half-way
    assert _tolerable(np.array([1.0, 0.75, 0.25, 0.0]), rates, 0.5) == (1.5, False)
    # not detected at rest
    assert _tolerable(np.array([0.4, 0.0, 0.0, 0.0]), rates, 0.5) == (None, False)
    # detected at every rate: capped at the last one
    assert _tolerable(np.ones(4), rates, 0.5) == (3.0, True)
    # the first failure counts, even if a later rate passes again (e.g. saturation recovery)
    assert _tolerable(np.array([1.0, 0.0, 1.0, 1.0]), rates, 0.5) == (0.5, False)


def _result(tol, capped, mags):
    n = len(mags)
    return SlewResult(
        magnitudes=np.asarray(mags, float), rates_deg_s=np.array([0.0, 5.0]),
        electrons=np.ones(n), detected_fraction=np.ones((n, 2)),
        mean_intensity_counts=np.ones((n, 2)), ideal_intensity_counts=np.ones(n),
        tolerable_rate_deg_s=tol, capped=np.asarray(capped), model="reed", sensor_name="x",
        n_trials=1, criterion=0.5,
    )  # fmt: skip


def test_magnitude_threshold_inverts_the_tolerance_curve():
    res = _result([5.0, 3.0, 1.0, None], [True, False, False, False], [2.0, 3.0, 4.0, 5.0])
    mt = magnitude_threshold(res, [0.0, 0.5, 1.0, 2.0, 3.5, 100.0])
    # m = 4 tolerates 1 deg/s, m = 3 3 deg/s, m = 2 every rate (capped); m = 5 never detected
    assert list(mt) == [4.0, 4.0, 4.0, 3.0, 2.0, 2.0]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"rates_deg_s": [0, -1]}, r"rates must be >= 0 deg/s"),
        ({"rates_deg_s": [1, 0.5]}, "strictly increasing"),
        ({"n_trials": 0}, "n_trials must be an integer >= 1"),
        ({"criterion": 1.5}, r"criterion must be in \(0, 1\]"),
        ({"magnitudes": []}, "magnitudes must be a non-empty"),
        ({"model": "blackbody"}, "slew analysis model must be 'reed' or 'liebe'"),
    ],
)
def test_bad_input(kwargs, message):
    with pytest.raises(InputError, match=message):
        simulate_slew(load_sensor("st16"), **kwargs)


def test_rate_that_sweeps_off_the_detector():
    # 2592 columns of 2.2 um at f = 16 mm, t = 0.1 s: a 300 deg/s slew sweeps ~4,200 px
    with pytest.raises(InputError, match="longer than the detector's 2592 columns"):
        simulate_slew(load_sensor("st16"), rates_deg_s=[0.0, 300.0], n_trials=1)
