"""`starsense datasheet`: the JSON interface, agreement with the commands that compute the same
thing, and sensors that see too little."""

from __future__ import annotations

import contextlib
import io
import json
import math
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from starsense.analysis.datasheet.sheet import _limit
from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.geometry.fov import CircularFov
from starsense.identify.hashing import MIN_SOLVING_STARS
from starsense.sensor import load_sensor

#: a light run: 3 frames per rate, 300 boresights (the numbers are checked for agreement with
#: the other commands, not for their statistics)
LIGHT = ["--trials", "3", "--n-orientations", "300", "--seed", "2"]


def _no_nan(text: str) -> dict:
    def refuse(name):
        raise AssertionError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def run(capsys, *argv, code=0):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    assert rc == code, err
    return out, err


@pytest.fixture(scope="module")
def st16_sheet(tmp_path_factory):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["datasheet", "--sensor", "st16", *LIGHT, "--json"])
    assert rc == 0
    return _no_nan(buf.getvalue())


def test_interface_keys(st16_sheet):
    d = st16_sheet
    for key in (
        "sensor",
        "fov_deg",
        "pixel_scale_arcsec",
        "limiting_magnitude",
        "stars_in_fov",
        "nea_arcsec",
        "limit_arcsec",
        "monte_carlo",
        "availability",
        "budget",
    ):
        assert key in d, key
    assert set(d["stars_in_fov"]) >= {"median", "p05"}
    assert set(d["nea_arcsec"]["cross"]) >= {"median", "p95"}
    mc_keys = {
        "frames",
        "solved",
        "wrong",
        "cross_rms_arcsec",
        "roll_rms_arcsec",
        "cross_ratio",
        "roll_ratio",
        "median_ms",
    }
    assert set(d["monte_carlo"]) >= mc_keys
    for axis in ("cross", "roll"):  # each ratio with its 95 % interval (none: too few frames)
        mc = d["monte_carlo"]
        assert (mc[f"{axis}_ratio_ci95"] is None) == (mc[f"{axis}_ratio"] is None)
    assert set(d["availability"]) >= {
        "lost_in_space",
        "tracking",
        "rates_deg_s",
        "lost_in_space_at_rate",
        "tracking_at_rate",
    }
    assert all(set(b) >= {"term", "cross_arcsec", "roll_arcsec", "source"} for b in d["budget"])
    # the ST-16's 2592 x 1944 px of 2.2 um behind f = 16 mm: 2 atan(2.85 / 16) = 20.21 deg
    assert d["fov_deg"][0] == pytest.approx(2 * math.degrees(math.atan(2592 * 2.2e-3 / 32)))
    # the physical limit (diffraction, every photon) lies far below the sensor's NEA
    assert d["limit_arcsec"]["cross"] < d["nea_arcsec"]["cross"]["median"]
    assert d["limit_arcsec"]["roll"] < d["nea_arcsec"]["roll"]["median"]
    # roll / cross follows the field geometry: 1 / rms field angle of the stars (within 25 %)
    ratio = d["roll_over_cross"]
    assert ratio["nea"] == pytest.approx(ratio["geometry"], rel=0.25)


def _schema():
    return json.loads((resources.files("starsense") / "data" / "datasheet.schema.json").read_text())


def test_datasheet_matches_its_schema(st16_sheet, capsys):
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(st16_sheet, _schema())
    out, _ = run(capsys, "datasheet", "--schema")
    assert json.loads(out) == _schema()


