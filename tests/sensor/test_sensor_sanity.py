"""Physical sanity of a sensor: what cannot exist is refused at load (one line, exit 2), what is
suspicious is said in the datasheet's warnings, in the text and in the JSON."""

from __future__ import annotations

import json
import tomllib
from importlib import resources

import numpy as np
import pytest

from starsense.analysis.datasheet.checks import empty_pixel_sigma_counts, sanity_warnings
from starsense.catalog import Catalog
from starsense.cli import main
from starsense.errors import InputError
from starsense.photometry.colour import (
    EVANS2018_G_MINUS_V_BP_RP,
    EVANS2018_G_MINUS_V_BV,
    gaia_to_johnson,
    magnitudes_in,
    with_johnson_from_gaia,
)
from starsense.sensor import load_sensor


def _toml(tmp_path, name="s", **changes):
    """The ST-16 preset with ``section__key=value`` changes, as a TOML file."""
    data = tomllib.loads(
        (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    )
    for dotted, value in changes.items():
        section, key = dotted.split("__")
        data[section][key] = value
    lines = [f'name = "{name}"', f"exposure_s = {data['exposure_s']}"]
    for section in ("optics", "detector", "detection"):
        lines.append(f"[{section}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in data[section].items()]
    path = tmp_path / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        # f = 16 mm behind a 114 mm aperture: f/0.14, faster than any lens in air (f/0.5)
        ({"optics__aperture_m": 0.114}, "f/0.14 is below f/0.5"),
        # a 12-bit ADC gives at most 4095 counts over a zero bias
        ({"detection__lit_pixel_counts": 5000.0}, "no pixel can exceed it"),
        ({"detection__lit_pixel_counts": 0.5}, "below one ADC count"),
        ({"detection__min_integrated_counts": 0.25}, "below one ADC count"),
    ],
)
def test_what_cannot_exist_is_refused(tmp_path, capsys, changes, words):
    path = _toml(tmp_path, **changes)
    with pytest.raises(InputError, match=words.replace("/", "/").replace(".", r"\.")):
        load_sensor(str(path))
    rc = main(["datasheet", "--sensor", str(path), "--json"])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


def test_the_fastest_real_lenses_load(tmp_path):
    # f/0.95 (the CCD design of the zoo) and exactly f/0.5 are physical
    load_sensor(str(_toml(tmp_path, "a", optics__aperture_m=0.016 / 0.95)))
    load_sensor(str(_toml(tmp_path, "b", optics__aperture_m=0.032)))


