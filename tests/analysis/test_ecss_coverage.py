"""The statement's coverage by Monte Carlo frames, and its flat JSON rows, on hand-built terms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.analysis.datasheet import DatasheetSettings
from starsense.analysis.ecss.confidence import ONE_SIGMA, THREE_SIGMA
from starsense.analysis.ecss.coverage import (
    consistent_with,
    coverage_rows,
    frame_errors_at,
    inside_fraction,
)
from starsense.analysis.ecss.export import ROW_KEYS, statement_rows
from starsense.analysis.ecss.statement import Statement
from starsense.analysis.ecss.terms import Term
from starsense.units import ARCSEC

#: 1-sigma X, Y, Z of the Gaussian term, arcsec, and the worst case of the non-Gaussian one
SIGMA = (1.0, 2.0, 10.0)
WORST = (0.5, 0.5, 0.0)
RATES = (0.0, 1.0)


def _statement(confidence: float = ONE_SIGMA) -> Statement:
    """A statement of two terms (a Gaussian noise, a worst-case bias) built by hand."""
    noise = Term(
        "temporal_noise",
        "temporal_noise",
        (np.array(SIGMA) * ARCSEC,) * len(RATES),
        True,
        True,
        "Gaussian",
        "given here",
    )
    bias = Term(
        "aberration_annual",
        "aberration",
        (np.array(WORST) * ARCSEC,) * len(RATES),
        False,
        True,
        "worst case",
        "given here",
    )
    empty = Statement("hand", 0.5, 0.0, RATES, (), (), (), (noise, bias), (0.2, 1e-4))
    return empty.at_confidence(confidence)


def test_inside_fraction_counts_the_frames_within_the_bound():
    # |e| <= bound, the bound itself inside: -1, 0.5, 2 of the four
    assert inside_fraction([-1.0, 0.5, 2.0, -3.0], 2.0) == 0.75
    assert inside_fraction([], 2.0) is None
    assert inside_fraction([1.0], None) is None
    assert inside_fraction([1.0, -1.0], 0.0) == 0.0


def test_totals_at_one_and_three_sigma_are_the_root_sum_squares():
    # the Gaussian term scales with k (1, 3), the worst case does not
    for p, k in ((ONE_SIGMA, 1.0), (THREE_SIGMA, 3.0)):
        tot = _statement(p).totals[0]
        for a, s, w in zip("xyz", SIGMA, WORST, strict=True):
            assert tot[f"total_{a}_arcsec"] == pytest.approx(math.hypot(k * s, w), rel=1e-12)


def test_coverage_is_the_hand_count_of_frames_inside():
    # frames built so that the count is known: on X (1-sigma bound hypot(1, 0.5) = 1.118,
    # 3-sigma hypot(3, 0.5) = 3.041) the errors 0, 1.1, -1.2, 3.0, -3.1 arcsec: 2 of 5 inside
    # the 1-sigma bound, 4 of 5 inside the 3-sigma one
    x = np.array([0.0, 1.1, -1.2, 3.0, -3.1])
    y = np.array([0.1, -0.1, 5.0, -7.0, 0.0])  # bounds 2.06 / 6.02: 3 and 4 of 5
    z = np.array([-9.0, 11.0, 29.0, -31.0, 0.0])  # bounds 10 / 30: 2 and 4 of 5
    errors = np.column_stack([x, y, z]) * ARCSEC
    frames = {0.0: (errors, 5, "hand"), 1.0: (np.zeros((0, 3)), 5, "hand")}
    rows = coverage_rows(_statement(0.95), frames)
    assert [(r["rate_deg_s"], r["axis"]) for r in rows] == [
        (0.0, "X"), (0.0, "Y"), (0.0, "Z"), (1.0, "X"), (1.0, "Y"), (1.0, "Z"),
    ]  # fmt: skip
    got = {r["axis"]: (r["inside_1sigma"], r["inside_3sigma"]) for r in rows[:3]}
    assert got == {"X": (0.4, 0.8), "Y": (0.6, 0.8), "Z": (0.4, 0.8)}
    assert all(r["frames"] == 5 and r["reason"] is None for r in rows[:3])
    # 2, 3 of 5 inside the 1-sigma bound: chance on 5 frames explains both (the exact 95 %
    # intervals hold 0.683); 4 of 5 inside the 3-sigma bound: the one-sided 95 % upper bound
    # is 0.95^(1/5) = 0.990 < 0.9973, a miss beyond chance
    assert all(r["consistent_1sigma"] is True for r in rows[:3])
    assert all(r["consistent_3sigma"] is False for r in rows[:3])
    # no right solution at 1 deg/s: no fraction, and why
    assert all(r["inside_1sigma"] is None and "no right solution" in r["reason"] for r in rows[3:])


def test_consistency_is_scipys_exact_binomial_interval():
    """consistent_with against scipy.stats.binomtest's Clopper-Pearson intervals."""
    from scipy.stats import binomtest

    for n in (5, 30, 88, 100, 400):
        for inside in sorted({0, 1, n // 2, round(0.68 * n), n - 3, n - 2, n - 1, n}):
            if not 0 <= inside <= n:
                continue
            lo, hi = binomtest(inside, n).proportion_ci(0.95, method="exact")
            assert consistent_with(inside, n, ONE_SIGMA, two_sided=True) == (lo <= ONE_SIGMA <= hi)
            up = binomtest(inside, n, alternative="less").proportion_ci(0.95, method="exact").high
            assert consistent_with(inside, n, THREE_SIGMA, two_sided=False) == (up >= THREE_SIGMA)
    assert consistent_with(0, 0, THREE_SIGMA, two_sided=False) is None
    # one frame of 100 outside a 3-sigma bound is chance (a right bound does it 24 % of the
    # time); two are not (the claim's 0.9973 lies above the count's 95 % upper bound 0.9964)
    assert consistent_with(99, 100, THREE_SIGMA, two_sided=False)
    assert not consistent_with(98, 100, THREE_SIGMA, two_sided=False)


def test_frames_already_run_are_not_run_again():
    # rates matched to the datasheet's runs: no Monte Carlo (a None sensor would fail one)
    have = {0.0: np.ones((3, 3)), 1.0: np.zeros((2, 3))}
    st = DatasheetSettings(n_trials=7, n_rate_trials=5)
    got = frame_errors_at(None, None, st, rates_deg_s=(0.0, 1.0 + 1e-12), have=have)
    assert got[0.0][1:] == (7, "datasheet") and got[1.0 + 1e-12][1:] == (5, "datasheet")
    assert got[0.0][0].shape == (3, 3) and got[1.0 + 1e-12][0].shape == (2, 3)


def test_rows_have_exactly_the_named_keys():
    s = _statement(THREE_SIGMA)
    rows = statement_rows(s)
    # (2 terms + 3 totals) x 3 axes x 2 rates
    assert len(rows) == 5 * 3 * len(RATES)
    assert all(tuple(r) == ROW_KEYS for r in rows)
    assert set(ROW_KEYS) == {
        "class", "axis", "rate_deg_s", "value_arcsec", "confidence", "distribution",
        "time_class", "source",
    }  # fmt: skip
    assert {r["axis"] for r in rows} == {"X", "Y", "Z"}
    assert all(r["confidence"] == THREE_SIGMA for r in rows)
    total_z = [r for r in rows if r["class"] == "total" and r["axis"] == "Z"]
    assert [r["value_arcsec"] for r in total_z] == pytest.approx([30.0, 30.0], rel=1e-12)
    noise = [r for r in rows if r["class"] == "temporal_noise"]
    assert {r["time_class"] for r in noise} == {"temporal_noise"}


def test_sky_ensemble_total_is_the_mixtures_bound_with_the_worst_cases_added():
    # two Gaussian terms known per attitude (four attitudes of different widths) and one worst
    # case: the ensemble total at p is the p-quantile of |e| for e drawn at a random attitude
    # with that attitude's quadrature sum of sigmas, then the worst case in quadrature. Checked
    # against 2e6 draws of that mixture (the quantile's sampling error there is ~0.1 %: 0.5 %
    # tolerance)
    sky_a = np.array([[1.0, 2.0, 5.0], [2.0, 1.0, 6.0], [0.5, 0.5, 3.0], [4.0, 3.0, 9.0]])
    sky_b = np.array([[1.0, 1.0, 1.0], [0.0, 2.0, 2.0], [1.5, 0.5, 4.0], [1.0, 1.0, 1.0]])
    worst = np.array([0.3, 0.0, 2.0])
    terms = (
        Term("temporal_noise", "temporal_noise", (sky_a * ARCSEC,), True, True, "G", "here"),
        Term("pixel_spatial_prnu", "pixel_spatial", (sky_b * ARCSEC,), True, True, "G", "here"),
        Term("aberration_annual", "aberration", (worst * ARCSEC,), False, True, "worst", "here"),
    )
    rng = np.random.default_rng(5)
    for p in (ONE_SIGMA, THREE_SIGMA):
        tot = Statement("hand", 0.5, 0.0, (0.0,), (), (), (), terms, (0.2, 1e-4))
        tot = tot.at_confidence(p).totals[0]
        for j, a in enumerate("xyz"):
            sig = np.hypot(sky_a[:, j], sky_b[:, j])
            draws = np.abs(rng.normal(size=2_000_000) * sig[rng.integers(0, 4, 2_000_000)])
            want = math.hypot(np.quantile(draws, p), worst[j])
            assert tot[f"total_sky_ensemble_{a}_arcsec"] == pytest.approx(want, rel=5e-3), (p, a)
