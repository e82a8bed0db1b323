"""`starsense trade`: bad input refused before any work, rows as JSON lines and CSV, Dask."""

from __future__ import annotations

import csv
import io
import json

import pytest

from starsense.cli import main

_CHEAP = ["--sensor", "st16", "--workers", "1"]


@pytest.mark.parametrize(
    ("argv", "fragments"),
    [
        (["--vary", "optics.focal_lenght_m=0.01,0.02"], ["unknown key", "focal_lenght_m"]),
        (["--vary", "exposure_s=0.1:0.2:1"], ["exposure_s", "0.1:0.2:1", "N must be"]),
        (
            ["--vary", "exposure_s=0.01:1:101", "--vary", "optics.focal_length_m=0.01:0.05:101"],
            ["10,201 designs", "--dask"],
        ),
        ([], ["--vary"]),
        (["--vary", "exposure_s=0.1", "--keep", "colour"], ["--keep", "colour"]),
        (["--vary", "exposure_s=0.1", "--verify", "some"], ["--verify", "some"]),
    ],
)
def test_bad_input_is_one_line_exit_2(argv, fragments, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = main(["trade", *_CHEAP, *argv])
    captured = capsys.readouterr()
    assert code == 2, captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    for fragment in fragments:
        assert fragment in lines[0]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_json_lines_csv_and_out(capsys, tmp_path):
    argv = [
        "trade",
        *_CHEAP,
        "--vary",
        "exposure_s=0.1",
        "--vary",
        "detector.pixel_pitch_m=-1,6e-6",
    ]
    assert main([*argv, "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2  # one object per line, one line per design
    row = json.loads(lines[0])
    assert row["rows"] is None and "pixel_pitch_m" in row["error"]  # its own error, exit 0
    good = json.loads(lines[1])
    assert good["error"] is None
    assert good["rows"]["nea_cross_arcsec"]["value"] > 0  # keys carry their unit
    assert "fastest_rate_99pct_deg_s" in good["rows"] and isinstance(good["warnings"], list)
    assert main([*argv, "--csv", "--out", str(tmp_path / "t")]) == 0
    table = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert len(table) == 2 and table[0]["exposure_s"] == "0.1"
    assert {"nea_cross_arcsec", "nea_cross_arcsec_capped", "warnings"} <= set(table[1])
    names = sorted(p.name for p in (tmp_path / "t").iterdir())
    assert "trade.jsonl" in names and "trade.csv" in names
    assert any(n.startswith("trade_pareto_") and n.endswith(".png") for n in names)


@pytest.mark.slow
def test_dask_and_worker_processes_give_identical_rows(capsys):
    pytest.importorskip("distributed", reason="the scale extra (dask.distributed) is not installed")
    grid = ["--vary", "optics.focal_length_m=0.02,0.03", "--vary", "exposure_s=0.05,0.2"]
    out = {}
    for where in (["--workers", "2"], ["--dask", "local:2"]):
        assert main(["trade", "--sensor", "st16", *grid, *where, "--json"]) == 0
        out[where[0]] = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(out["--workers"]) == 4
    assert out["--workers"] == out["--dask"]  # a design is a pure function of its document


def test_every_design_failing_is_an_error_and_writes_nothing(capsys, tmp_path):
    """A grid of which no design could be evaluated is not a result: exit 2, one line, no file."""
    argv = ["trade", *_CHEAP, "--vary", "detector.pixel_pitch_m=-1,-2", "--json"]
    assert main([*argv, "--out", str(tmp_path / "t")]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "every design of the grid failed (2 of 2)" in lines[0]
    assert "pixel_pitch_m" in lines[0]
    assert not (tmp_path / "t").exists() or list((tmp_path / "t").iterdir()) == []
