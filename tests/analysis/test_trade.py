"""Trade studies: the grid of designs, the Pareto set, the fast prediction against the datasheet."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.analysis.datasheet import datasheet
from starsense.analysis.datasheet.compare import ROW_KEYS, format_value, row_values
from starsense.analysis.datasheet.field import axis_sigmas, field_stars_cam, fisher_per_pointing
from starsense.analysis.datasheet.skycache import limit_sigmas
from starsense.analysis.inputs import as_catalog
from starsense.analysis.limits.sky import star_weights
from starsense.analysis.trade import (
    base_document,
    designs,
    pareto_mask,
    parse_vary,
    predict,
    prediction_settings,
    run_trade,
)
from starsense.errors import InputError
from starsense.geometry.sampling import random_attitudes
from starsense.photometry.stars import BlackBodyStars
from starsense.sensor import load_sensor

# small sky statistics: these tests compare two paths on the same inputs, not the numbers
_FAST = {"n_orientations": 150, "n_slew_trials": 4}


def test_parse_vary_list_and_range():
    assert parse_vary("exposure_s=0.05,0.1,0.2") == ("exposure_s", [0.05, 0.1, 0.2])
    key, values = parse_vary("optics.focal_length_m=0.012:0.035:6")
    assert key == "optics.focal_length_m" and len(values) == 6
    assert values[0] == 0.012 and values[-1] == pytest.approx(0.035, abs=1e-15)
    assert np.allclose(np.diff(values), (0.035 - 0.012) / 5)


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("optics.focal_lenght_m=0.01,0.02", "unknown key 'optics.focal_lenght_m'"),
        ("exposure_s=0.1:0.2:1", "N must be an integer >= 2"),
        ("exposure_s=0.1:0.2:0", "has 0 steps"),
        ("exposure_s=0.1:0.1:3", "zero width"),
        ("exposure_s=0.1:x:3", "'x' is not a number"),
        ("exposure_s", "expected KEY=LIST"),
    ],
)
def test_parse_vary_bad(text, fragment):
    with pytest.raises(InputError) as err:
        parse_vary(text)
    assert fragment in str(err.value)


def test_keep_f_number_and_fov():
    base = base_document("st16")
    f0, d0 = base["optics"]["focal_length_m"], base["optics"]["aperture_m"]
    half0 = load_sensor("st16").half_fov_rad
    grid = [parse_vary("optics.focal_length_m=0.012,0.032")]
    for d in designs(base, grid, keep=("f_number", "fov")):
        s = d.sensor()
        # the f-number and the field are those of the base (exact arithmetic up to rounding)
        assert s.optics.focal_length_m / s.optics.aperture_m == pytest.approx(f0 / d0, rel=1e-12)
        assert s.half_fov_rad == pytest.approx(half0, rel=1e-12)
    plain = designs(base, grid)
    assert plain[1].sensor().optics.aperture_m == d0  # no coupling asked: aperture unchanged


def test_pareto_mask_hand_built():
    # minimise both: (1,3), (2,2), (3,1) trade against each other; (3,3) and (2,2.5) are
    # dominated by (2,2); a NaN row is never optimal
    pts = np.array([[1, 3], [2, 2], [3, 1], [3, 3], [2, 2.5], [np.nan, 0]], dtype=float)
    assert pareto_mask(pts).tolist() == [True, True, True, False, False, False]


def test_limit_scales_as_d2_sqrt_t():
    # the cached unit bound scaled by D^-2 t^-1/2 equals eq. 21 summed with the sensor's own
    # eq. 19 weights (independent path: the weights of the sensor's D and t, no scaling)
    cat = as_catalog(None)
    sensor = load_sensor("st16")
    fov = sensor.fov()
    mats = random_attitudes(20, rng=3).as_matrix()
    cross, roll = limit_sigmas(cat, sensor, fov, matrices=mats)
    stars = BlackBodyStars.from_catalog(cat)
    w = star_weights(stars, sensor.optics.aperture_m, sensor.exposure_s)
    pairs = field_stars_cam(fov, mats, stars.vectors)
    c2, r2 = axis_sigmas(fisher_per_pointing(pairs, w[pairs.star]))
    # rounding only: both invert the same matrices, one scaled by D^4 t
    np.testing.assert_allclose(cross, c2, rtol=1e-9)
    np.testing.assert_allclose(roll, r2, rtol=1e-9)


def test_prediction_equals_the_datasheets_prediction():
    """Numbers stand still: the fast path is the datasheet's prediction, bit for bit."""
    cat = as_catalog(None)
    fast = predict("st16", cat, settings=prediction_settings(rng=5, **_FAST)).to_dict()
    full = datasheet("st16", cat, n_trials=1, rng=5, **_FAST).to_dict()
    skip = {"monte_carlo", "monte_carlo_at_rate", "settings", "warnings"}
    for key in fast:
        if key not in skip:
            assert fast[key] == full[key], key
    assert fast["monte_carlo"]["frames"] == 0 and full["monte_carlo"]["frames"] == 1
    rows_fast, rows_full = row_values(fast), row_values(full)
    for key in ROW_KEYS:
        if rows_fast[key]["value"] is not None:  # the measured rows exist only with frames
            assert rows_fast[key] == rows_full[key], key


