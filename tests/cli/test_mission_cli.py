"""`starsense availability mission`: the documented interface, JSON keys, figure, bad input."""

from __future__ import annotations

import json
import math
import re
import warnings
from importlib import resources

import pytest

from starsense.analysis.mission import TimeGrid, TleAgeWarning, TleOrbit, parse_tle
from starsense.cli.app import main
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.sensor import load_sensor
from starsense.units import DEG

#: Vallado et al. 2006 verification TLE, satellite 00005 (epoch 2000-06-27 18:50 UTC)
TLE5 = [
    "1 00005U 58002B   00179.78495062  .00000023  00000-0  28098-4 0  4753",
    "2 00005  34.2682 348.7242 1859667 331.7664  19.3264 10.82419157413667",
]
#: a tolerable-slew curve in the form `starsense slew tolerance --json` writes (input, not a
#: result: it skips the slew Monte Carlo): m_t = 5.5 at rest, 4.85 at 1 deg/s, 4.2 at 2 deg/s
TOLERANCE = {
    "sensor": "st16",
    "model": "test",
    "magnitudes": [4.2, 4.85, 5.5, 5.75],
    "tolerable_rate_deg_s": [2.0, 1.0, 0.0, None],
    "capped": [False] * 4,
    "rates_deg_s": [0.0, 10.0],
}
PLUS_Y = "st16@0.7071068,0,0,0.7071068"
MINUS_Y = "st16@-0.7071068,0,0,0.7071068"
ZENITH = "st16@1,0,0,0"


@pytest.fixture(scope="module")
def tol(tmp_path_factory):
    path = tmp_path_factory.mktemp("tol") / "tolerance.json"
    path.write_text(json.dumps(TOLERANCE))
    return str(path)


def run(capsys, *argv):
    code = main(["availability", "mission", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_documented_interface_json_and_plot(capsys, tol, tmp_path):
    plot = tmp_path / "timeline.png"
    code, out, err = run(
        capsys,
        "--orbit",
        "sso:550:6",
        "--attitude",
        "nadir",
        "--heads",
        PLUS_Y,
        MINUS_Y,
        ZENITH,
        "--start",
        "2025-03-20T00:00:00",
        "--duration-h",
        "2",
        "--step-s",
        "10",
        "--tolerance-json",
        tol,
        "--json",
        "--plot",
        str(plot),
    )
    assert code == 0, err
    res = json.loads(out)
    assert res["steps"] == 720
    assert [h["name"] for h in res["heads"]] == [PLUS_Y, MINUS_Y, ZENITH]
    keys = {
        "name",
        "available_fraction",
        "sun_blinded_fraction",
        "moon_blinded_fraction",
        "earth_blinded_fraction",
        "outages",
        "longest_outage_s",
    }
    for h in res["heads"]:
        assert keys <= set(h)
    assert set(res["combined"]) == {"available_fraction", "outages", "longest_outage_s"}
    # dawn-dusk orbit, nadir: the Sun stays near the orbit normal (body -Y with +x along the
    # velocity): one horizontal head sees it all the time, the other never; the zenith head
    # is never blinded by the Earth
    sun = sorted(h["sun_blinded_fraction"] for h in res["heads"][:2])
    assert sun == [0.0, 1.0]
    assert res["heads"][2]["earth_blinded_fraction"] == 0.0
    assert res["combined"]["available_fraction"] >= res["heads"][2]["available_fraction"]
    assert plot.stat().st_size > 10_000


def test_quaternion_file_profile_equals_inertial(capsys, tol, tmp_path):
    q = attitude_from_radec_roll(80.0 * DEG, 30.0 * DEG, 0.0).as_quat()
    csv = tmp_path / "q.csv"
    csv.write_text(
        "t_s,qx,qy,qz,qw\n"
        + "".join(f"{t},{q[0]:.17g},{q[1]:.17g},{q[2]:.17g},{q[3]:.17g}\n" for t in (0, 4000))
    )
    common = [
        "--orbit",
        "circular:700:98",
        "--heads",
        "st16",
        "--duration-h",
        "1",
        "--step-s",
        "30",
        "--tolerance-json",
        tol,
        "--json",
    ]
    outs = []
    for att in (f"quaternions:{csv}", "inertial:80,30,0"):
        code, out, err = run(capsys, "--attitude", att, *common)
        assert code == 0, err
        outs.append(json.loads(out))
    strip = ("attitude",)
    assert {k: v for k, v in outs[0].items() if k not in strip} == {
        k: v for k, v in outs[1].items() if k not in strip
    }


def test_tle_run_and_age_warning(capsys, tol, tmp_path):
    tle = tmp_path / "sat5.tle"
    tle.write_text("VANGUARD 1\n" + "\n".join(TLE5) + "\n")
    code, out, err = run(
        capsys,
        "--tle",
        str(tle),
        "--heads",
        "st16",
        "--attitude",
        "sun",
        "--duration-h",
        "0.5",
        "--step-s",
        "60",
        "--tolerance-json",
        tol,
        "--json",
    )
    assert code == 0, err
    assert "warning" not in err
    assert json.loads(out)["start"].startswith("2000-06-27T18:50")
    code, out, err = run(
        capsys,
        "--tle",
        str(tle),
        "--heads",
        "st16",
        "--attitude",
        "sun",
        "--start",
        "2000-08-01T00:00:00",
        "--duration-h",
        "0.5",
        "--step-s",
        "60",
        "--tolerance-json",
        tol,
        "--json",
    )
    assert code == 0
    assert "warning: the span is +34.2 days from the TLE epoch" in err
    with pytest.warns(TleAgeWarning, match=r"\+34\.2 days"):
        TleOrbit(*TLE5).state(TimeGrid.span("2000-08-01T00:00:00", 60.0, 30.0))


def _broken(line: int, col: int, char: str) -> str:
    lines = list(TLE5)
    s = lines[line - 1]
    lines[line - 1] = s[: col - 1] + char + s[col:]
    return "\n".join(lines)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (_broken(2, 12, "x"), r"line 2, columns 9-16: inclination '34x2682' is not a number"),
        (_broken(1, 69, "9"), r"line 1, column 69: checksum '9' does not match"),
        (_broken(1, 1, "3"), r"line 1, column 1: expected line number 1"),
        (TLE5[0] + "\n" + TLE5[1][:60], r"line 2, column 61: a TLE line has 69 characters"),
        (TLE5[0], r"a TLE has 2 lines"),
    ],
)
def test_malformed_tle_names_line_and_column(text, message):
    with pytest.raises(InputError, match=message):
        parse_tle(text, "sat.tle")