def test_st16_logic_on_a_low_gain_detector_is_said(tmp_path, capsys):
    # the ST-16's 120-count lit threshold on a 0.5 counts/e- detector: 120 / (0.5 x 3.5 e-) =
    # 69 sigma of the read noise (68 with quantisation); with a tiny aperture it sees
    # nothing, so the run is short
    changes = {"detector__gain_counts_per_e": 0.5, "optics__aperture_m": 1e-5}
    path = _toml(tmp_path, "lowgain", detector__bias_counts=0.0, **changes)
    sigma = empty_pixel_sigma_counts(load_sensor(str(path)))
    assert sigma == pytest.approx(np.hypot(0.5 * 3.5, 1 / np.sqrt(12)))
    argv = ["datasheet", "--sensor", str(path), "--trials", "2", "--n-orientations", "100"]
    assert main([*argv, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    said = [w for w in d["warnings"] if "sigma of an empty pixel" in w]
    assert len(said) == 1 and "68 sigma" in said[0]
    # a bias of 0 counts is said too, in the JSON and the text
    bias = "bias 0 counts is 0.0 sigma of the read noise (1.77 counts): the ADC clips"
    assert sum(w.startswith(bias) for w in d["warnings"]) == 1
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "lowgain: the lit-pixel threshold (120 counts) is 68 sigma" in text
    assert f"lowgain: {bias}" in text


def test_sanity_warnings_in_words(tmp_path):
    # 120 counts / (6.5 x 3.5 e-) = 5.3 sigma, and a bias of 100 counts (4.4 sigma) keeps the
    # noise off the ADC's zero: nothing to say
    sens = load_sensor(str(_toml(tmp_path, "biased", detector__bias_counts=100.0)))
    assert sanity_warnings(sens, catalog_name="hip2", limit_mag=5.7, runs={}) == []
    # past Hipparcos's completeness (V = 7.3): the warning names it and suggests Gaia
    (w,) = sanity_warnings(sens, catalog_name="hip2", limit_mag=8.4, runs={})
    assert "past hip2's completeness (V = 7.3" in w and "--catalog gaia" in w
    noisy = load_sensor(
        str(_toml(tmp_path, detection__lit_pixel_counts=40.0, detector__bias_counts=100.0))
    )
    (w,) = sanity_warnings(noisy, catalog_name="hip2", limit_mag=5.7, runs={})
    assert "1.8 sigma" in w  # 40 / 22.75 counts


def test_a_bias_below_three_sigma_is_said_in_words(tmp_path):
    # the ST-16 with a bias of 0: its read noise, 22.75 counts (22.75 with the ADC's 1/12
    # count^2), is clipped at zero. The rectified Gaussian's closed form (mean s phi(0) =
    # 0.3989 s, rms s sqrt(1/2 - 1/(2 pi)) = 0.5838 s, 50 % at 0) with the rounding's half count
    # (the pixels below +0.5 read 0: 50.9 %) gives 9.08 counts above the bias and 13.3 rms
    zero = load_sensor(str(_toml(tmp_path, "b0", detector__bias_counts=0.0)))
    (w,) = sanity_warnings(zero, catalog_name="hip2", limit_mag=5.7, runs={})
    assert w.startswith("bias 0 counts is 0.0 sigma of the read noise (22.8 counts): the ADC")
    assert "9.08 counts above the bias with 13.3 counts rms, 51% of them 0" in w
    # at 2.9 sigma (66 counts) still said, at 3.0 sigma (69 counts) not
    for bias, said in ((66.0, 1), (69.0, 0)):
        sens = load_sensor(str(_toml(tmp_path, f"b{bias:g}", detector__bias_counts=bias)))
        got = sanity_warnings(sens, catalog_name="hip2", limit_mag=5.7, runs={})
        assert len(got) == said, got


def test_a_run_at_the_rate_without_a_prediction_is_said_in_words():
    from types import SimpleNamespace

    from starsense.analysis.datasheet.verify import _ratios

    sens = load_sensor("st16")
    # every frame's prediction NaN (no star predicted bright enough at the rate): the measured
    # rms is kept, nothing is divided by NaN
    e = np.full((12, 3), 1e-5)
    out = _ratios(e, np.full(12, np.nan), np.full(12, np.nan))
    assert out["cross_ratio"] is None and out["cross_rms_arcsec"] > 0
    run = SimpleNamespace(
        frames=40,
        solved=12,
        rate_deg_s=1.0,
        cross_rms_arcsec=out["cross_rms_arcsec"],
        cross_predicted_arcsec=None,
    )
    said = sanity_warnings(
        sens, catalog_name="hip2", limit_mag=5.7, runs={"monte_carlo_at_rate": run}
    )
    (w,) = [w for w in said if "deg/s" in w]  # beside the ST-16's bias at 0 counts
    assert "at 1 deg/s 12 frames solved" in w and "measured, not predicted" in w


def test_gaia_v_agrees_with_an_independent_relation():
    # Riello et al. 2021 (EDR3) and Evans et al. 2018 (DR2) fit G - V against BP - RP on
    # different data: over the range both cover they agree within their combined scatter
    # (0.03 and 0.046 mag rms: 0.055 mag)
    c = np.linspace(0.0, 2.5, 26)
    v, _ = gaia_to_johnson(np.zeros_like(c), c)
    evans = np.polynomial.polynomial.polyval(c, EVANS2018_G_MINUS_V_BP_RP)
    assert np.max(np.abs(-v - evans)) < 0.055


def test_gaia_b_v_of_the_sun_and_the_inversion():
    # the Sun: BP - RP = 0.82, B - V = 0.653 (Casagrande & VandenBerg 2018, MNRAS 479, L102);
    # within Evans's 0.063 mag rms
    _, bv = gaia_to_johnson(np.array([0.0]), np.array([0.82]))
    assert bv[0] == pytest.approx(0.653, abs=0.063)
    # the inversion: Evans's cubic at the B - V returned gives back the G - V it was solved for
    c = np.linspace(0.3, 2.5, 12)
    _, bv = gaia_to_johnson(np.zeros_like(c), c)
    target = np.polynomial.polynomial.polyval(c, EVANS2018_G_MINUS_V_BP_RP)
    back = np.polynomial.polynomial.polyval(bv, EVANS2018_G_MINUS_V_BV)
    assert np.max(np.abs(back - target)) < 1e-3  # the 0.001 mag table step


def test_a_gaia_catalogue_gets_v_and_b_v():
    cat = Catalog.from_columns(
        name="gaia_dr3",
        source="test",
        epoch_yr=2016.0,
        ids=[1, 2, 3],
        ra_deg=[0.0, 10.0, 20.0],
        dec_deg=[0.0, 5.0, -5.0],
        mags={"G": [5.0, 6.0, 7.0]},
        colours={"BP-RP": [0.82, np.nan, 1.5]},
    )
    out, note = with_johnson_from_gaia(cat)
    v, bv = gaia_to_johnson(np.array([5.0, 6.0, 7.0]), np.array([0.82, 1.0, 1.5]))
    np.testing.assert_allclose(out.mags["V"], v)
    np.testing.assert_allclose(out.colours["B-V"], bv)
    assert "Riello et al. 2021" in note and "1 of 3 stars have no BP-RP" in note
    assert with_johnson_from_gaia(out) == (out, None)  # V already there: as is


def test_a_star_without_the_band_takes_it_from_its_other_bands():
    """G from V and B - V (Evans et al. 2018's cubic), V from G and BP - RP (Riello et al.).

    The Sun (B - V = 0.653, BP - RP = 0.82: Casagrande & VandenBerg 2018): its G - V from B - V
    and from BP - RP, two relations fitted to different stars, agree within their rms (0.063
    and 0.03 mag); a star with its own G keeps it; a catalogue with neither input gives NaN.
    """
    hip = Catalog.from_columns(
        name="hip2", source="test", epoch_yr=1991.25, ids=[1, 2, 3], ra_deg=[0.0, 10.0, 20.0],
        dec_deg=[0.0, 5.0, -5.0], mags={"V": [5.0, 6.0, 7.0], "G": [np.nan, 5.5, np.nan]},
        colours={"B-V": [0.653, 0.2, np.nan]},
    )  # fmt: skip
    g = magnitudes_in(hip, "G")
    # gaia_to_johnson at G = 0 returns V = -(G - V)
    from_bp_rp = 5.0 - gaia_to_johnson(np.array([0.0]), np.array([0.82]))[0][0]
    assert g[0] == pytest.approx(from_bp_rp, abs=0.063 + 0.03)
    assert g[1] == 5.5  # its own
    # no B - V: the colour of the default BP - RP (about a G dwarf's), not NaN
    assert np.isfinite(g[2]) and 6.5 < g[2] < 7.0
    gaia = Catalog.from_columns(
        name="gaia_dr3", source="test", epoch_yr=2016.0, ids=[1], ra_deg=[0.0], dec_deg=[0.0],
        mags={"G": [6.0]}, colours={"BP-RP": [0.82]},
    )  # fmt: skip
    assert magnitudes_in(gaia, "V")[0] == pytest.approx(gaia_to_johnson([6.0], [0.82])[0][0])
    assert np.isnan(magnitudes_in(gaia, "Ks")).all()


#: presets that reproduce a paper and no camera keep what the paper assumed (Lin et al. 2024:
#: a bias of 0); every other preset is a camera (the ST-16 at its detector's black level)
PAPER_PRESETS = {"lin2024"}


def test_camera_presets_have_a_bias_the_noise_is_not_clipped_at():
    """A real camera's preset sets its bias at >= 3 sigma of an empty pixel's noise, so its
    datasheet opens with no warning about its own ADC clipping the background."""
    from starsense.analysis.datasheet.checks import BIAS_SIGMAS
    from starsense.sensor.load import preset_names

    cameras = [n for n in preset_names() if n not in PAPER_PRESETS]
    assert cameras, "no camera preset to check"
    for name in cameras:
        sensor = load_sensor(name)
        sigma = empty_pixel_sigma_counts(sensor)
        assert sensor.detector.bias_counts >= BIAS_SIGMAS * sigma, name
        said = sanity_warnings(sensor, catalog_name="", limit_mag=None, runs={})
        assert not any(w.startswith("bias ") for w in said), name