def test_predict_takes_rng_like_the_datasheet():
    """``ss.predict(sensor, rng=...)`` as ``ss.datasheet``: the keywords are the settings."""
    import starsense as ss

    cat = as_catalog(None)
    by_keywords = ss.predict("st16", cat, rng=5, **_FAST)
    by_settings = predict("st16", cat, settings=prediction_settings(rng=5, **_FAST))
    assert by_keywords.settings.seed == 5
    assert by_keywords.to_dict() == by_settings.to_dict()
    with pytest.raises(InputError, match="give settings or rng, not both"):
        predict("st16", cat, rng=1, settings=prediction_settings(**_FAST))


def test_a_bad_design_gets_its_own_error_and_the_trade_goes_on():
    base = base_document("st16")
    todo = designs(base, [parse_vary("detector.pixel_pitch_m=-1,2.2e-6")])
    study = run_trade(todo, settings=prediction_settings(**_FAST), workers=1)
    bad, good = study.rows
    assert bad.rows is None and "detector.pixel_pitch_m = -1.0" in bad.error
    assert good.error is None and good.rows["nea_cross"]["value"] > 0
    assert good.pareto == {"nea_vs_rate": True, "roll_vs_aperture": True}  # alone: optimal


def test_output_keys_name_every_row_with_its_unit():
    from starsense.analysis.trade.keys import OUTPUT_KEYS

    assert list(OUTPUT_KEYS) == list(ROW_KEYS)  # every row, in order: a new row needs a name
    assert len(set(OUTPUT_KEYS.values())) == len(OUTPUT_KEYS)
    units = ("_deg", "_arcsec", "_deg_s", "_ms", "_fraction", "_count", "_ratio", "_v")
    for name in OUTPUT_KEYS.values():
        assert any(u in name for u in units) or name.startswith("measured_over_predicted"), name


def test_trade_carries_the_catalogue_completeness_warning():
    """A design that sees past Hipparcos's completeness (V 7.3) says so, as its datasheet does."""
    base = base_document("st16")
    todo = designs(base, [parse_vary("optics.aperture_m=0.012,0.03")])
    study = run_trade(todo, settings=prediction_settings(**_FAST), workers=1)
    small, large = study.rows
    assert (
        large.rows["limiting_magnitude"]["value"] > 7.3 > small.rows["limiting_magnitude"]["value"]
    )
    said = [w for w in large.warnings if "completeness" in w]
    assert len(said) == 1 and "hip2" in said[0]
    assert not any("completeness" in w for w in small.warnings)
    line = large.to_dict()
    assert line["warnings"] == list(large.warnings)
    assert line["rows"]["nea_cross_arcsec"] == large.rows["nea_cross"]  # the same, named


