"""The ECSS performance statement (starsense.analysis.ecss): factors, axes, keys, rate classes."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from scipy.stats import norm

from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
from starsense.analysis.ecss import ecss_statement, gaussian_factor, mixture_bound
from starsense.analysis.ecss.confidence import (
    ONE_SIGMA,
    THREE_SIGMA,
    parse_confidence,
    weighted_median,
)
from starsense.analysis.ecss.sky import sky_stars
from starsense.analysis.inputs import as_catalog
from starsense.errors import InputError
from starsense.photometry.colour import with_johnson_from_gaia
from starsense.sensor import load_sensor
from starsense.units import RAD_TO_ARCSEC

#: a light sky (300 attitudes, few slew renders): the statement's arithmetic, not its precision
LIGHT = DatasheetSettings(n_trials=0, n_orientations=300, n_slew_trials=4)
TERMS = (
    "bias", "thermo_elastic", "fov_spatial", "pixel_spatial_interpolation",
    "pixel_spatial_prnu", "pixel_spatial_dsnu", "temporal_noise", "aberration_annual",
)  # fmt: skip


@pytest.mark.parametrize("p", [0.5, ONE_SIGMA, 0.9, 0.95, THREE_SIGMA, 0.999])
def test_gaussian_factor_is_scipy_two_sided_quantile(p):
    # scipy.stats.norm.ppf is an independent implementation: agreement to round-off
    assert gaussian_factor(p) == pytest.approx(norm.ppf(0.5 * (1.0 + p)), rel=1e-12)


def test_named_levels_are_one_and_three_sigma():
    assert gaussian_factor(parse_confidence("1sigma")) == pytest.approx(1.0, rel=1e-12)
    assert gaussian_factor(parse_confidence("3sigma")) == pytest.approx(3.0, rel=1e-12)
    for text in ("95", "95%", "0.95", " 95 % "):
        assert parse_confidence(text) == pytest.approx(0.95, rel=1e-15)


@pytest.mark.parametrize("bad", ["abc", "0", "100", "-5", "nan", "", "1e3"])
def test_bad_confidence_is_one_line(bad):
    with pytest.raises(InputError, match="--confidence") as err:
        parse_confidence(bad)
    assert "\n" not in str(err.value)


def test_mixture_bound_holds_its_probability():
    # equal sigmas: the Gaussian bound itself
    assert mixture_bound([2.0] * 7, 0.95) == pytest.approx(2.0 * norm.ppf(0.975), rel=1e-9)
    # unequal: the bound q solves mean(P(|e| < q)) = p, checked with scipy's cdf (independent
    # of the ndtr the solver used); a wide mixture needs more than k times its median
    s = np.array([0.5, 1.0, 1.0, 3.0, np.nan])
    q = mixture_bound(s, THREE_SIGMA)
    live = s[np.isfinite(s)]
    assert np.mean(2.0 * norm.cdf(q / live) - 1.0) == pytest.approx(THREE_SIGMA, abs=1e-9)
    assert q > 3.0 * np.median(live)
    assert mixture_bound([np.nan], 0.9) is None
    assert mixture_bound([0.0, 0.0], 0.9) == 0.0


@pytest.fixture(scope="module")
def st16():
    sensor = load_sensor("st16")
    cat, _ = with_johnson_from_gaia(as_catalog(None))
    sheet = build_datasheet(sensor, cat, settings=LIGHT)
    statement = ecss_statement(
        sensor, cat, confidence=THREE_SIGMA, rates_deg_s=[0, 1], settings=LIGHT, sheet=sheet
    )
    return sensor, cat, sheet, statement


def test_x_y_split_is_the_datasheets_cross(st16):
    sensor, cat, sheet, statement = st16
    # per attitude the datasheet's cross is the rms of X and Y: X^2 + Y^2 = 2 cross^2 (same
    # attitudes, stars and weights: equal to round-off), Z its roll
    axes = sky_stars(
        sensor, cat, LIGHT, limit_mag=sheet.limiting_magnitude, slew=sheet.slew
    ).propagated("nea")
    ok = np.isfinite(sheet.nea_cross_rad)
    assert ok.sum() > 250
    np.testing.assert_allclose(
        axes[ok, 0] ** 2 + axes[ok, 1] ** 2, 2.0 * sheet.nea_cross_rad[ok] ** 2, rtol=1e-9
    )
    rest = statement.terms[TERMS.index("temporal_noise")]["at_rate"][0]
    # over every attitude, the datasheet's roll; the statement's median is over the attitudes
    # that solve, each weighing its chance (st16 solves nearly everywhere at rest)
    assert float(np.median(axes[:, 2])) * RAD_TO_ARCSEC == pytest.approx(
        sheet.nea_arcsec.roll.median, rel=1e-9
    )
    w = statement.solving[0][len(axes)]
    assert np.mean(w) > 0.99
    assert rest["z_1sigma_arcsec"] == pytest.approx(
        weighted_median(axes[:, 2], w) * RAD_TO_ARCSEC, rel=1e-9
    )
    # at the sky median the identity holds only roughly (a median of a sum is not the sum of
    # medians): X and Y straddle the cross within 10 %
    cross = sheet.nea_arcsec.cross.median
    for a in ("x", "y"):
        assert 0.9 * cross < rest[f"{a}_1sigma_arcsec"] < 1.1 * cross
    # the 3-sigma value is 3 times the 1-sigma (Gaussian factor)
    assert rest["x_arcsec"] == pytest.approx(3.0 * rest["x_1sigma_arcsec"], rel=1e-9)
    # a smeared star holds less information: the noise grows with the rate
    at_rate = statement.terms[TERMS.index("temporal_noise")]["at_rate"][1]
    assert all(at_rate[f"{a}_arcsec"] > rest[f"{a}_arcsec"] for a in ("x", "y", "z"))


def test_keys_are_stable_snake_case_with_units(st16):
    *_, statement = st16
    d = statement.to_dict()
    assert [t["key"] for t in d["terms"]] == list(TERMS)
    expected = {"rate_deg_s"}
    expected |= {f"{t}_{a}_arcsec" for t in TERMS for a in "xyz"}
    expected |= {f"{t}_{a}_arcsec" for t in ("total", "total_bias", "total_noise") for a in "xyz"}
    for row in d["values"]:
        assert set(row) == expected
        assert all(re.fullmatch(r"[a-z0-9_]+_(arcsec|deg_s)", k) for k in row)
    # not known is null, never a number that is round-off
    row = d["values"][0]
    assert row["bias_x_arcsec"] is None
    assert row["pixel_spatial_interpolation_x_arcsec"] == 0.0  # the fit: exactly none


@pytest.fixture(scope="module")
def flawed():
    """A sensor with PRNU 1 %, a 0.1 px distortion residual and a 5 arcsec bias."""
    base = load_sensor("st16")
    sensor = base.with_(
        detector=dataclasses.replace(base.detector, prnu_fraction=0.01),
        optics=dataclasses.replace(base.optics, distortion_residual_px=0.1),
        budget=(("bias_cross_arcsec", 5.0), ("bias_roll_arcsec", 5.0)),
    )
    return ecss_statement(sensor, confidence=ONE_SIGMA, rates_deg_s=[0, 1], settings=LIGHT)


def test_spatial_errors_are_bias_at_rest_and_noise_in_slew(flawed):
    t = {row["key"]: row for row in flawed.terms}
    for key in ("fov_spatial", "pixel_spatial_prnu"):
        rest, slew = t[key]["at_rate"]
        assert (rest["acts_as"], slew["acts_as"]) == ("bias", "noise")
        assert rest["x_arcsec"] > 0
        # the amplitude is the one at rest, attitude by attitude; the sky median at the rate
        # is over the attitudes that solve at the rate (fewer): unweighted, the two are equal
        source = next(t for t in flawed.sources if t.key == key)
        np.testing.assert_array_equal(source.values_rad[0], source.values_rad[1])
        both = dataclasses.replace(flawed, solving=()).at_confidence(ONE_SIGMA)
        rest_all, slew_all = next(t for t in both.terms if t["key"] == key)["at_rate"]
        assert rest_all["x_arcsec"] == slew_all["x_arcsec"]
    assert [r["acts_as"] for r in t["bias"]["at_rate"]] == ["bias", "bias"]
    assert [r["acts_as"] for r in t["temporal_noise"]["at_rate"]] == ["noise", "noise"]
    assert t["bias"]["at_rate"][0]["x_arcsec"] == pytest.approx(5.0)
    # a pixel's crossing time at 1 deg/s: its angle / the rate
    pixel_arcsec = 2.2e-6 / 0.016 * RAD_TO_ARCSEC
    period = t["pixel_spatial_prnu"]["at_rate"][1]["period_s"]
    assert period == pytest.approx(pixel_arcsec / 3600.0, rel=1e-9)
    # the totals, recomputed from the rows: the bias moves into the noise with the rate
    for i, tot in enumerate(flawed.totals):
        for a in "xyz":
            parts = {"bias": 0.0, "noise": 0.0}
            for row in flawed.terms:
                v = row["at_rate"][i][f"{a}_arcsec"]
                if row["counted"] and v is not None:
                    parts[row["at_rate"][i]["acts_as"]] += v * v
            assert tot[f"total_bias_{a}_arcsec"] == pytest.approx(math.sqrt(parts["bias"]))
            assert tot[f"total_noise_{a}_arcsec"] == pytest.approx(math.sqrt(parts["noise"]))
    still, moving = flawed.totals
    assert moving["total_bias_x_arcsec"] == pytest.approx(5.0)  # only the bias stays one
    assert still["total_bias_x_arcsec"] > 5.0


def test_bad_rates(st16):
    sensor, cat, sheet, _ = st16
    for rates, match in (([-1], "out of range"), (["x"], "not a number"), ([], "no rate")):
        with pytest.raises(InputError, match=match):
            ecss_statement(sensor, cat, rates_deg_s=rates, settings=LIGHT, sheet=sheet)
    top = float(sheet.dynamic.rates_rad_s[-1]) * 180.0 / math.pi
    if top < 29.0:
        with pytest.raises(InputError, match="past the slew tolerance"):
            ecss_statement(sensor, cat, rates_deg_s=[top + 1.0], settings=LIGHT, sheet=sheet)


def test_too_few_solving_attitudes_give_every_attitudes_values(st16):
    # the statement over the attitudes that solve, weighed by their chances: 25 attitudes of
    # equal chance (an effective 25, at least MIN_SOLVING_ATTITUDES) give the median of those
    # 25; a single one of chance 1e-3 (an
    # effective 1: what esa_blackfly at 2 deg/s weighed) gives that of every attitude, and a
    # note names the rate
    from starsense.analysis.ecss.confidence import weighted_median
    from starsense.analysis.ecss.statement import MIN_SOLVING_ATTITUDES, effective_attitudes

    *_, statement = st16
    source = next(t for t in statement.sources if t.key == "temporal_noise")
    col = source.values_rad[0][:, 0]
    n = len(col)
    few = np.zeros(n)
    few[:25] = 1.0
    one = np.zeros(n)
    one[7] = 1e-3
    assert effective_attitudes(few) == pytest.approx(25.0)
    assert effective_attitudes(one) == pytest.approx(1.0)
    assert effective_attitudes(np.zeros(n)) == 0.0
    assert MIN_SOLVING_ATTITUDES == 20  # between the two
    rows = statement.solving[1]
    for w, want, noted in ((few, weighted_median(col, few), False), (one, np.median(col), True)):
        solving = ({n: w}, rows)
        got = dataclasses.replace(statement, solving=solving).at_confidence(ONE_SIGMA)
        rest = next(t for t in got.terms if t["key"] == "temporal_noise")["at_rate"][0]
        assert rest["x_1sigma_arcsec"] == pytest.approx(want * RAD_TO_ARCSEC, rel=1e-12)
        assert any(note.startswith("at 0 deg/s fewer than") for note in got.notes) is noted
    # the 25 are not the sky's median attitude, or the two cases could not be told apart
    assert abs(weighted_median(col, few) / np.median(col) - 1.0) > 0.01
