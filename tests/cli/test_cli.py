"""Command line: the interface the checks use, and one-line errors with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from starsense.cli import main
from starsense.cli.common import progress_bar


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_limit_star_table1_vega_json(capsys):
    # Paper Table 1 (D = 10 cm, t = 100 ms): Vega T 13231 K, C 2.96e-17, sigma 1.19e-10 rad;
    # tolerances (1.5 %, 6 %, 3 %): our passbands and Vega spectrum are not the paper's.
    code, out, _ = run(
        capsys,
        "limit",
        "star",
        "--mag-v",
        "0.03",
        "--b-v",
        "-0.001",
        "--diameter-m",
        "0.1",
        "--exposure-s",
        "0.1",
        "--json",
    )
    assert code == 0
    res = json.loads(out)
    assert set(res) >= {"temperature_k", "dilution", "photons", "sigma_rad"}
    assert res["temperature_k"] == pytest.approx(13231, rel=0.015)
    assert res["dilution"] == pytest.approx(2.96e-17, rel=0.06)
    assert res["sigma_rad"] == pytest.approx(1.19e-10, rel=0.03)
    # photons: the closed form of eq. 12's integral; about 8e7 for Vega in 10 cm x 100 ms
    assert 5e7 < res["photons"] < 1.5e8


def test_limit_star_table1_vega_hks_json(capsys):
    code, out, _ = run(
        capsys,
        "limit",
        "star",
        "--mag-h",
        "-0.004",
        "--h-ks",
        "-0.005",
        "--diameter-m",
        "0.1",
        "--exposure-s",
        "0.1",
        "--json",
    )
    assert code == 0
    res = json.loads(out)
    assert res["temperature_k"] == pytest.approx(10417, rel=0.015)
    assert res["dilution"] == pytest.approx(4.80e-17, rel=0.06)
    assert res["sigma_rad"] == pytest.approx(1.70e-10, rel=0.03)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--mag-v", "1", "--b-v", "nan"], "--b-v must be finite, got nan"),
        (["--mag-v", "1", "--b-v", "0.5", "--diameter-m", "0"], "--diameter-m = 0.0 is out"),
        (["--mag-v", "1", "--b-v", "0.5", "--exposure-s", "-1"], "--exposure-s = -1.0 is out"),
        (["--mag-v", "1"], "--mag-v and --b-v must be given together"),
        (["--mag", "1", "--colour-index", "0.2", "--colour", "X-Y"], "unknown colour system"),
    ],
)
def test_limit_star_bad_input_one_line_exit_2(capsys, argv, message):
    code, out, err = run(capsys, "limit", "star", *argv)
    assert code == 2
    assert message in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert out == ""


def test_limit_sky_unknown_catalog(capsys):
    code, _, err = run(capsys, "limit", "sky", "--catalog", "nosuch:thing", "--json")
    assert code == 2
    assert "nosuch" in err and "Traceback" not in err


def test_limit_sky_fov_without_target(capsys):
    code, _, err = run(capsys, "limit", "sky", "--fov-deg", "10")
    assert code == 2
    assert "--fov-deg and --target-deg go together" in err


def test_console_script_exit_code_and_single_line():
    # The installed entry point, in a fresh process: exit 2, one line on stderr, no traceback.
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from starsense.cli import main; sys.exit(main())",
            "limit",
            "star",
            "--mag-v",
            "1",
            "--b-v",
            "0.2",
            "--diameter-m",
            "-3",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("error: --diameter-m = -3.0 is out of range")
    assert len(proc.stderr.strip().splitlines()) == 1


def test_python_dash_m_starsense_is_the_command_line():
    # `python -m starsense` runs the same command line as the script: same error, same exit
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "starsense",
            "limit",
            "star",
            "--mag-v",
            "1",
            "--b-v",
            "0.2",
            "--diameter-m",
            "-3",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("error: --diameter-m = -3.0 is out of range")


def test_fialho2019_sec33_g_interval_bundled_catalogue(capsys):
    # Acceptance: G over the bundled Hipparcos lies inside the paper's interval for G,
    # 7e-15 < G < 1e-13 rad m^2 s^1/2 (sec. 3.3). With D = 1 m, t = 1 s, theta_rms is G itself.
    code, out, _ = run(capsys, "limit", "sky", "--diameter-m", "1", "--exposure-s", "1", "--json")
    assert code == 0
    res = json.loads(out)
    assert set(res) >= {"theta_rms_rad", "axis_sigma_rad", "n_stars", "g_rad_m2_s05"}
    assert res["n_stars"] == 117_955  # every hip2 star has Hp and B-V
    assert 7e-15 < res["g_rad_m2_s05"] < 1e-13
    assert res["g_rad_m2_s05"] == pytest.approx(res["theta_rms_rad"], rel=1e-12)


def test_limit_sky_fov_360_equals_whole_sky_and_merge(capsys):
    # A 360 deg field sees every star: each head equals the whole-sky limit, and two identical
    # heads merged gain exactly sqrt(2) (paper Table 2, first row).
    _, out, _ = run(capsys, "limit", "sky", "--diameter-m", "0.1", "--exposure-s", "0.01", "--json")
    sky = json.loads(out)
    _, out, _ = run(
        capsys,
        "limit",
        "sky",
        "--diameter-m",
        "0.1",
        "--exposure-s",
        "0.01",
        "--fov-deg",
        "360",
        "--target-deg",
        "0,0",
        "--target-deg",
        "90,0",
        "--json",
    )
    fov = json.loads(out)
    for head in fov["heads"]:
        assert head["theta_rms_rad"] == pytest.approx(sky["theta_rms_rad"], rel=1e-12)
    assert fov["merged"]["theta_rms_rad"] == pytest.approx(sky["theta_rms_rad"] / 2**0.5, rel=1e-12)


def test_limit_sky_max_mag_leaving_no_stars(capsys):
    code, _, err = run(capsys, "limit", "sky", "--max-mag", "-5")
    assert code == 2
    assert "--max-mag -5.0 leaves 0 star(s)" in err


def test_limit_sky_malformed_catalogue_names_file_line_field(capsys, tmp_path):
    # A Gaia CSV whose second data row has a letter in 'ra': file, line and field are named.
    path = tmp_path / "bad.csv"
    path.write_text(
        "source_id,ra,dec,phot_g_mean_mag,bp_rp\n1,10.0,20.0,5.0,0.8\n2,1x.5,21.0,6.0,0.9\n"
    )
    code, out, err = run(capsys, "limit", "sky", "--catalog", f"gaia:{path}")
    assert code == 2 and out == ""
    assert "bad.csv" in err and "line 3" in err and "ra" in err
    assert len(err.strip().splitlines()) == 1


def test_limit_sky_bad_target(capsys):
    code, _, err = run(capsys, "limit", "sky", "--fov-deg", "10", "--target-deg", "0,95")
    assert code == 2
    assert "Dec within [-90, 90]" in err


def test_slew_tolerance_json_interface(capsys):
    code, out, _ = run(
        capsys,
        "slew",
        "tolerance",
        "--sensor",
        "st16",
        "--model",
        "reed",
        "--magnitudes",
        "3,4,8",
        "--rates-deg-s",
        "0,1,2,4,8",
        "--trials",
        "4",
        "--json",
    )
    assert code == 0
    res = json.loads(out)
    assert res["magnitudes"] == [3.0, 4.0, 8.0]
    tol = res["tolerable_rate_deg_s"]
    assert tol[2] is None  # m = 8 is ~12 e- under Reed: never detected
    assert tol[0] > tol[1] > 0


def test_slew_bad_rates_one_line(capsys):
    code, _, err = run(capsys, "slew", "tolerance", "--rates-deg-s", "0,-1", "--json")
    assert code == 2 and "rates must be >= 0 deg/s" in err
    code, _, err = run(capsys, "slew", "intensity", "--sensor", "nosuch")
    assert code == 2 and "unknown sensor 'nosuch'" in err


def test_render_writes_frame_and_truth(capsys, tmp_path):
    from PIL import Image

    out = tmp_path / "frame.tiff"
    code, stdout, _ = run(
        capsys,
        "render",
        "--sensor",
        "st16",
        "--ra-deg",
        "83.8",
        "--dec-deg",
        "-5.4",
        "--roll-deg",
        "0",
        "--rate-deg-s",
        "0.5,0,0",
        "--seed",
        "4",
        "--max-mag",
        "5",
        "--out",
        str(out),
    )
    assert code == 0, stdout
    image = np.array(Image.open(out))
    assert image.shape == (1944, 2592)
    assert image.max() <= 4095  # 12-bit ADC
    truth = json.loads((tmp_path / "frame.tiff.json").read_text())
    assert truth["n_stars"] > 5  # Orion to V 5 in a 15 x 20 deg field
    assert truth["seed"] == 4


def test_render_bad_rate_and_extension(capsys, tmp_path):
    code, _, err = run(capsys, "render", "--rate-deg-s", "1,2", "--out", str(tmp_path / "f.tiff"))
    assert code == 2 and "--rate-deg-s expects 3 values" in err
    code, _, err = run(capsys, "render", "--max-mag", "3", "--out", str(tmp_path / "f.bmp"))
    assert code == 2 and "Traceback" not in err
    assert not (tmp_path / "f.bmp").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["montecarlo", "--rate-deg-s", "-1"], "--rate-deg-s = -1.0 is out of range"),
        (["montecarlo", "--trials", "0"], "--trials must be >= 1, got 0"),
        (["render", "--dec-deg", "95", "--out", "x.png"], "--dec-deg = 95.0 is out of range"),
        (["render", "--ra-deg", "nan", "--out", "x.png"], "--ra-deg must be finite"),
        (["report", "--diameter-m", "0"], "--diameter-m = 0.0 is out of range"),
    ],
)
def test_options_checked_at_the_edge_under_their_own_names(capsys, tmp_path, argv, message):
    # the command validates its options (in their units) before converting and calling the API
    argv = [str(tmp_path / a) if a == "x.png" else a for a in argv]
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_progress_bar_hidden_when_not_a_terminal_or_json(monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    with progress_bar() as bar:
        assert not bar.shown and bar.callback is None
        bar("label", 1, 2)  # a no-op, not an error
        bar.task("one task", total=3)(1, 3)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with progress_bar(enabled=False) as bar:  # --json
        assert not bar.shown and bar.callback is None


def test_progress_bar_labelled_tasks_and_partitions(monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with progress_bar(unit="partitions") as bar:
        assert bar.shown and bar.callback is bar
        bar("whole-sky limit", 0, 4)
        bar("whole-sky limit", 3, 4)
        step = bar.task("Monte Carlo", total=10)
        step(5, 10)
        tasks = {t.description: t for t in bar._bar.tasks}
    assert set(tasks) == {"whole-sky limit", "Monte Carlo"}
    assert tasks["whole-sky limit"].completed == 3 and tasks["whole-sky limit"].total == 4
    assert tasks["Monte Carlo"].completed == 5
