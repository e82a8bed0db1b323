"""The typed datasheet: sections that read as the JSON does, and the entry points around it."""

from __future__ import annotations

import dataclasses
import json
import tomllib
from importlib import resources

import numpy as np
import pytest

from starsense.analysis.datasheet import (
    Comparison,
    Datasheet,
    DatasheetSettings,
    build_datasheet,
    datasheet,
)
from starsense.analysis.datasheet.sections import json_clean
from starsense.analysis.slew import SlewResult
from starsense.sensor import load_sensor, sensor_from_dict

LIGHT = {"n_trials": 2, "n_orientations": 100, "n_slew_trials": 4, "rng": 1}


@pytest.fixture(scope="module")
def sheet() -> Datasheet:
    return datasheet("st16", **LIGHT)


def _walk(obj, d: dict, path: str = ""):
    """Yield (path, typed value, JSON value) for every field of every section."""
    for f in dataclasses.fields(obj):
        key = f.metadata.get("key", f.name)
        if key not in d:
            continue
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, SlewResult):
            yield from _walk(value, d[key], f"{path}.{f.name}")
        elif isinstance(value, tuple) and value and dataclasses.is_dataclass(value[0]):
            for i, (v, dv) in enumerate(zip(value, d[key], strict=True)):
                yield from _walk(v, dv, f"{path}.{f.name}[{i}]")
        elif not isinstance(value, SlewResult | np.ndarray):
            yield f"{path}.{f.name}", value, d[key]


def test_typed_fields_read_as_the_json(sheet):
    d = sheet.to_dict()
    assert sheet.nea_arcsec.cross.median == d["nea_arcsec"]["cross"]["median"]
    assert (
        sheet.availability.fastest_rate_deg_s.tracking.p90
        == (d["availability"]["fastest_rate_deg_s"]["tracking"]["90"])
    )
    assert sheet.settings.n_trials == d["settings"]["trials"] == 2
    assert sheet.slew.tolerance_dict() == d["slew"]
    seen = 0
    for path, typed, plain in _walk(sheet, d):
        assert json_clean(typed) == plain, path
        seen += 1
    assert seen > 60


def test_to_dict_is_json_without_the_arrays(sheet):
    d = sheet.to_dict()
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text) == d
    assert not {"boresights", "nea_cross_rad", "dynamic"} & set(d)
    assert sheet.boresights.shape == (100, 3)
    assert sheet.nea_cross_rad.shape == (100,)


def test_sections_are_frozen(sheet):
    with pytest.raises(dataclasses.FrozenInstanceError):
        sheet.nea_arcsec.cross.median = 0.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sheet.sensor = "x"  # type: ignore[misc]


def test_entry_point_is_build_datasheet_with_its_settings(sheet):
    settings = DatasheetSettings(n_trials=2, seed=1, n_orientations=100, n_slew_trials=4)
    other = build_datasheet(load_sensor("st16"), settings=settings)
    strip = {"median_ms", "p95_ms"}
    for key in ("monte_carlo", "monte_carlo_at_rate"):
        a = {k: v for k, v in sheet.to_dict()[key].items() if k not in strip}
        b = {k: v for k, v in other.to_dict()[key].items() if k not in strip}
        assert a == b
    assert other.to_dict()["nea_arcsec"] == sheet.to_dict()["nea_arcsec"]


def test_comparison_rows_from_the_sheets(sheet):
    comp = Comparison.from_sheets([sheet, sheet])
    assert comp.sensors == ("st16", "st16")
    rows = {r.label: r.values for r in comp.rows}
    assert rows["NEA cross, arcsec"] == (sheet.nea_arcsec.cross.median,) * 2
    assert rows["LIS solved at rest"] == (sheet.monte_carlo.solved_fraction,) * 2
    assert comp.to_dict() == {
        "sensors": [sheet.to_dict(), sheet.to_dict()],
        "rows": [r.to_dict() for r in comp.rows],  # the trade rows, with their "capped" flags
    }


def test_blind_sensor_has_only_the_settings_and_why():
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    data = tomllib.loads(text)
    data["optics"]["aperture_m"] = 1e-5
    blind = sensor_from_dict({**data, "name": "blind"})
    sheet = datasheet(blind, **LIGHT)
    d = sheet.to_dict()
    assert list(d) == ["schema", "sensor", "limiting_magnitude", "warnings", "settings"]
    assert sheet.limiting_magnitude is None and sheet.nea_arcsec is None
    assert "detects no star" in sheet.warnings[0]
    assert Comparison.from_sheets([sheet]).rows[2].values == (None,)


def test_a_sky_fainter_than_the_limit_is_no_star():
    """A sky whose brightest star lies below the sensor's limit (the ST-16, V 5.8, over the
    catalogue's stars fainter than V 7) gives the blind sensor's sheet, saying both magnitudes,
    not an error."""
    from starsense.catalog import load_catalog

    hip = load_catalog("hipparcos")
    faint = hip.subset(np.asarray(hip.mags["V"]) > 7.0)
    sheet = datasheet(load_sensor("st16"), faint, **LIGHT)
    assert sheet.limiting_magnitude is None and sheet.nea_arcsec is None
    assert "detects no star of the sky" in sheet.warnings[0]
    assert "brightest star (V 7." in sheet.warnings[0]
