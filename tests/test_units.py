"""The one home of angle units: constants against astropy, and values read back at the edge."""

from __future__ import annotations

import astropy.units as u
import numpy as np
import pytest

from starsense import units


@pytest.mark.parametrize(
    ("ours", "theirs"),
    [
        (units.DEG, u.deg),
        (units.ARCMIN, u.arcmin),
        (units.ARCSEC, u.arcsec),
        (units.MAS, u.mas),
    ],
)
def test_constants_agree_with_astropy(ours, theirs):
    # an independent computation: astropy's unit conversion, to the last ulp or two
    assert ours == pytest.approx((1 * theirs).to_value(u.rad), rel=4e-16)
    assert 1.0 / ours == pytest.approx((1 * u.rad).to_value(theirs), rel=4e-16)


def test_inverse_constants():
    assert units.RAD_TO_DEG * units.DEG == pytest.approx(1.0, rel=2e-16)
    assert units.RAD_TO_ARCSEC * units.ARCSEC == pytest.approx(1.0, rel=2e-16)
    assert units.RAD_TO_MAS * units.MAS == pytest.approx(1.0, rel=2e-16)


def test_to_edge_reads_back_what_was_given():
    given = [0.3, 0.2, 0.1, 1.25, 10.0, -90.0, 0.123456789]
    # x * DEG / DEG is not always x to the last bit: to_edge undoes the edge conversion exactly
    assert units.to_edge(np.array(given) * units.DEG, units.DEG).tolist() == given
    assert [units.to_edge(g * units.ARCSEC, units.ARCSEC) for g in given] == given
    assert isinstance(units.to_edge(0.3 * units.DEG, units.DEG), float)


def test_to_edge_keeps_computed_values_and_non_finite():
    x = np.array([np.pi / 7, np.inf, np.nan])
    out = units.to_edge(x, units.DEG)
    assert out[0] == pytest.approx(np.pi / 7 / units.DEG, rel=1e-15)
    assert out[1] == np.inf and np.isnan(out[2])
