"""`starsense availability static|dynamic|track`: JSON keys, figures, one-line errors."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from starsense.cli import app, main
from starsense.cli.availability import availability_app
from starsense.errors import InputError

runner = CliRunner()

#: a tolerable-slew curve as `starsense slew tolerance --json` writes it: the thresholds the
#: paper's Table 2 implies (m_t = 4.78, 4.40, 3.875, 3.60 at 1, 1.5, 2, 3 deg/s)
TOLERANCE = {
    "sensor": "st16",
    "model": "paper-implied",
    "magnitudes": [3.6, 3.875, 4.40, 4.78, 5.75, 6.0],
    "tolerable_rate_deg_s": [3.0, 2.0, 1.5, 1.0, 0.0, None],
    "capped": [False] * 6,
    "rates_deg_s": [0.0, 10.0],
}


@pytest.fixture(scope="module")
def tolerance_json(tmp_path_factory):
    path = tmp_path_factory.mktemp("tol") / "tolerance.json"
    path.write_text(json.dumps(TOLERANCE))
    return path


def invoke(*argv):
    result = runner.invoke(availability_app, list(argv))
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    assert result.exit_code == 0, result.output
    return result.output


def test_static_json_bsc5_acceptance(bsc5_path):
    out = invoke(
        "static",
        "--sensor",
        "st16",
        "--catalog",
        f"bsc5:{bsc5_path}",
        "--max-mag",
        "5.75",
        "--n-min",
        "3",
        "--half-fov-deg",
        "7.5",
        "--json",
    )
    res = json.loads(out)
    assert {"availability", "n_orientations", "n_stars"} <= set(res)
    assert res["n_orientations"] == 10_000
    assert res["n_stars"] == 3852
    assert res["availability"] > 0.999


def test_static_text_prints_stars_used_and_writes_figures(tmp_path):
    plot, maps = tmp_path / "fig6.png", tmp_path / "maps"
    out = invoke(
        "static",
        "--n-orientations",
        "2000",
        "--max-mag",
        "5.0",
        "--fov",
        "rectangular",
        "--roll-deg",
        "30",
        "--plot",
        str(plot),
        "--maps",
        str(maps),
    )
    assert "stars used" in out and "spatial static availability" in out
    assert plot.stat().st_size > 1000
    assert sorted(p.name for p in maps.iterdir()) == [
        "static_sparse.png",
        "static_stars_in_field.png",
    ]


def test_dynamic_json_keys(tolerance_json):
    out = invoke(
        "dynamic",
        "--sensor",
        "st16",
        "--model",
        "reed",
        "--rates-deg-s",
        "0.5,1,1.5,2,3",
        "--n-min",
        "3",
        "--n-orientations",
        "3000",
        "--tolerance-json",
        str(tolerance_json),
        "--json",
    )
    res = json.loads(out)
    assert res["rates_deg_s"] == [0.5, 1.0, 1.5, 2.0, 3.0]
    assert len(res["availability"]) == 5
    assert all(0 <= a <= 1 for a in res["availability"])
    assert res["availability"] == sorted(res["availability"], reverse=True)  # m_t falls
    assert res["threshold_mag"][1] == pytest.approx(4.78)


def test_track_json_keys(tolerance_json, tmp_path):
    plot = tmp_path / "track.png"
    out = invoke(
        "track",
        "--sensor",
        "st16",
        "--model",
        "reed",
        "--rate-deg-s",
        "1",
        "--n-min",
        "3",
        "--n-orientations",
        "2000",
        "--inclination-step-deg",
        "10",
        "--track-samples",
        "300",
        "--tolerance-json",
        str(tolerance_json),
        "--plot",
        str(plot),
        "--json",
    )
    res = json.loads(out)
    assert {"mean", "max", "min", "inclinations_deg", "availability"} <= set(res)
    assert res["inclinations_deg"][0] == -90 and res["inclinations_deg"][-1] == 90
    assert len(res["availability"]) == len(res["inclinations_deg"]) == 19
    assert res["min"] <= res["mean"] <= res["max"]
    assert plot.stat().st_size > 1000


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["static", "--n-min", "0"], r"N_min \(--n-min\) = 0 is out of range"),
        (["static", "--n-orientations", "0"], r"--n-orientations\) = 0"),
        (["static", "--max-mag", "-9"], r"--max-mag -9 leaves no stars"),
        (["static", "--fov", "rectangular", "--half-fov-deg", "7.5"], r"circular field only"),
        (["dynamic", "--rates-deg-s", "1,-1"], r"= -1 deg/s is negative"),
        (["track", "--rate-deg-s", "-1"], r"--rate-deg-s\) = -1 deg/s is negative"),
        (["track", "--track-samples", "0"], r"--track-samples\) = 0"),
        (["dynamic", "--tolerance-json", "/nonexistent/tol.json"], r"--tolerance-json not found"),
    ],
)
def test_bad_input_raises_input_error(argv, message):
    with pytest.raises(InputError, match=message):
        invoke(*argv)


def test_registered_in_main_app_one_line_exit_2(capsys):
    names = {g.name for g in app.registered_groups}
    if "availability" not in names:
        pytest.skip("availability sub-app not registered in starsense.cli yet")
    code = main(["availability", "static", "--n-min", "0"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "--n-min" in err
