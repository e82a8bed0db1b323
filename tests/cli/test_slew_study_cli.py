"""`starsense slew study`: JSON keys, the figure, one-line errors."""

from __future__ import annotations

import json

import pytest

from starsense.cli import main

pytest.importorskip("starsense.detect.stack")


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_slew_study_json_and_plot(capsys, tmp_path):
    plot = tmp_path / "study.png"
    code, out, _ = run(
        capsys,
        "slew",
        "study",
        "--sensor",
        "st16",
        "--sigmas-px",
        "1.5,2.5",
        "--qe",
        "0.3,0.4",
        "--trials",
        "4",
        "--mag-step",
        "0.1",
        "--seed",
        "2",
        "--plot",
        str(plot),
        "--json",
    )
    assert code == 0
    res = json.loads(out)
    assert res["sigmas_px"] == [1.5, 2.5] and res["qe_means"] == [0.3, 0.4]
    assert res["rates_deg_s"] == [0.0, 1.0, 1.5, 2.0, 3.0]
    assert res["paper_rates_deg_s"] == [1.0, 1.5, 2.0, 3.0]
    # (S, Q, R) thresholds; a fainter threshold at the higher QE, by 2.5 log10(0.4 / 0.3)
    thr = res["threshold_mag"]
    assert len(thr) == 2 and len(thr[0]) == 2 and len(thr[0][0]) == 5
    assert thr[0][1][1] - thr[0][0][1] == pytest.approx(0.3124, abs=1e-4)
    assert set(res["best"]) >= {"sigma_px", "qe_mean", "worst_mismatch_mag", "reproduces"}
    assert res["seed"] == 2 and res["n_trials"] == 4
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_slew_study_text(capsys):
    code, out, _ = run(
        capsys, "slew", "study", "--sigmas-px", "1.5", "--trials", "4", "--mag-step", "0.1"
    )
    assert code == 0
    assert "paper" in out and "best physically sensible pair: sigma 1.5 px" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--qe", "0"], "--qe = 0.0 is out of range"),
        (["--sigmas-px", "1,x"], "--sigmas-px expects comma-separated numbers"),
        (["--mag-step", "0"], "--mag-step must be within"),
        (["--trials", "0"], "--trials must be >= 1"),
        (["--model", "blackbody"], "flat-QE model"),
        (["--sensor", "nosuch"], "unknown sensor 'nosuch'"),
    ],
)
def test_slew_study_bad_input_one_line(capsys, tmp_path, argv, message):
    plot = tmp_path / "p.png"
    code, _, err = run(capsys, "slew", "study", *argv, "--plot", str(plot))
    assert code == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not plot.exists()
