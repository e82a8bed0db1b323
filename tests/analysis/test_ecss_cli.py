"""``starsense ecss``: the statement's JSON and CSV agree, and bad input is one line, exit 2."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os

import pytest
from budget_csv import assert_totals_are_the_rows_sums

from starsense.cli import main

#: a light sky (the numbers' agreement between formats, not their precision)
LIGHT = ["--sensor", "st16", "--n-orientations", "120", "--n-slew-trials", "4"]


def _run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ecss")
    args = [*LIGHT, "--confidence", "95", "--rates", "0,1"]
    rc, out, err = _run("ecss", *args, "--out", str(folder / "s.csv"), "--json")
    assert rc == 0, err
    rc2, _, err2 = _run("ecss", *args, "--out", str(folder / "s.json"))
    assert rc2 == 0, err2
    return (
        json.loads(out),
        (folder / "s.csv").read_text(),
        json.loads((folder / "s.json").read_text()),
    )


def test_json_file_is_the_printed_json(written):
    printed, _, saved = written
    printed.pop("files")
    assert printed == saved
    assert saved["confidence"] == pytest.approx(0.95)
    assert saved["rates_deg_s"] == [0.0, 1.0]


def test_csv_round_trips_to_the_json(written):
    d, text, _ = written
    rows = list(csv.DictReader(io.StringIO(text)))
    by_term = {r["term"]: r for r in rows}
    assert [r["term"] for r in rows] == [t["key"] for t in d["terms"]] + [
        "total_bias", "total_noise", "total",
    ]  # fmt: skip
    for i, values in enumerate(d["values"]):
        lab = f"{values['rate_deg_s']:g}"
        for key, v in values.items():
            if key == "rate_deg_s":
                continue
            term, axis = key.rsplit("_", 2)[0], key.rsplit("_", 2)[1]
            cell = by_term[term][f"{axis}_arcsec_at_{lab}_deg_s"]
            assert (cell == "" and v is None) or float(cell) == v, (key, i)


def test_csv_totals_recomputed_from_its_rows(written):
    # a small reference summation: root sum square of the counted rows, by bias / noise
    _, text, _ = written
    assert_totals_are_the_rows_sums(text, ("0", "1"))


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--confidence", "abc"], "--confidence"),
        (["--confidence", "150"], "--confidence"),
        (["--rates", "0,x"], "--rates"),
        (["--rates", "-1"], "--rates"),
        (["--out", "{d}/s.txt"], ".csv or .json"),
        (["--out", "{d}/missing/s.csv"], "does not exist"),
        (["--sensor", "no_such_sensor"], "no_such_sensor"),
    ],
)
def test_bad_input_is_one_line_and_no_file(tmp_path, argv, words):
    argv = [a.replace("{d}", str(tmp_path)) for a in argv]
    rc, _out, err = _run("ecss", *argv)
    assert rc == 2
    assert words in err and len(err.strip().splitlines()) == 1
    assert os.listdir(tmp_path) == []


def test_refuses_a_fifo(tmp_path):
    fifo = tmp_path / "s.csv"
    os.mkfifo(fifo)
    rc, _, err = _run("ecss", "--out", str(fifo))
    assert rc == 2 and "FIFO" in err.upper()
    assert sorted(os.listdir(tmp_path)) == ["s.csv"] and fifo.is_fifo()
