"""Authority values: Dzamba & Enright 2014 (ST-16, Yale Bright Star Catalogue)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.analysis.availability import (
    AvailabilityAnalysis,
    ThresholdCurve,
    implied_threshold,
)
from starsense.analysis.slew import simulate_slew
from starsense.catalog import load_catalog
from starsense.geometry.fov import CircularFov
from starsense.references import dzamba2014 as paper
from starsense.references.dzamba2014 import TABLE2 as PAPER_TABLE2
from starsense.sensor import load_sensor

#: shared/data/catalogs/README.md: BSC5 stars with V <= 5.75 and a position
BSC5_V575 = 3852


@pytest.fixture(scope="module")
def st16_bsc5(bsc5_path):
    """The paper's set-up: BSC5, V <= 5.75, 7.5 deg half-axis circular field, 10,000 pointings."""
    catalog = load_catalog(f"bsc5:{bsc5_path}")
    return AvailabilityAnalysis.from_catalog(
        catalog,
        CircularFov(math.radians(paper.HALF_FOV_DEG)),
        paper.MAX_MAG,
        n_orientations=paper.N_ORIENTATIONS,
    )


def test_dzamba2014_st16_static_availability(st16_bsc5):
    # Paper sec. 1.2: "> 99.9 %" with N_min = 3, m_t = 5.75, 7.5 deg half-axis, 10,000
    # orientations. The paper's own cut has 3,746 stars, ours 3,852 (README of the catalogue:
    # the paper's count is not reproducible from the published file); 99.9 % is the claim.
    res = st16_bsc5.static(3)
    assert res.n_stars == BSC5_V575
    assert res.n_orientations == paper.N_ORIENTATIONS
    assert res.availability > paper.STATIC_AVAILABILITY_N3
    # tracking needs fewer stars, the conservative definition more
    assert res.by_n_min[2] >= res.availability >= res.by_n_min[4]
    assert res.by_n_min[4] > 0.995


def test_dzamba2014_table2_spatial_column_implies_one_threshold_per_rate(st16_bsc5):
    # Table 2's spatial column gives, at each rate, availability for N_min = 2 and 3 with one
    # threshold m_t(w). If our sky (catalogue, field, boresights) is the paper's, the m_t at
    # which our availability equals the N_min = 2 value equals the one for N_min = 3. They
    # agree to 0.05 mag at 1-2 deg/s; at 3 deg/s (14 % / 39 %, a few bright stars per field,
    # where the counts are most sensitive to the boresight set) to 0.15 mag.
    for rate, tol in ((1.0, 0.05), (1.5, 0.05), (2.0, 0.05), (3.0, 0.15)):
        n2, n3 = (v / 100 for v in PAPER_TABLE2[rate]["spatial"])
        m2 = implied_threshold(st16_bsc5, n2, 2)
        m3 = implied_threshold(st16_bsc5, n3, 3)
        assert m2 == pytest.approx(m3, abs=tol), (rate, m2, m3)


def test_dzamba2014_dynamic_with_paper_implied_curve(st16_bsc5):
    # With the threshold curve the paper's spatial column implies (m_t at 1, 1.5, 2, 3 deg/s),
    # our spatial dynamic availability is the paper's to within the threshold mismatch above
    # (3 points at 1-2 deg/s, 5 at 3 deg/s); the quoted Fig. 11 values (~90/80 % at 1 deg/s,
    # ~55/30 % at 2 deg/s) follow.
    curve = ThresholdCurve(np.radians([0.0, 1.0, 1.5, 2.0, 3.0]), [5.75, 4.78, 4.40, 3.875, 3.60])
    dyn = st16_bsc5.dynamic(curve, np.radians([1.0, 1.5, 2.0, 3.0]), n_min=3)
    for j, rate in enumerate((1.0, 1.5, 2.0, 3.0)):
        n2, n3 = (v / 100 for v in PAPER_TABLE2[rate]["spatial"])
        tol = 0.05 if rate == 3.0 else 0.03
        assert dyn.by_n_min[2][j] == pytest.approx(n2, abs=tol)
        assert dyn.by_n_min[3][j] == pytest.approx(n3, abs=tol)
    np.testing.assert_array_equal(dyn.availability, dyn.by_n_min[3])


@pytest.fixture(scope="module")
def slew_curves():
    """m_t(w) of the slew Monte Carlo (Fig. 10 read sideways), both sensitivity models."""
    pytest.importorskip("starsense.detect.stack")

    sensor = load_sensor("st16")
    return {
        model: ThresholdCurve.from_slew(simulate_slew(sensor, model=model, n_trials=20, rng=0))
        for model in ("reed", "liebe")
    }


def test_dzamba2014_fig11_reed_1degs(st16_bsc5, slew_curves):
    # Sec. 3.1: at 1 deg/s, Reed model, "~80 %" (N_min = 3) and "~90 %" (N_min = 2); Table 2
    # gives 80.9 / 93.3. Ours: 88 / 96 with the seeded Monte Carlo. Tolerance 0.10: the
    # paper's values are read off a figure, and our m_t(1 deg/s) = 4.89 is 0.1 mag fainter than
    # the 4.78 the paper's Table 2 implies on our sky (PSF size and QE are assumptions of the
    # st16 preset: its comments give the reasons).
    dyn = st16_bsc5.dynamic(slew_curves["reed"], np.radians([1.0]), n_min=3)
    n2, n3 = paper.FIG11_REED[1.0]
    assert dyn.by_n_min[3][0] == pytest.approx(n3, abs=0.10)
    assert dyn.by_n_min[2][0] == pytest.approx(n2, abs=0.10)
    assert dyn.by_n_min[2][0] > dyn.by_n_min[3][0]


@pytest.mark.xfail(
    strict=True,
    reason="known gap: our Reed slew simulation tolerates more at 2 deg/s (m_t = 4.19) than the "
    "paper (3.87 implied by its Table 2 on our sky), so availability is 68 / 45 % against "
    "the paper's ~55 / ~30 %; the difference is in the tolerable-slew curve, not the "
    "availability count (see test_dzamba2014_table2_spatial_column_implies_one_threshold)",
)
def test_dzamba2014_fig11_reed_2degs(st16_bsc5, slew_curves):
    dyn = st16_bsc5.dynamic(slew_curves["reed"], np.radians([2.0]), n_min=3)
    n2, n3 = paper.FIG11_REED[2.0]
    assert dyn.by_n_min[3][0] == pytest.approx(n3, abs=0.07)
    assert dyn.by_n_min[2][0] == pytest.approx(n2, abs=0.07)


def test_dzamba2014_fig11_liebe(st16_bsc5, slew_curves):
    # Sec. 3.1: Liebe model "~100 % availability at 1 deg/s and > 90 % at 2 deg/s for both LIS
    # and tracking solutions", then a significant drop from 2 to 5 deg/s.
    dyn = st16_bsc5.dynamic(slew_curves["liebe"], np.radians([1.0, 2.0, 5.0]), n_min=3)
    for k in (2, 3):
        assert dyn.by_n_min[k][0] > paper.FIG11_LIEBE[1.0]
        assert dyn.by_n_min[k][1] > paper.FIG11_LIEBE[2.0]
        assert dyn.by_n_min[k][2] < dyn.by_n_min[k][1] - 0.25
