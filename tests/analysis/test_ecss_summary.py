"""The vendor-style summary: each line from where it says, nothing invented."""

from __future__ import annotations

import pytest

from starsense.analysis.ecss.summary import vendor_summary
from starsense.plotting.figure import save_pdf
from starsense.plotting.summary import summary_page
from starsense.sensor import load_sensor

#: a datasheet's JSON reduced to what the summary reads (the values are arbitrary but distinct)
SHEET = {
    "sensor": "st16",
    "fov_deg": [20.2, 15.2],
    "availability": {
        "lost_in_space": 0.97,
        "fastest_rate_deg_s": {"tracking": {"50": 2.0, "90": 1.5, "99": 1.17}},
    },
    "monte_carlo": {"frames": 40, "solved": 38, "median_ms": 12.5},
}


def _total(axis: str, rate: float, value: float) -> dict:
    return {"class": "total", "axis": axis, "rate_deg_s": rate, "value_arcsec": value}


ROWS = [
    _total("X", 0.0, 0.33),
    _total("Y", 0.0, 0.32),
    _total("Z", 0.0, 2.7),
    _total("X", 1.0, 0.7),
    _total("Y", 1.0, 0.65),
    _total("Z", 1.0, 4.9),
    {"class": "temporal_noise", "axis": "X", "rate_deg_s": 0.0, "value_arcsec": 99.0},
]


def _lines(summary) -> dict:
    return {line["key"]: line for line in summary["lines"]}


def test_each_line_is_its_sources_number():
    sensor = load_sensor("st16")
    got = _lines(vendor_summary(SHEET, ROWS, confidence=0.6827, sensor=sensor, mass_kg=0.28))
    assert got["accuracy_rest_arcsec"]["values"] == [0.33, 0.32, 2.7]  # the totals, not a term
    assert got["accuracy_1_deg_s_arcsec"]["values"] == [0.7, 0.65, 4.9]
    assert got["max_tracking_rate_deg_s"]["values"] == [1.17]
    assert got["lost_in_space_success_fraction"]["values"] == [38 / 40, 0.97]
    assert got["lost_in_space_time_ms"]["values"] == [12.5]
    # one attitude a frame: the rate is the exposure's inverse
    assert got["update_rate_hz"]["values"] == [pytest.approx(1.0 / sensor.exposure_s)]
    assert got["sky_coverage_fraction"]["values"] == [0.97]
    ex = sensor.exclusion.to_dict()  # the TOML's degrees, read back
    assert got["exclusion_deg"]["values"] == pytest.approx(
        [ex["sun_deg"], ex["moon_deg"], ex["earth_limb_deg"]], rel=1e-12
    )
    assert got["mass_kg"]["values"] == [0.28] and got["mass_kg"]["source"] == "given by the user"
    assert got["power_w"]["value"] == "not given" and got["power_w"]["values"] == [None]


def test_no_frames_and_no_exclusion_say_so():
    sensor = load_sensor("esa_blackfly").with_(exclusion=None)
    sheet = {**SHEET, "monte_carlo": {"frames": 0, "solved": 0, "median_ms": None}}
    got = _lines(vendor_summary(sheet, ROWS, confidence=0.95, sensor=sensor))
    assert got["lost_in_space_success_fraction"]["values"][0] is None
    assert got["lost_in_space_time_ms"]["value"] == "n/a"
    assert got["exclusion_deg"]["value"] == "not given"


def test_the_page_is_a_pdf(tmp_path):
    summary = vendor_summary(SHEET, ROWS, confidence=0.6827, sensor=load_sensor("st16"))
    path = save_pdf(summary_page(summary, note="test"), tmp_path / "s.pdf")
    assert path.read_bytes()[:5] == b"%PDF-" and path.stat().st_size > 1000
    assert [p.name for p in tmp_path.iterdir()] == ["s.pdf"]  # no temporary left beside it
