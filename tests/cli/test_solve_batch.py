"""`starsense solve F1 F2 DIR ...`: batches, one database load, one line per frame."""

from __future__ import annotations

import csv
import io
import json
import sys

import pytest

from starsense.cli import main


@pytest.fixture(scope="module")
def esa_two(shared_dir):
    folder = shared_dir / "data" / "images" / "esa"
    frames = sorted(folder.glob("*.tiff"))[:2]
    return frames, json.loads((folder / "reference.json").read_text())["frames"]


@pytest.fixture
def batch_dir(tmp_path, esa_two):
    frames, _ = esa_two
    d = tmp_path / "frames"
    d.mkdir()
    for f in frames:
        (d / f.name).symlink_to(f)
    (d / "c_corrupt.tiff").write_bytes(b"II*\x00 not really a TIFF")
    (d / "notes.txt").write_text("not an image: skipped")
    return d


def _run(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_batch_json_lines_one_per_frame_and_a_corrupt_frame_goes_on(batch_dir, esa_two, capsys):
    frames, reference = esa_two
    code, out, err = _run(["solve", str(batch_dir), "--sensor", "esa_blackfly", "--json"], capsys)
    rows = [json.loads(line) for line in out.splitlines()]
    names = [r["image"].rsplit("/", 1)[-1] for r in rows]
    assert names == sorted([f.name for f in frames] + ["c_corrupt.tiff"])  # sorted, no .txt
    by_name = dict(zip(names, rows, strict=True))
    assert by_name["c_corrupt.tiff"]["status"] == "unreadable"
    assert "not a readable image" in by_name["c_corrupt.tiff"]["message"]
    for f in frames:
        row = by_name[f.name]
        assert row["status"] == "solved"
        assert row["ra_deg"] == pytest.approx(reference[f.name]["ra_deg"], abs=0.01)
    # the fields of a single solve, plus "image"
    code1, out1, _ = _run(["solve", str(frames[0]), "--sensor", "esa_blackfly", "--json"], capsys)
    assert code1 == 0 and set(json.loads(out1)) <= set(by_name[frames[0].name])
    assert code == 1  # not every frame solved
    assert "Traceback" not in err


def test_batch_csv_table_and_jobs(batch_dir, esa_two, capsys):
    frames, _ = esa_two
    argv = ["solve", str(frames[0]), str(batch_dir), "--sensor", "esa_blackfly", "--jobs", "2"]
    code, out, _ = _run(argv, capsys)
    table = list(csv.DictReader(io.StringIO(out)))
    assert [r["status"] for r in table] == ["solved", "solved", "solved", "unreadable"]
    assert table[0]["image"] == str(frames[0]) and table[0]["ra_deg"] == table[1]["ra_deg"]
    assert table[3]["ra_deg"] == ""
    assert code == 1


def test_folder_without_images_is_one_line_exit_2(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("x")
    code, out, err = _run(["solve", str(empty), "--fov-deg", "10"], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "no images in this folder" in err


def test_batch_refuses_wcs_and_missing_paths(batch_dir, tmp_path, capsys):
    code, _, err = _run(["solve", str(batch_dir), "--wcs", str(tmp_path / "w.fits")], capsys)
    assert code == 2 and "--wcs writes one frame's WCS" in err
    assert not (tmp_path / "w.fits").exists()
    code, _, err = _run(["solve", str(batch_dir), str(tmp_path / "nope.tiff")], capsys)
    assert code == 2 and "image not found" in err
    code, _, err = _run(["solve"], capsys)
    assert code == 2 and "give a frame, a folder of frames or --centroids FILE" in err


def test_progress_bar_on_a_terminal_leaves_stdout_alone(batch_dir, capsys, monkeypatch):
    # stderr a terminal: the rich bar is drawn there; stdout still holds only the JSON lines

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    code, out, _ = _run(["solve", str(batch_dir), "--sensor", "esa_blackfly", "--json"], capsys)
    assert [json.loads(line)["status"] for line in out.splitlines()] == [
        "solved",
        "solved",
        "unreadable",
    ]
    assert code == 1
