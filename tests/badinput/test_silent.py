"""Inputs that used to give a silently wrong answer with exit 0: refused in one line (exit 2).

A NaN position imported as a star, a body rate of 1e308 deg/s rendered as a frame of no stars,
an observer faster than light, two magnitude systems of which one was ignored, a head named
"st16=", a Solution whose status is a typo.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import starsense
from starsense.analysis.mission.specs import parse_head
from starsense.cli import main
from starsense.errors import InputError
from starsense.render.tracks import MAX_RATE_RAD_S
from starsense.sensor import load_sensor

# fmt: off
CASES = [
    (["render", "--out", "{out}/f.png", "--rate-deg-s", "1e308,0,0"],
     ["--rate-deg-s", "1e+308", "360"]),
    (["render", "--out", "{out}/f.png", "--roll-deg", "1e308"], ["--roll-deg", "1e+308", "360"]),
    (["render", "--out", "{out}/f.png", "--ra-deg", "-1e308"], ["--ra-deg", "-1e+308"]),
    (["solve", "{out}/frame.png", "--observer-velocity-km-s", "400000,0,0"],
     ["--observer-velocity-km-s", "400,000 km/s", "speed of light", "299,792 km/s"]),
    (["limit", "star", "--mag-v", "5", "--b-v", "0.5", "--mag-h", "3", "--h-ks", "0.1"],
     ["--mag-v/--b-v and --mag-h/--h-ks", "give one"]),
    (["limit", "star", "--mag-v", "5", "--b-v", "0.5", "--mag-h", "3"],
     ["--mag-v/--b-v and --mag-h/--h-ks"]),
    (["catalog", "import", "{out}/nan.csv", "{out}/hats"],
     ["nan.csv", "line 3", "column dec", "missing value (empty or NaN)"]),
    (["catalog", "import", "{out}/inf.csv", "{out}/hats"],
     ["inf.csv", "line 2", "column ra", "inf"]),
    (["catalog", "import", "{out}/nan.parquet", "{out}/hats"],
     ["nan.parquet", "row 2", "column ra", "nan"]),
]
# fmt: on


@pytest.fixture
def inputs(tmp_path):
    Image.fromarray(np.full((32, 48), 100, np.uint8)).save(tmp_path / "frame.png")
    (tmp_path / "nan.csv").write_text("ra,dec,phot_g_mean_mag\n10.0,20.0,5.0\n11.0,nan,5.5\n")
    (tmp_path / "inf.csv").write_text("ra,dec,phot_g_mean_mag\ninf,20.0,5.0\n11.0,1.0,5.5\n")
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    table = pa.table({"ra": [1.0, float("nan")], "dec": [2.0, 3.0], "phot_g_mean_mag": [5.0, 6.0]})
    pq.write_table(table, tmp_path / "nan.parquet")
    return tmp_path


@pytest.mark.parametrize(("argv", "fragments"), CASES, ids=lambda x: " ".join(x)[:60])
def test_silent_case_is_refused_in_one_line(argv, fragments, inputs, capsys):
    before = sorted(inputs.iterdir())
    code = main([a.replace("{out}", str(inputs)) for a in argv])
    captured = capsys.readouterr()
    assert code == 2, captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    assert sorted(inputs.iterdir()) == before  # nothing written


def test_api_rate_faster_than_one_turn_a_second_is_refused():
    sensor = load_sensor("st16")
    attitude = starsense.attitude_from_radec_roll(0.0, 0.0, 0.0)
    with pytest.raises(InputError, match=r"rate_rad_s = \[1e\+308, 1e\+308, 0.0\] is 1.414e\+308"):
        starsense.render_frame(sensor, attitude, rate_rad_s=[1e308, 1e308, 0.0])
    with pytest.raises(InputError, match=r"faster than 6\.283 rad/s"):
        starsense.render_frame(sensor, attitude, rate_rad_s=[0.0, 1.01 * MAX_RATE_RAD_S, 0.0])


def test_api_observer_faster_than_light_is_refused():
    with pytest.raises(InputError, match=r"observer_velocity_m_s .* not below the speed of light"):
        starsense.Solver("st16", observer_velocity_m_s=[4e8, 0.0, 0.0])
    with pytest.raises(InputError, match="observer_velocity_m_s must have 3 components"):
        starsense.Solver("st16", observer_velocity_m_s=[1.0, 2.0])


@pytest.mark.parametrize("spec", ["st16=", "st16@0,0,0,1=", "st16=  "])
def test_head_with_empty_name_is_refused(spec):
    with pytest.raises(InputError, match="no name after '='"):
        parse_head(spec)
    assert parse_head("st16=left")[1] == "left"
    assert parse_head("st16")[1] == "st16"


@pytest.mark.parametrize("status", ["bogus", "Solved", "", None, 3])
def test_solution_status_is_checked(status):
    with pytest.raises(InputError, match="status must be one of solved, no_stars"):
        starsense.Solution(status=status)


def test_solution_known_statuses_are_accepted():
    assert starsense.Solution(status="solved").solved
    assert not starsense.Solution(status="no_match").solved
