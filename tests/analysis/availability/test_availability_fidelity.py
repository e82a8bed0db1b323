"""Full-fidelity check: rendered frames through the detector against the threshold model.

Runs only when the rendering and detection modules exist.
"""

from __future__ import annotations

import numpy as np
import pytest

from starsense.analysis.availability import ThresholdCurve, fidelity_check
from starsense.catalog import load_catalog
from starsense.sensor import load_sensor


@pytest.fixture(scope="module")
def modules():
    pytest.importorskip("starsense.render.scene")
    detect = pytest.importorskip("starsense.detect")
    if not (hasattr(detect, "StarDetector") or hasattr(detect, "detect_stars")):
        pytest.skip("the full-frame detector (StarDetector / detect_stars) is not available yet")


def test_fidelity_check_static_frames(modules):
    sensor = load_sensor("st16")
    catalog = load_catalog("hipparcos")
    res = fidelity_check(
        sensor, catalog, ThresholdCurve.constant(5.75), rate_rad_s=0.0, n_trials=3, rng=1
    )
    assert res.n_frames == 3
    assert res.model_counts.shape == res.frame_counts.shape == (3,)
    assert 0.0 <= res.frame_availability <= 1.0
    # at rest the detector sees (nearly) every catalogue star <= 5.75 in the field: the ST-16
    # preset's PSF is chosen so that a static m = 5.75 star passes the detection logic; edge
    # stars can go either way (partial PSF on the detector)
    assert np.all(np.abs(res.frame_counts - res.model_counts) <= 0.25 * res.model_counts + 2)
    assert res.to_dict()["n_frames"] == 3