def test_availability_agrees_with_availability_dynamic(st16_sheet, capsys, tmp_path):
    d = st16_sheet
    tol = tmp_path / "tol.json"
    tol.write_text(json.dumps(d["slew"]))
    st = d["settings"]
    rates = ",".join(repr(r) for r in d["availability"]["rates_deg_s"])
    out, _ = run(
        capsys,
        "availability",
        "dynamic",
        "--sensor",
        "st16",
        "--fov",
        "rectangular",
        "--max-mag",
        repr(st["catalog_cut_mag"]),
        "--n-orientations",
        str(st["n_orientations"]),
        "--seed",
        str(st["seed"]),
        "--rates-deg-s",
        rates,
        "--tolerance-json",
        str(tol),
        "--n-min",
        "5",  # the solver's: its 4-star pattern and one more star
        "--json",
    )
    ref = _no_nan(out)
    assert ref["availability_by_n_min"]["5"] == d["availability"]["lost_in_space_at_rate"]
    assert ref["availability_by_n_min"]["2"] == d["availability"]["tracking_at_rate"]


def test_slew_tolerance_agrees_with_slew_command(st16_sheet, capsys):
    s = st16_sheet["slew"]
    out, _ = run(
        capsys,
        "slew",
        "tolerance",
        "--sensor",
        "st16",
        "--magnitudes",
        ",".join(repr(m) for m in s["magnitudes"]),
        "--rates-deg-s",
        ",".join(repr(r) for r in s["rates_deg_s"]),
        "--trials",
        str(s["n_trials"]),
        "--seed",
        str(s["seed"]),
        "--json",
    )
    ref = _no_nan(out)
    # same seeds, same renders: equal to the last digit (rates read back from deg/s differ by
    # at most one ulp, which moves no pixel)
    for a, b in zip(ref["tolerable_rate_deg_s"], s["tolerable_rate_deg_s"], strict=True):
        assert (a is None and b is None) or a == pytest.approx(b, rel=1e-12)


def test_limit_agrees_with_limit_sky(capsys):
    sens = load_sensor("st16")
    out, _ = run(
        capsys,
        "limit",
        "sky",
        "--diameter-m",
        "0.012",
        "--exposure-s",
        "0.1",
        "--fov-deg",
        "20",
        "--target-deg",
        "83.8,-5.4",
        "--json",
    )
    ref = _no_nan(out)
    head = ref["heads"][0] if "heads" in ref else ref
    east, north, roll = head["axis_sigma_rad"]
    att = attitude_from_radec_roll(np.radians([83.8]), np.radians([-5.4]), np.zeros(1))
    cross, rl = _limit(
        load_catalog("hipparcos"),
        sens,
        CircularFov(math.radians(10)),
        att.as_matrix().reshape(-1, 3, 3),
    )
    # the same eq. 21 over the same stars: to rounding
    assert cross[0] == pytest.approx(math.sqrt(0.5 * (east**2 + north**2)), rel=1e-9)
    assert rl[0] == pytest.approx(roll, rel=1e-9)


def _sensor_toml(tmp_path, name, **changes):
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    data = tomllib.loads(text)
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


def test_sensor_that_sees_nothing_says_so(capsys, tmp_path):
    blind = _sensor_toml(tmp_path, "blind", optics__aperture_m=1e-5)
    out, _ = run(capsys, "datasheet", "--sensor", str(blind), *LIGHT, "--json")
    d = _no_nan(out)
    assert d["limiting_magnitude"] is None
    assert "detects no star" in d["warnings"][0]
    pytest.importorskip("jsonschema").validate(d, _schema())
    out, _ = run(capsys, "datasheet", "--sensor", str(blind), *LIGHT)
    assert "detects no star" in out


@pytest.mark.slow
def test_sensor_with_too_few_stars_says_so(capsys, tmp_path):
    narrow = _sensor_toml(tmp_path, "narrow", optics__focal_length_m=0.5)  # 0.65 deg field
    out, _ = run(capsys, "datasheet", "--sensor", str(narrow), *LIGHT, "--json")
    d = _no_nan(out)
    # lost in space needs the solver's 4-star pattern and one more star
    assert any(f"fewer than the {MIN_SOLVING_STARS}" in w for w in d["warnings"])
    assert d["monte_carlo"]["wrong"] == 0


