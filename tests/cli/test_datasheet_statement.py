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
        (["--summary-pdf", "{d}/s.pdf"], "--summary-pdf needs --statement"),
        (["--mass-kg", "0.3"], "--mass-kg needs --statement"),
        (["--statement", "--mass-kg", "-1"], "--mass-kg = -1.0 must be a positive number"),
        (["--statement", "--power-w", "nan"], "--power-w"),
        (
            ["--statement", "--compare", "esa_blackfly", "--summary-pdf", "{d}/s.pdf"],
            "--summary-pdf writes one sensor's table",
        ),
        (
            ["--statement", "--compare", "esa_blackfly", "--budget-csv", "{d}/b.csv"],
            "--budget-csv writes one sensor's table",
        ),
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
    pdf = path.with_name("summary.pdf")
    args = [*LIGHT, "--statement", "--rates", "0,0.5,1", "--budget-csv", str(path)]
    args += ["--summary-pdf", str(pdf), "--mass-kg", "0.3"]
    rc, out, err = _run("datasheet", *args, "--json")
    assert rc == 0, err
    return json.loads(out), path.read_text(), pdf


@pytest.mark.slow
def test_summary_page_states_the_totals_and_what_was_given(light):
    s = light[0]["statement"]
    lines = {line["key"]: line for line in s["summary"]["lines"]}
    totals = {
        (r["axis"], r["rate_deg_s"]): r["value_arcsec"] for r in s["rows"] if r["class"] == "total"
    }
    for rate, key in ((0.0, "accuracy_rest_arcsec"), (0.5, "accuracy_0.5_deg_s_arcsec")):
        assert lines[key]["values"] == [totals[(a, rate)] for a in "XYZ"]
    assert lines["mass_kg"]["values"] == [0.3] and lines["power_w"]["value"] == "not given"
    assert light[2].read_bytes()[:5] == b"%PDF-" and str(light[2]) in s["files"]


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


@pytest.mark.slow  # two datasheets and two statements: ~1 min
def test_compare_carries_each_sensors_statement_totals():
    argv = ["--trials", "3", "--n-orientations", "120", "--seed", "3", "--rates", "0,1"]
    rc, out, err = _run(
        "datasheet", "--sensor", "st16", "--compare", "esa_blackfly", "--statement", *argv, "--json"
    )
    assert rc == 0, err
    d = json.loads(out)
    rows = {r["key"]: r["values"] for r in d["rows"]}
    for k, sheet in enumerate(d["sensors"]):
        totals = {
            (r["axis"], r["rate_deg_s"]): r["value_arcsec"]
            for r in sheet["statement"]["rows"]
            if r["class"] == "total"
        }
        for axis in ("x", "y", "z"):
            # the comparison's row is the sensor's own statement total, at rest and at the rate
            assert rows[f"ecss_total_{axis}_rest"][k] == totals[(axis.upper(), 0.0)]
            assert rows[f"ecss_total_{axis}_rate"][k] == totals[(axis.upper(), 1.0)]
            assert rows[f"ecss_total_{axis}_rate"][k] > 0
    rc, text, _ = _run(
        "datasheet", "--sensor", "st16", "--compare", "esa_blackfly", "--statement", *argv
    )
    assert rc == 0 and "ECSS total X at rest, arcsec" in text
