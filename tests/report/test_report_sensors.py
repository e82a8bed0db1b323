"""The real-sensor table loader: good files, and bad ones with errors naming line and column."""

from __future__ import annotations

import math

import pytest

from starsense.errors import InputError
from starsense.report import load_sensor_table, theta_from_sigmas


def write(tmp_path, text, name="sensors.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_theta_form(tmp_path):
    path = write(
        tmp_path,
        "# my sensors\nname,diameter_m,exposure_s,theta_rms_arcsec\n\n"
        "A,0.1,0.1,5\nB,0.05,0.2,12.5\n",
    )
    a, b = load_sensor_table(path)
    assert (a.name, a.diameter_m, a.exposure_s, a.theta_rms_arcsec) == ("A", 0.1, 0.1, 5.0)
    assert a.sigma_cross_arcsec is None
    assert b.line == 5
    assert b.figure_of_merit == pytest.approx(0.05**2 * math.sqrt(0.2))
    assert a.theta_rms_rad == pytest.approx(5.0 / 206264.80624709636)


def test_sigma_form_uses_two_cross_axes(tmp_path):
    # sec. 3.5: theta^2 = sigma_x^2 + sigma_y^2 + sigma_z^2 with sigma_x = sigma_y
    path = write(
        tmp_path,
        "name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec\n"
        '"Tracker, rev B",0.12,0.25,3.0,20.0\n',
    )
    (s,) = load_sensor_table(path)
    assert s.name == "Tracker, rev B"
    assert s.theta_rms_arcsec == pytest.approx(math.sqrt(2 * 3.0**2 + 20.0**2))
    assert (s.sigma_cross_arcsec, s.sigma_roll_arcsec) == (3.0, 20.0)
    assert theta_from_sigmas(3.0, 4.0) == pytest.approx(math.sqrt(34.0))


def test_columns_in_any_order_with_bom(tmp_path):
    path = tmp_path / "s.csv"
    path.write_bytes(
        "theta_rms_arcsec,name,exposure_s,diameter_m\n7,X,0.5,0.2\n".encode("utf-8-sig")
    )
    (s,) = load_sensor_table(path)
    assert (s.name, s.diameter_m, s.exposure_s, s.theta_rms_arcsec) == ("X", 0.2, 0.5, 7.0)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\nA,0.1,0.1,5\nB,abc,0.1,5\n",
            r"sensors\.csv, line 3, column 2 \(diameter_m\): 'abc' is not a number",
        ),
        (
            "name,diameter_m,theta_rms_arcsec\nA,0.1,5\n",
            r"sensors\.csv, line 1: missing column 'exposure_s'",
        ),
        (
            "name,diameter_m,exposure_s,sigma_cross_arcsec\nA,0.1,0.1,5\n",
            r"line 1: missing column 'sigma_roll_arcsec'",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\nA,0,0.1,5\n",
            r"line 2, column 2 \(diameter_m\): must be a finite number > 0, got '0'",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\nA,0.1,-0.01,5\n",
            r"line 2, column 3 \(exposure_s\): must be a finite number > 0, got '-0.01'",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\nA,0.1,nan,5\n",
            r"line 2, column 3 \(exposure_s\): must be a finite number > 0",
        ),
        (
            "name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec\nA,0.1,0.1,1,x\n",
            r"line 2, column 5 \(sigma_roll_arcsec\): 'x' is not a number",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\nA,0.1,0.1\n",
            r"line 2: 3 fields, but the header has 4",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec\n,0.1,0.1,5\n",
            r"line 2, column 1 \(name\): empty",
        ),
        (
            "name,diameter_m,exposure_s,theta_rms_arcsec,sigma_roll_arcsec\nA,0.1,0.1,5,3\n",
            r"line 1: give either theta_rms_arcsec or sigma_cross_arcsec",
        ),
        ("", r"sensors\.csv: sensors table is empty"),
        ("name,diameter_m,exposure_s,theta_rms_arcsec\n", r"has a header but no sensors"),
    ],
)
def test_bad_tables(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        load_sensor_table(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"sensors table not found: .*nope\.csv"):
        load_sensor_table(tmp_path / "nope.csv")
