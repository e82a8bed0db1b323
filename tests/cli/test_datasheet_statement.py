"""``starsense datasheet --statement``: the ECSS statement's rows, budget CSV and Monte Carlo
coverage in the datasheet, and its usage errors."""

from __future__ import annotations

import contextlib
import io
import json
import os
from importlib import resources

import pytest
from budget_csv import assert_totals_are_the_rows_sums

from starsense.analysis.ecss.export import ROW_KEYS
from starsense.cli import main

#: a light run: 6 frames per rate, 120 boresights (the interface and its arithmetic, not the
#: statistics); 0.5 deg/s is not one of the datasheet's runs: it is rendered for the statement
LIGHT = ["--sensor", "st16", "--trials", "6", "--n-orientations", "120", "--seed", "3"]


def _run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--confidence", "95"], "--confidence needs --statement"),
        (["--rates", "0,1"], "--rates needs --statement"),
        (["--budget-csv", "{d}/b.csv"], "--budget-csv needs --statement"),
        (["--statement", "--compare", "esa_blackfly"], "--compare"),
        (["--statement", "--centroids-only"], "--centroids-only"),
        (["--statement", "--confidence", "150"], "--confidence"),
        (["--statement", "--rates", "0,x"], "--rates"),
        (["--statement", "--rates", "-1"], "--rates"),
        (["--statement", "--budget-csv", "{d}/missing/b.csv"], "does not exist"),
    ],
)
def test_usage_errors_are_one_line_exit_2_and_no_file(tmp_path, argv, words):
    argv = [a.replace("{d}", str(tmp_path)) for a in argv]
    rc, out, err = _run("datasheet", "--sensor", "st16", *argv)
    assert rc == 2 and out == ""
    assert words in err and len(err.strip().splitlines()) == 1
    assert os.listdir(tmp_path) == []


