"""Every bad input a clean error: exit 2, one line naming the thing and its value, no traceback,
no file left behind.

One line per case: the arguments (``{bad}`` is the folder of bad files built by conftest.py,
``{out}`` an empty folder the command may write into) and the fragments the one-line message
must hold (the option or file, and the value). Run in-process (``starsense.cli.main``): every
case fails before the work starts, so the whole table takes seconds.
"""

from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

import pytest

import starsense._io.files as io_mod
from starsense.cli import main
from starsense.cli.common import step_grid


def _closed_port() -> int:
    with socket.create_server(("127.0.0.1", 0)) as server:
        return server.getsockname()[1]  # freed on exit: nothing listens there


ST = ["--sensor", "st16"]

# fmt: off
CASES = [
    # -- A: files that cannot be read, named --------------------------------------------------
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/latin1.toml"],
     ["latin1.toml", "not UTF-8", "0xe9"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/adir.toml"],
     ["adir.toml", "is a directory"]),
    (["render", "--out", "{out}/f.png", "--sensor", ""], ["sensor is empty", "st16"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/nosuch.toml"],
     ["sensor file not found", "nosuch.toml"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/gain.toml"],
     ["gain_counts_per_e", "1e-30"]),
    (["solve", "{bad}/huge.png"], ["huge.png", "200000 x 200000", "STARSENSE_MAX_PIXELS"]),
    (["solve", "{bad}/huge2.png"], ["huge2.png", "65535 x 65535", "268,435,456"]),
    (["solve", "{bad}/huge.fits"], ["huge.fits", "65535 x 65535", "STARSENSE_MAX_PIXELS"]),
    (["solve", "{bad}/nobitpix.fits"], ["nobitpix.fits", "no BITPIX"]),
    (["solve", "{bad}/blankbitpix.fits"], ["blankbitpix.fits", "BITPIX is blank"]),
    (["solve", "{bad}/short.fits"], ["short.fits", "promises 20,000 bytes", "truncated"]),
    (["solve", "{bad}/nan.fits"], ["nan.fits", "64 pixels are NaN or infinite"]),
    (["solve", "{bad}/onebit.png"], ["onebit.png", "1-bit"]),
    # a folder is a batch of frames: an empty one is named as such
    (["solve", "{bad}/adir.png"], ["adir.png", "no images in this folder"]),
    # typer turns '' into Path('.'): the working folder, a batch with no image in it
    (["solve", ""], [".: no images in this folder"]),
    (["render", "--out", "{out}/f.png", "--catalog", "gaia:{bad}/badschema.parquet"],
     ["badschema.parquet", "cannot read Parquet", "utf-8"]),
    (["render", "--out", "{out}/f.png", "--catalog", "gaia:{bad}/dup.csv"],
     ["dup.csv", "source_id 1000 appears more than once", "2 repeated rows"]),
    (["render", "--out", "{out}/f.png", "--catalog", "bsc5:{bad}/sentinel.bsc5"],
     ["sentinel.bsc5", "magnitude V = 327.67", "id 2"]),
    (["render", "--out", "{out}/f.png", "--catalog", "gaia:{bad}/g1e300.csv"],
     ["g1e300.csv", "magnitude G = 1e+300"]),
    (["render", "--out", "{out}/f.png", "--catalog", "gaia:{bad}/adir.csv"],
     ["adir.csv", "is a directory"]),
    (["render", "--out", "{out}/f.png", "--catalog", "gaia:{bad}/nosuch.csv"],
     ["catalogue file not found", "nosuch.csv"]),
    # -- B: values ---------------------------------------------------------------------------
    (["render", "--out", "{out}/f.png", "--seed", "-1"], ["--seed", "-1"]),
    (["montecarlo", "--seed", "-1"], ["--seed", "-1"]),
    (["slew", "tolerance", "--seed", "-1"], ["--seed", "-1"]),
    (["slew", "intensity", "--seed", "-1"], ["--seed", "-1"]),
    (["availability", "static", "--seed", "-1"], ["--seed", "-1"]),
    (["availability", "track", "--seed", "-1"], ["--seed", "-1"]),
    (["guide-stars", "simulate", "--seed", "-1"], ["--seed", "-1"]),
    (["limit", "photons", "--seed", "-1"], ["--seed", "-1"]),
    (["report", "--out", "{out}/r", "--seed", "-1"], ["--seed", "-1"]),
    (["slew", "tolerance", "--rates-deg-s", "1,,2"], ["--rates-deg-s", "empty element", "'1,,2'"]),
    (["slew", "tolerance", "--magnitudes", "3,"], ["--magnitudes", "empty element", "'3,'"]),
    (["render", "--out", "{out}/f.png", "--rate-deg-s", "0,,0"], ["--rate-deg-s", "'0,,0'"]),
    (["limit", "star", "--mag-v", "327.67", "--b-v", "0.5"], ["--mag-v", "327.67"]),
    (["limit", "star", "--mag-v", "1e300", "--b-v", "0.5"], ["--mag-v", "1e+300"]),
    (["limit", "star", "--mag-v", "1", "--b-v", "nan"], ["--b-v", "nan"]),
    (["availability", "track", "--inclination-step-deg", "1e-9"],
     ["--inclination-step-deg", "1e-09", "0.001"]),
    (["availability", "track", "--inclination-step-deg", "0"], ["--inclination-step-deg", "0"]),
    (["availability", "static", "--half-fov-deg", "nan"], ["--half-fov-deg", "nan"]),
    (["availability", "static", "--max-mag", "nan"], ["--max-mag", "nan"]),
    (["limit", "photons", "--diameter-m", "nan"], ["--diameter-m", "nan"]),
    (["montecarlo", "--max-mag", "nan"], ["--max-mag", "nan"]),
    (["render", "--out", "{out}/f.png", "--max-mag", "inf"], ["--max-mag", "inf"]),
    (["slew", "tolerance", "--b-v", "nan"], ["--b-v", "nan"]),
    (["guide-stars", "select", "--center-deg", "10,,10", "--lens-fov-deg", "20"],
     ["--center-deg", "'10,,10'"]),
    (["guide-stars", "select", "--center-deg", "10,10", "--lens-fov-deg", "20",
      "--sigma-arcsec", "nan"], ["--sigma-arcsec", "nan"]),
    # -- C: outputs checked before the work ---------------------------------------------------
    (["render", "--out", "{out}/nodir/f.png"], ["--out", "nodir/f.png", "does not exist"]),
    (["render", "--out", "{out}"], ["--out", "it is a directory"]),
    (["render", "--out", "{bad}/file.txt/f.png"], ["--out", "file.txt", "is not a directory"]),
    (["slew", "tolerance", "--plot", "{out}/nodir/p.png"], ["--plot", "nodir/p.png"]),
    (["limit", "curve", "--plot", "{out}/nodir/p.png"], ["--plot", "nodir/p.png"]),
    (["availability", "static", "--maps", "{bad}/file.txt"],
     ["--maps", "file.txt", "not a directory"]),
    (["availability", "static", "--plot", "{out}"], ["--plot", "it is a directory"]),
    (["solve", "{bad}/ok.fits", "--wcs", "{out}/nodir/w.fits"], ["--wcs", "nodir/w.fits"]),
    (["report", "--out", "{bad}/file.txt"], ["--out", "file.txt", "not a directory"]),
    (["catalog", "import", "{bad}/baddec.csv", "{out}/h"],
     ["baddec.csv", "line 3, column dec: 'abc' is not a number"]),
    (["catalog", "import", "{bad}/baddec.csv", "{bad}/file.txt/h"],
     ["output", "file.txt", "is not a directory"]),
    # -- D: the sensor TOML's schema, checked when it is loaded --------------------------------
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/name.toml"],
     ["name.toml", "name must be text", "['a']"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/budget.toml"],
     ["budget.toml", "[budget] source must be text", "5"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/quoted.toml"],
     ["quoted.toml: [quoted] nea_cross_arcsec = -1.0 is out of range"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/k1.toml"],
     ["k1.toml", "optics.distortion_k1 = -10", "fold"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/wide.toml"],
     ["wide.toml", "177.1 deg across the columns", "175 deg"]),
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/lit.toml"],
     ["lit.toml", "detection.lit_pixel_counts = 1e+300"]),
    (["slew", "tolerance", "--sensor", "{bad}/onepx.toml"],
     ["detector.columns = 1", "star does not fit"]),
    # -- E: the work bounded before it starts (memory of the machine) --------------------------
    (["render", "--out", "{out}/f.png", "--sensor", "{bad}/big.toml"],
     ["100000 x 100000", "10,000,000,000 pixels", "67,108,864"]),
    (["datasheet", "--sensor", "{bad}/big.toml"], ["100000 x 100000", "67,108,864"]),
    # -- G: the newer commands -------------------------------------------------------------------
    (["render", "--out", "{out}/f.png", "--sequence", "2", "--interval-s", "1", "--time", "x"],
     ["--time", "'x' is not an ISO 8601 time"]),
    (["datasheet", "--out", "{bad}/file.txt/sub"], ["--out", "file.txt", "is not a directory"]),
    (["calibrate", "--fit", "focal_length,k1,focal_length", "--out", "{out}/c.toml",
      "{bad}/ok.fits"], ["--fit", "focal_length listed twice"]),
    (["track", "--sensor", "st16", "--interval-s", "1e-300", "--json", "{bad}/ok.fits"],
     ["--interval-s", "1e-300", "1e-06"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/day0.tle"],
     ["day0.tle, line 2, columns 21-32", "epoch day 000.5", "[1, 367]"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/day400.tle"],
     ["day400.tle, line 2", "epoch day 400.5"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/day366.tle"],
     ["day366.tle", "epoch day 366.5", "past the end of 2023"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/inc200.tle"],
     ["inc200.tle, line 3, columns 9-16", "inclination (deg) 200.0000", "[0, 180]"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/ok.tle", "--start",
      "1990-01-01T00:00", "--duration-h", "0.1", "--step-s", "60"],
     ["SGP4 fails", "-12418.5 days from the TLE epoch 2024-01-01T12:00:00.000"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--start",
      "9999-01-01T00:00"], ["9999", "outside 1900-2100"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--attitude",
      "quaternions:{bad}/adir.csv"], ["quaternion file", "adir.csv is a directory"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--attitude",
      "quaternions:{bad}/latin1.csv"], ["latin1.csv", "not UTF-8", "0xe9 at line 3"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--attitude",
      "quaternions:{bad}/qnan.csv"], ["qnan.csv, line 4, column 2 (qx): nan"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--attitude",
      "target:10,1e300"], ["--attitude target longitude (deg) = 1e+300"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "kepler:-5,0,0,0,0,0"],
     ["--orbit kepler semi-major axis (km) = -5.0"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "circular:1e12:10"],
     ["--orbit circular altitude (km)", "1000000.0"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--plot",
      "{bad}/file.txt/t.png"], ["--plot", "file.txt/t.png", "is not a directory"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--plot",
      "{bad}/file.txt/sub/t.png"], ["--plot", "file.txt/sub/t.png", "is not a directory"]),
    (["availability", "mission", "--heads", "st16", "--orbit", "sso:500", "--duration-h",
      "0.0001"], ["--duration-h 0.0001 at --step-s 1 gives 1 steps"]),
    # -- F: network addresses ------------------------------------------------------------------
    (["limit", "sky", "--catalog", "hats:http://127.0.0.1:99999/x"],
     ["http://127.0.0.1:99999/x", "port", "1-65535"]),
    (["limit", "sky", "--catalog", "hats:{bad}", "--dask", "tcp://127.0.0.1:99999"],
     ["--dask", "'99999'", "1-65535"]),
    (["catalog", "import", "{bad}/baddec.csv", "{out}/h", "--dask", "tcp://127.0.0.1:99999"],
     ["--dask", "'99999'", "1-65535"]),
    (["limit", "sky", "--catalog", "hats:http://127.0.0.1:{closed}/x"],
     ["http://127.0.0.1:{closed}/x", "connection refused"]),
    (["limit", "sky", "--catalog", "hats:{bad}", "--dask", "tcp://127.0.0.1:{closed}"],
     ["tcp://127.0.0.1:{closed}", "connection refused"]),
    # -- an aperture or exposure beyond a sensor's ranges (1e308 overflowed: a traceback, or
    # RuntimeWarnings and a Fisher matrix of infinities)
    (["limit", "star", "--mag-v", "5", "--b-v", "0", "--exposure-s", "1e308"],
     ["--exposure-s", "1e+308", "100000.0"]),
    (["limit", "curve", "--diameter-m", "1e308"], ["--diameter-m", "1e+308", "10.0"]),
    (["limit", "sky", "--max-mag", "3", "--exposure-s", "1e308"], ["--exposure-s", "1e+308"]),
    (["limit", "photons", "--diameter-m", "11"], ["--diameter-m", "11", "10.0"]),
    (["report", "--out", "{out}/r", "--exposure-s", "1e308"], ["--exposure-s", "1e+308"]),
    # an empty list of configurations ran them all
    (["guide-stars", "simulate", "--configurations", ""], ["--configurations", "''", "no config"]),
    (["guide-stars", "field", "--configurations", ","], ["--configurations", "','"]),
    (["guide-stars", "select", "--sensor", "lin2024", "--center-deg", "84,-1", "--areas", ""],
     ["--areas", "''", "no area"]),
    # found by the sweep (bench/bad_input_sweep.py): NaN kept no star, without a word; 10**23
    # overflowed the field's counts and 1e308 the figure's axis (tracebacks)
    (["guide-stars", "field", "--max-mag", "nan"], ["--max-mag", "nan"]),
    (["availability", "static", "--n-min", "99999999999999999999999"],
     ["--n-min", "99999999999999999999999", "1,000,000"]),
    (["limit", "curve", "--extrapolate-to", "1e308"], ["--extrapolate-to", "1e+308"]),
    (["track", "{bad}/onebit.png", "{bad}/onebit.png", "--sensor", "st16", "--interval-s",
      "1e308"], ["--interval-s", "1e+308", "86400"]),
    (["slew", "intensity", "--magnitudes", "1e308"], ["--magnitudes", "1e+308", "40.0"]),
    (["guide-stars", "field", "--sigmas-arcsec", "1e308"], ["--sigmas-arcsec", "3600"]),
    (["characterize", "{bad}/onebit.png", "--out", "{out}/c.toml", "--exposure-s", "1e308"],
     ["--exposure-s", "1e308", "100000"]),
    # a magnitude limit brighter than the Sun kept no star, without a word
    (["render", "--out", "{out}/f.png", "--max-mag", "-1e308"], ["--max-mag", "-30"]),
    (["guide-stars", "field", "--max-mag", "-1e308"], ["--max-mag", "-30"]),
    (["availability", "static", "--max-mag", "-40"], ["--max-mag", "-40", "-30"]),
    (["limit", "sky", "--max-mag", "-1e308"], ["--max-mag", "-30"]),
    (["availability", "dynamic", "--rates-deg-s", "1e308,0,0"],
     ["--rates-deg-s", "1e+308", "360"]),
    (["catalog", "import", "{bad}/nosuch.csv", "{out}/h", "--pixel-threshold",
      "99999999999999999999999"], ["--pixel-threshold", "99999999999999999999999"]),
    (["guide-stars", "select", "--sensor", "lin2024", "--center-deg", "84,-1", "--areas",
      "1,,2"], ["--areas", "'1,,2'", "empty item"]),
    # a fresh seed of the sweep: 1e308 rolls and spans ran silently or overflowed (a traceback)
    (["availability", "static", "--roll-deg", "1e308"], ["--roll-deg", "1e+308", "360"]),
    (["availability", "track", "--roll-deg", "-1e308"], ["--roll-deg", "-1e+308", "360"]),
    (["guide-stars", "simulate", "--threshold-arcsec", "1e308"],
     ["--threshold-arcsec", "1e+308", "648000"]),
    (["availability", "mission", "--heads", "st16", "--tle", "{bad}/day0.tle", "--duration-h",
      "1e308"], ["--duration-h", "1e+308"]),
    # a name the system refuses (longer than a file name may be): the name and why, one line
    (["render", "--out", "{out}/f.png", "--sensor", "x" * 300],
     ["xxxxxxxxxx", "File name too long"]),
]
# fmt: on


def _fill(text: str, values: dict[str, str]) -> str:
    for key, value in values.items():
        text = text.replace("{" + key + "}", value)
    return text


def _listing(*folders: Path) -> list[str]:
    return sorted(str(p) for d in folders for p in d.rglob("*"))


@pytest.mark.parametrize(("argv", "fragments"), CASES, ids=lambda x: " ".join(x)[:60])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(
    argv, fragments, bad_dir, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)  # a command writing to its working directory would show up
    values = {"bad": str(bad_dir), "out": str(out), "closed": str(_closed_port())}
    before = _listing(bad_dir, tmp_path)
    code = main([_fill(a, values) for a in argv])
    captured = capsys.readouterr()
    assert code == 2, captured
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert "Traceback" not in captured.err and "np.float64" not in captured.err
    assert len(lines[0]) < 400  # one readable line, never a dump of an array
    for fragment in fragments:
        assert _fill(fragment, values) in lines[0]
    assert _listing(bad_dir, tmp_path) == before  # no file left behind, temporary or not


def test_read_only_output_directory(tmp_path, capsys, monkeypatch):
    # the tests may run as root, for whom every directory is writable: the permission is
    # refused the way the kernel would refuse it to a user

    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(
        io_mod.os, "access", lambda p, m: False if Path(p) == locked else real(p, m)
    )
    code = main(["render", "--out", str(locked / "f.png")])
    err = capsys.readouterr().err
    assert code == 2
    assert (
        err.strip()
        == f"error: cannot write --out {locked / 'f.png'}: directory {locked} is not writable"
    )
    assert list(locked.iterdir()) == []


def test_unreadable_files_are_named(bad_dir, tmp_path, capsys, monkeypatch):
    secret = tmp_path / "secret.toml"
    secret.write_text("name = 'x'\n")
    real = os.access
    monkeypatch.setattr(
        io_mod.os, "access", lambda p, m: False if Path(p) == secret else real(p, m)
    )
    code = main(["render", "--out", str(tmp_path / "f.png"), "--sensor", str(secret)])
    err = capsys.readouterr().err
    assert (
        code == 2 and err.strip() == f"error: cannot read sensor file {secret}: permission denied"
    )


def test_valid_fine_inclination_steps_are_accepted():
    # 0.01, 0.03, 0.001 deg were refused (a floating end point past 90 deg); the grid is now
    # built from a count: it starts at -90, ends at 90 and never passes it

    def _inclinations_deg(step):
        return step_grid(-90.0, 90.0, step, "--inclination-step-deg", 1e-3)

    for step, n in ((0.01, 18_001), (0.03, 6_001), (0.001, 180_001), (0.7, 258)):
        grid = _inclinations_deg(step)
        assert grid.size == n and grid[0] == -90.0 and grid.max() <= 90.0
        assert abs(grid[1] - grid[0] - step) < 1e-9
    assert _inclinations_deg(0.01)[-1] == 90.0


def test_colour_clamp_is_said(capsys):
    code = main(["limit", "star", "--mag-v", "1", "--b-v", "100", "--json"])
    captured = capsys.readouterr()
    assert code == 0
    assert "warning: --b-v 100 is outside" in captured.err
    assert "clamped to 2,000 K" in captured.err

    assert json.loads(captured.out)["colour_clamped"] is True


@pytest.mark.parametrize(
    ("argv", "kelvin"),
    [
        # a colour of 1e308 overflowed the lookup's scaling (a RuntimeWarning on the terminal,
        # an error under this suite's warnings-as-errors) before it was clamped
        (["limit", "star", "--mag-v", "5", "--b-v", "-1e308"], "30,000 K"),
        (["limit", "star", "--mag-v", "5", "--b-v", "1e308"], "2,000 K"),
        # slew clamped the same colours without a word
        (["slew", "tolerance", "--trials", "2", "--magnitudes", "3", "--rates-deg-s", "0",
          "--b-v", "1e308"], "2,000 K"),
        (["slew", "intensity", "--trials", "2", "--magnitudes", "3", "--rates-deg-s", "0",
          "--b-v", "-5"], "30,000 K"),
    ],
)  # fmt: skip
def test_an_extreme_colour_is_clamped_in_words(argv, kelvin, capsys):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 0
    assert len(err) == 1 and err[0].startswith("warning: --b-v"), err
    assert f"clamped to {kelvin}" in err[0]


def test_case_count():
    # the note quotes the size of this table; keep it honest
    assert len(CASES) >= 90


@pytest.mark.parametrize(
    "argv",
    [
        ["limit", "sky", "--catalog", "hats:http://127.0.0.1:9/x"],
        ["limit", "sky", "--dask", "tcp://127.0.0.1:9", "--catalog", "hats:http://127.0.0.1:9/x"],
        ["limit", "sky", "--dask", "tcp://127.0.0.1:9", "--catalog", "hats:{bad}"],
    ],
    ids=["hats-url", "dask+url", "dask"],
)
def test_refused_addresses_fail_at_once(argv, bad_dir, capsys):
    # the discard port 9 refuses at once; no 10 s timeout, no lsdb import, no
    # cluster (measured in-process: the interpreter's start-up is not the command's doing)
    t0 = time.perf_counter()
    code = main([a.replace("{bad}", str(bad_dir)) for a in argv])
    elapsed = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert code == 2 and "connection refused by 127.0.0.1:9" in err
    assert elapsed < 2.0


def test_render_sequence_takes_a_time_with_a_utc_offset(tmp_path, capsys):
    # 20:47:26+02:00 is 18:47:26 UTC; frame k of the sequence is taken k x 0.5 s later
    code = main(
        [
            "render", "--out", str(tmp_path / "s.png"), "--sequence", "2", "--interval-s",
            "0.5", "--time", "2019-07-29T20:47:26+02:00", "--max-mag", "3", "--no-noise",
            "--ra-deg", "83.8", "--dec-deg", "-1.2",  # Orion's belt: stars in the field
        ]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    for k, utc in enumerate(["2019-07-29T18:47:26.000", "2019-07-29T18:47:26.500"]):
        truth = json.loads((tmp_path / f"s_{k:03d}.png.json").read_text())
        assert truth["apparent_places"]["time_utc"] == utc
        assert truth["time_s"] == 0.5 * k
