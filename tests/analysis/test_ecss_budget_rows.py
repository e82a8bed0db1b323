"""The datasheet's budget rows a statement builds on: no round-off printed as a value.

The forward model's fit has no sub-pixel bias (its model integrates the PSF over the pixels):
its pixel spatial error is exactly 0, not a floor of the interpolation. A confusion that is
round-off (a catalogue without the stars fainter than the limit) is "not modelled", None.
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.datasheet.budget import error_budget
from starsense.analysis.datasheet.model_noise import model_centroid_noise
from starsense.analysis.datasheet.sections import AxisSpread, Spread
from starsense.sensor import load_sensor

NEA = AxisSpread(Spread(0.3, 0.5), Spread(2.7, 4.5))


def _errors(confusion_rad: float) -> dict:
    m = 50
    return {
        "pixel": (np.zeros(m), np.zeros(m)),
        "confusion": (np.full(m, confusion_rad), np.full(m, confusion_rad)),
    }


def test_model_fit_pixel_bias_is_exactly_zero():
    table = model_centroid_noise(load_sensor("st16"), 100.0, 1e5)
    assert np.all(table.bias(np.geomspace(50.0, 2e5, 9)) == 0.0)


def test_round_off_confusion_is_not_modelled():
    sensor = load_sensor("st16")
    rows = error_budget(sensor, NEA, errors=_errors(4e-22), pse_px=None, refine="cog")
    row = next(r for r in rows if r.term.startswith("confusion"))
    assert row.cross_arcsec is None and row.roll_arcsec is None
    assert "not modelled" in row.source
    assert "confusion" not in rows[-1].source  # not in the total
    # a real confusion (0.01 arcsec) stays a value and counts
    rows = error_budget(sensor, NEA, errors=_errors(5e-8), pse_px=None, refine="cog")
    row = next(r for r in rows if r.term.startswith("confusion"))
    assert row.cross_arcsec == np.float64(5e-8) * 206264.80624709636
    assert "confusion" in rows[-1].source