def test_budget_csv_refuses_a_fifo(tmp_path):
    fifo = tmp_path / "b.csv"
    os.mkfifo(fifo)
    rc, _, err = _run("datasheet", "--statement", "--budget-csv", str(fifo))
    assert rc == 2 and "FIFO" in err.upper() and len(err.strip().splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == ["b.csv"] and fifo.is_fifo()


@pytest.fixture(scope="module")
def light(tmp_path_factory):
    path = tmp_path_factory.mktemp("statement") / "budget.csv"
    args = [*LIGHT, "--statement", "--rates", "0,0.5,1", "--budget-csv", str(path)]
    rc, out, err = _run("datasheet", *args, "--json")
    assert rc == 0, err
    return json.loads(out), path.read_text()


@pytest.mark.slow  # a datasheet and a statement: ~30 s
def test_rows_have_exactly_the_named_keys(light):
    s = light[0]["statement"]
    assert s["rates_deg_s"] == [0.0, 0.5, 1.0]
    assert all(tuple(r) == ROW_KEYS for r in s["rows"])
    assert {r["axis"] for r in s["rows"]} == {"X", "Y", "Z"}
    assert {r["rate_deg_s"] for r in s["rows"]} == {0.0, 0.5, 1.0}
    # every (class, axis, rate) once
    keys = [(r["class"], r["axis"], r["rate_deg_s"]) for r in s["rows"]]
    assert len(keys) == len(set(keys))
    assert light[0]["statement"]["files"]
    schema = json.loads(
        (resources.files("starsense") / "data" / "datasheet.schema.json").read_text()
    )
    pytest.importorskip("jsonschema").validate(light[0], schema)


@pytest.mark.slow
def test_budget_csv_totals_recompute_from_its_rows(light):
    # a small reference summation from the CSV alone: per rate and axis the root sum square
    # of the counted terms, split by what each acts as at that rate
    totals = assert_totals_are_the_rows_sums(light[1], ("0", "0.5", "1"))
    assert set(totals) == {"total_bias", "total_noise", "total"}


@pytest.mark.slow
def test_coverage_recounts_from_the_frames(light):
    s = light[0]["statement"]
    frames = {f["rate_deg_s"]: f["errors_arcsec"] for f in s["frame_errors"]}
    by_total = {
        (r["axis"], r["rate_deg_s"]): r["value_arcsec"] for r in s["rows"] if r["class"] == "total"
    }
    assert len(s["coverage"]) == 3 * 3
    for c in s["coverage"]:
        e = frames[c["rate_deg_s"]]
        assert c["frames"] == len(e) and c["frames_rendered"] == 6
        if c["reason"] is not None:
            assert c["inside_1sigma"] is None and c["frames"] == 0
            continue
        j = "XYZ".index(c["axis"])
        # the statement is at 1 sigma here: its total is the coverage's 1-sigma bound
        assert c["bound_1sigma_arcsec"] == by_total[(c["axis"], c["rate_deg_s"])]
        for n in ("1", "3"):
            inside = sum(abs(f[j]) <= c[f"bound_{n}sigma_arcsec"] for f in e) / len(e)
            got = c[f"inside_{n}sigma"]
            assert 0.0 <= got <= 1.0 and got == pytest.approx(inside, abs=1e-12)
    origins = {c["rate_deg_s"]: c["frames_from"] for c in s["coverage"]}
    assert origins == {0.0: "datasheet", 0.5: "run for the statement", 1.0: "datasheet"}


@pytest.mark.slow
def test_text_prints_the_statement_and_its_coverage(tmp_path):
    rc, out, err = _run("datasheet", *LIGHT, "--statement", "--rates", "0")
    assert rc == 0, err
    assert "ECSS-E-ST-60-20C statement at 68.27 %" in out
    line = next(x for x in out.splitlines() if "coverage of the 1-sigma / 3-sigma" in x)
    assert "0 deg/s" in line and "of 6 frames" in line and " X " in line


#: the acceptance's frames per rate: a 68.27 % binomial of 400 frames spreads by
#: sqrt(0.683 * 0.317 / 400) = 0.023, so 0.60-0.76 is -3.6 / +3.3 sigma of it; a 99.73 %
#: one expects 1.1 frames outside, and 0.99 allows 4 (P(>= 5 | Poisson 1.1) = 0.5 %)
ACCEPTANCE_FRAMES = 400


@pytest.fixture(scope="module")
def acceptance():
    rc, out, err = _run(
        "datasheet", "--sensor", "st16", "--trials", str(ACCEPTANCE_FRAMES), "--statement",
        "--rates", "0,1", "--json",
    )  # fmt: skip
    assert rc == 0, err
    cov = json.loads(out)["statement"]["coverage"]
    assert len(cov) == 6
    assert all(c["frames"] >= 0.9 * ACCEPTANCE_FRAMES for c in cov), cov
    return {(c["rate_deg_s"], c["axis"]): c for c in cov}


@pytest.mark.slow  # 800 rendered frames: about 4 minutes
def test_st16_one_sigma_coverage_at_0_and_1_deg_s(acceptance):
    got = {k: c["inside_1sigma"] for k, c in acceptance.items()}
    assert all(0.60 <= v <= 0.76 for v in got.values()), got


@pytest.mark.slow
def test_st16_sky_ensemble_coverage_at_0_and_1_deg_s(acceptance):
    # the frames are drawn at random attitudes: they test the statement's ensemble bound (a
    # random attitude's); measured on seed 0 (400 frames a rate): 1-sigma 0.655-0.708, 3-sigma
    # 0.9946-1.0. Against the sky-median totals the 3-sigma coverage is 0.97-0.99 (the sky's
    # mixture of widths has heavier tails than one Gaussian of the median width)
    one = {k: c["inside_1sigma_sky_ensemble"] for k, c in acceptance.items()}
    three = {k: c["inside_3sigma_sky_ensemble"] for k, c in acceptance.items()}
    assert all(0.60 <= v <= 0.76 for v in one.values()), one
    assert all(v >= 0.99 for v in three.values()), three