def test_capped_value_is_flagged_and_written_as_a_bound():
    payload = {
        "availability": {"fastest_rate_deg_s": {"lost_in_space": {"50": 10.0, "90": 4.0}}},
        "slew": {"rates_deg_s": [0.0, 5.0, 10.0]},
    }
    rows = row_values(payload)
    assert rows["fastest_50"] == {"value": 10.0, "capped": True}
    assert rows["fastest_90"] == {"value": 4.0, "capped": False}
    assert rows["fastest_99"] == {"value": None, "capped": False}  # absent: no value
    assert format_value(10.0, ".0f", capped=True) == ">= 10"
    assert format_value(None, ".2f") == "n/a"


@pytest.mark.slow
def test_dask_gives_identical_rows():
    pytest.importorskip("distributed", reason="the scale extra (dask.distributed) is not installed")
    from starsense.scale import dask_client

    base = base_document("st16")
    todo = designs(base, [parse_vary("exposure_s=0.05,0.2"), parse_vary("optics.aperture_m=0.012")])
    st = prediction_settings(**_FAST)
    here = run_trade(todo, settings=st, workers=1)
    with dask_client("local:1", processes=False) as client:
        there = run_trade(todo, settings=st, client=client)
    assert [r.to_dict() for r in here.rows] == [r.to_dict() for r in there.rows]


@pytest.mark.slow
def test_st16_prediction_agrees_with_rendered_frames():
    """The fast prediction is the datasheet's; on 40 rendered frames at rest the measured rms
    per axis is within the project's 0.8-1.25 of it (40 frames: ~11 % 1-sigma on an rms)."""
    cat = as_catalog(None)
    fast = predict("st16", cat).to_dict()
    full = datasheet("st16", cat, n_trials=40, n_rate_trials=1).to_dict()
    assert fast["nea_arcsec"] == full["nea_arcsec"]
    assert fast["availability"] == full["availability"]
    mc = full["monte_carlo"]
    assert mc["wrong"] == 0
    assert 0.8 <= mc["cross_ratio"] <= 1.25 and 0.8 <= mc["roll_ratio"] <= 1.25


@pytest.mark.slow
def test_verify_pareto_checks_only_the_front_on_frames():
    base = base_document("st16")
    todo = designs(base, [parse_vary("exposure_s=0.05,0.2")])
    st = prediction_settings(**_FAST)
    plain = run_trade(todo, settings=st, workers=1)
    checked = run_trade(todo, settings=st, n_frames=2, verify="pareto", workers=1)
    for before, after in zip(plain.rows, checked.rows, strict=True):
        on_front = any(before.pareto.values())
        assert after.verified == on_front
        # the predicted rows do not move when frames are added; the measured ones appear
        assert after.rows["nea_cross"] == before.rows["nea_cross"]
        assert (after.rows["lis_solved_rest"]["value"] is not None) == on_front


@pytest.mark.slow  # two designs' predictions and statements: ~1 min
def test_trade_statement_totals_are_the_designs_statements():
    from starsense.analysis.ecss import ecss_statement

    base = base_document("st16")
    todo = designs(base, [parse_vary("optics.focal_length_m=0.012,0.02")])
    st = prediction_settings(rng=4, n_orientations=150)
    study = run_trade(todo, settings=st, statement=True)
    for design, row in zip(todo, study.rows, strict=True):
        stated = ecss_statement(design.sensor(), rates_deg_s=(0.0, 1.0), settings=st)
        for i, where in enumerate(("rest", "rate")):
            for a in ("x", "y", "z"):
                want = stated.totals[i][f"total_{a}_arcsec"]
                # the same design, catalogue and seed: the same number
                assert row.rows[f"ecss_total_{a}_{where}"]["value"] == pytest.approx(
                    want, rel=1e-12
                )
    plain = run_trade(todo[:1], settings=st)
    assert plain.rows[0].rows["ecss_total_x_rest"]["value"] is None  # not asked: not stated