def test_malformed_tle_cli_one_line(capsys, tmp_path):
    tle = tmp_path / "bad.tle"
    tle.write_text("NAME\n" + _broken(2, 12, "x"))
    code, out, err = run(capsys, "--tle", str(tle), "--heads", "st16")
    assert code == 2 and out == ""
    assert err.strip().count("\n") == 0
    assert f"{tle}, line 3, columns 9-16: inclination" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--heads", "st16@0,0,0,2"], "norm 2: not a rotation"),
        (["--heads", "st16@0,0,0"], "expects 4 finite numbers"),
        (["--heads", "st16@xyz:90,0"], "expects 3 finite numbers"),
        (["--heads", "st16@xq:90,0"], "Euler sequence must be 1-3 of xyz"),
        (["--heads", "st16", "--step-s", "0"], r"--step-s = 0\.0 is out of range"),
        (["--heads", "st16", "--duration-h", "-1"], r"--duration-h = -1\.0 is out of range"),
        (["--heads", "st16", "--attitude", "spin"], "--attitude"),
        (["--heads", "st16", "--orbit", "sso:50"], r"altitude \(km\) = 50\.0 is out of range"),
        (["--heads", "st16", "--start", "yesterday"], "not an ISO 8601 time"),
    ],
)
def test_bad_input_one_line_exit_2_no_file(capsys, tmp_path, tol, argv, message):
    plot = tmp_path / "t.png"
    if "--orbit" not in argv:
        argv = [*argv, "--orbit", "sso:550"]
    code, out, err = run(capsys, *argv, "--tolerance-json", tol, "--plot", str(plot))
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert re.search(message, err), err
    assert not plot.exists() and list(tmp_path.iterdir()) == []


def test_exclusion_out_of_range_in_toml(capsys, tmp_path, tol):
    text = (resources.files("starsense.sensor") / "presets" / "st16.toml").read_text()
    bad = tmp_path / "st16_bad.toml"
    bad.write_text(text.replace("sun_deg = 45.0", "sun_deg = 200.0"))
    with pytest.raises(InputError, match=r"exclusion\.sun_deg = 200\.0 is out of range"):
        load_sensor(bad)
    code, _, err = run(capsys, "--orbit", "sso:550", "--heads", str(bad), "--tolerance-json", tol)
    assert code == 2 and str(bad) in err and "[0.0, 180.0]" in err


def test_sensor_exclusion_preset_and_no_warning():
    exc = load_sensor("st16").exclusion
    assert math.isclose(exc.sun_rad, 45.0 * DEG) and exc.atmosphere_m == 100e3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        TleOrbit(*TLE5).state(TimeGrid.span("2000-06-28T00:00:00", 60.0, 30.0))
