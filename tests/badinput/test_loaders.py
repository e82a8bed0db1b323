"""Loaders: deep nesting, scalars for lists, a byte-order mark, thousands of unknown keys, a
header-only catalogue and binary garbage, each one short line (or, for the BOM, accepted).
"""

from __future__ import annotations

import os
import stat

import pytest
from bad_files import SENSOR_TOML

from starsense.cli import main
from starsense.errors import MAX_MESSAGE_CHARS, InputError, one_line
from starsense.sensor import load_sensor
from starsense.sensor.detector import Detector
from starsense.solve.centroids import read_centroids

#: a terminal escape sequence (clear the screen, turn red) and a bell, as a hostile file holds
GARBAGE = "\x1b[2J\x1b[31mEVIL\x07"


def _run(argv, capsys) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) <= 1, captured.err
    return code, lines[0] if lines else ""


def _sensor(tmp_path, text, name="s.toml", encoding="utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


@pytest.mark.parametrize("command", ["render", "trade"])
def test_deeply_nested_toml_is_one_line(command, tmp_path, capsys):
    deep = SENSOR_TOML.replace(
        "exposure_s = 0.1", "exposure_s = 0.1\nx = " + "[" * 50_000 + "]" * 50_000
    )
    path = _sensor(tmp_path, deep)
    argv = ["render", "--out", tmp_path / "f.png", "--sensor", path]
    if command == "trade":
        argv = ["trade", "--sensor", path, "--vary", "exposure_s=0.1,0.2"]
    code, line = _run(argv, capsys)
    assert code == 2
    assert str(path) in line and "nested too deeply" in line
    assert not (tmp_path / "f.png").exists()


def test_scalar_for_a_list_is_one_line(tmp_path, capsys):
    path = _sensor(tmp_path, SENSOR_TOML + "passband_nm = 400.0\n")
    code, line = _run(["render", "--out", tmp_path / "f.png", "--sensor", path], capsys)
    assert code == 2
    assert "[detector] passband_nm must be a list of numbers" in line and "got 400.0" in line


@pytest.mark.parametrize(
    ("field", "value"), [("passband_nm", 400.0), ("qe_curve_nm", "abc"), ("qe_curve", 0.5)]
)
def test_detector_list_fields_checked_in_the_api(field, value):
    base = load_sensor("st16").detector
    kwargs = {f: getattr(base, f) for f in base.__dataclass_fields__}
    kwargs[field] = value
    with pytest.raises(InputError, match=rf"detector\.{field} must be a list of numbers"):
        Detector(**kwargs)


def test_byte_order_mark_in_sensor_toml_is_accepted(tmp_path):
    plain = load_sensor(_sensor(tmp_path, SENSOR_TOML, "plain.toml"))
    with_bom = load_sensor(_sensor(tmp_path, SENSOR_TOML, "bom.toml", encoding="utf-8-sig"))
    assert (tmp_path / "bom.toml").read_bytes().startswith(b"\xef\xbb\xbf")
    assert with_bom.detector == plain.detector and with_bom.optics == plain.optics


def test_byte_order_mark_in_trade_base_is_accepted(tmp_path, capsys):
    path = _sensor(tmp_path, SENSOR_TOML, "bom.toml", encoding="utf-8-sig")
    code = main(["trade", "--sensor", str(path), "--vary", "detector.pixel_pitch_m=-1,-2"])
    # past the TOML: both designs fail on their own pitch (the message says so), not on the BOM
    assert code == 2
    assert "every design of the grid failed" in capsys.readouterr().err


def test_byte_order_mark_in_centroid_csv_is_accepted(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("x,y,flux\n10.5,20.25,100\n30,40,50\n", encoding="utf-8-sig")
    got = read_centroids(path)
    assert got.xy.tolist() == [[10.5, 20.25], [30.0, 40.0]]
    assert got.flux.tolist() == [100.0, 50.0]


def test_thousands_of_unknown_keys_name_a_few_and_the_count(tmp_path, capsys):
    keys = "\n".join(f"k{i} = 1" for i in range(5000))
    path = _sensor(tmp_path, SENSOR_TOML.replace("[optics]", keys + "\n[optics]"))
    code, line = _run(["render", "--out", tmp_path / "f.png", "--sensor", path], capsys)
    assert code == 2
    assert "unknown top-level key(s) k0, k1, k10, k100, k1000 and 4,995 more (5,000 in all)" in line
    assert len(line) < 600  # was 40 KB


def test_header_only_catalogue_says_it_has_no_rows(tmp_path, capsys):
    src = tmp_path / "cat.csv"
    src.write_text("source_id,ra,dec,phot_g_mean_mag\n")
    code, line = _run(["catalog", "import", src, tmp_path / "hats"], capsys)
    assert code == 2
    assert line == f"error: cannot import {src}: the file has no rows (a header only)"
    assert not (tmp_path / "hats").exists()


@pytest.mark.parametrize("kind", ["centroids header", "centroids row", "catalog import"])
def test_binary_garbage_is_escaped_and_cut(kind, tmp_path, capsys):
    junk = GARBAGE * 3000
    path = tmp_path / "junk.csv"
    if kind == "centroids header":
        path.write_text(junk + "\n1,2\n")
        argv = ["solve", "--centroids", path, "--sensor", "st16"]
    elif kind == "centroids row":
        path.write_text("x,y\n" + junk + "\n")
        argv = ["solve", "--centroids", path, "--sensor", "st16"]
    else:
        path.write_text("source_id,ra,dec,phot_g_mean_mag\n" + junk + "\n")
        argv = ["catalog", "import", path, tmp_path / "hats"]
    code, line = _run(argv, capsys)
    assert code == 2
    assert str(path) in line
    assert line.isprintable()  # no escape sequence, bell or NUL reaches the terminal
    assert "\\x1b[2J" in line  # shown escaped
    assert len(line) < MAX_MESSAGE_CHARS + 100  # was 45 KB


def test_one_line_escapes_and_cuts():
    assert one_line("plain text") == "plain text"
    assert one_line("a\nb\x1b[0m\x00") == "a\\nb\\x1b[0m\\x00"
    cut = one_line("x" * 5000, limit=100)
    assert cut == "x" * 100 + " ... (4,900 more characters)"
    assert str(InputError("bad \x07 value")) == "bad \\x07 value"


@pytest.mark.parametrize(
    "argv",
    [
        ["availability", "dynamic", "--tolerance-json", "{fifo}"],
        ["availability", "fidelity", "--tolerance-json", "{fifo}"],
        ["report", "--out", "{out}", "--sensors", "{fifo}"],
    ],
    ids=lambda a: " ".join(a[:2]),
)
def test_a_fifo_given_as_an_input_file_is_refused_not_waited_on(argv, tmp_path, capsys):
    # reading a FIFO nobody writes waits for ever (the sweep's timeouts): refused at once
    fifo = tmp_path / "in.json"
    os.mkfifo(fifo)
    args = [a.format(fifo=fifo, out=tmp_path / "r") for a in argv]
    code = main(args)
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(fifo) in err and "not a regular file" in err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and sorted(tmp_path.iterdir()) == [fifo]


def test_a_path_with_a_nul_byte_is_named_not_a_value_error():
    # from Python (a command line cannot hold a NUL): the system's "embedded null byte"
    # ValueError escaped the readers and writers' checks
    from starsense._io import check_output, readable_file
    from starsense.errors import OutputError

    with pytest.raises(InputError, match=r"sensor file path a\\x00b holds a NUL byte"):
        readable_file("a\x00b", "sensor file")
    with pytest.raises(OutputError, match=r"--out path a\\x00b.png holds a NUL byte"):
        check_output("a\x00b.png", "--out")