def test_unknown_quoted_key_is_named(capsys, tmp_path):
    path = _sensor_toml(tmp_path, "q")
    path.write_text(path.read_text() + '[quoted]\nsource = "x"\naccuracy = 5\n')
    _, err = run(capsys, "datasheet", "--sensor", str(path), "--json", code=2)
    assert "unknown key 'accuracy'" in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_compare_two_apertures(capsys, tmp_path):
    a = _sensor_toml(tmp_path, "small", optics__aperture_m=0.012)
    b = _sensor_toml(tmp_path, "large", optics__aperture_m=0.024)
    out, _ = run(capsys, "datasheet", "--compare", str(a), "--compare", str(b), *LIGHT, "--json")
    payload = _no_nan(out)
    small, large = payload["sensors"]
    rows = {r["key"]: r for r in payload["rows"]}  # the trade rows, one value per sensor
    assert rows["nea_cross"]["values"] == [
        small["nea_arcsec"]["cross"]["median"],
        large["nea_arcsec"]["cross"]["median"],
    ]
    assert len(rows["fastest_99"]["capped"]) == 2
    # 4x the photons: fainter limit, more stars, and each star centroided better
    assert large["limiting_magnitude"] > small["limiting_magnitude"]
    assert large["nea_arcsec"]["cross"]["median"] < small["nea_arcsec"]["cross"]["median"] / 2
    out, _ = run(capsys, "datasheet", "--compare", str(a), "--compare", str(b), *LIGHT)
    assert "small" in out and "large" in out
    assert "fastest rate keeping 99 %, deg/s" in out and "NEA / limit cross" in out


@pytest.mark.parametrize(
    ("name", "stem"), [("../x", "_x"), ("a/b", "a_b"), ("..", "sensor"), ("st 16", "st_16")]
)
def test_out_writes_the_json_under_a_safe_name(capsys, tmp_path, name, stem):
    blind = _sensor_toml(tmp_path, "blind", optics__aperture_m=1e-5)
    blind.write_text(blind.read_text().replace('name = "blind"', f"name = {json.dumps(name)}"))
    out_dir = tmp_path / "out"
    out, _ = run(
        capsys, "datasheet", "--sensor", str(blind), *LIGHT, "--json", "--out", str(out_dir)
    )
    d = _no_nan(out)
    written = out_dir / f"{stem}_datasheet.json"
    assert d["files"] == [str(written)]
    # read back: the sheet as printed, less the list of files
    assert _no_nan(written.read_text()) == {k: v for k, v in d.items() if k != "files"}
    assert [p.name for p in out_dir.iterdir()] == [written.name]  # nothing outside, no temporary
    assert not (tmp_path / "x_datasheet.json").exists()


def test_out_two_sensors_of_one_name_write_two_files(capsys, tmp_path):
    a = _sensor_toml(tmp_path, "blind", optics__aperture_m=1e-5)
    b = tmp_path / "other.toml"
    b.write_text(a.read_text().replace("aperture_m = 1e-05", "aperture_m = 2e-05"))
    out_dir = tmp_path / "out"
    argv = ["datasheet", "--compare", str(a), "--compare", str(b), *LIGHT, "--json"]
    out, _ = run(capsys, *argv, "--out", str(out_dir))
    files = _no_nan(out)["files"]
    assert sorted(files) == [
        str(out_dir / "blind-2_datasheet.json"),
        str(out_dir / "blind_datasheet.json"),
    ]
    assert all(_no_nan(Path(f).read_text())["sensor"] == "blind" for f in files)


def test_sensor_with_compare_is_compared_first_not_dropped(capsys, tmp_path):
    """`--sensor X --compare A` compares X and A (X first); X is never dropped without a word."""
    x = _sensor_toml(tmp_path, "x", optics__aperture_m=1e-5)
    a = tmp_path / "a.toml"
    a.write_text(x.read_text().replace('name = "x"', 'name = "a"'))
    out, _ = run(capsys, "datasheet", "--sensor", str(x), "--compare", str(a), *LIGHT, "--json")
    assert [s["sensor"] for s in _no_nan(out)["sensors"]] == ["x", "a"]
