"""Every command's --json is valid JSON (RFC 8259: no NaN, no Infinity; missing numbers null).

Each command runs in-process on the smallest input that exercises its output; ``montecarlo
--max-mag -5`` renders no star at all, so its error statistics are missing (they were printed
as bare ``NaN``).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from starsense._io import json_text
from starsense.cli import main


def _strict(text: str):
    def refuse(token):
        raise ValueError(f"not JSON: {token}")

    return json.loads(text, parse_constant=refuse)


def _nulls(x) -> int:
    if isinstance(x, dict):
        return sum(_nulls(v) for v in x.values())
    if isinstance(x, list):
        return sum(_nulls(v) for v in x)
    return int(x is None)


COMMANDS = [
    ["limit", "star", "--mag-v", "1", "--b-v", "0.5"],
    ["limit", "sky", "--max-mag", "4"],
    ["limit", "curve"],
    ["limit", "photons", "--trials", "3"],
    ["slew", "tolerance", "--magnitudes", "3", "--rates-deg-s", "1", "--trials", "2"],
    ["slew", "intensity", "--magnitudes", "3", "--rates-deg-s", "1", "--trials", "2"],
    ["availability", "static", "--n-orientations", "200"],
    ["availability", "dynamic", "--n-orientations", "200", "--rates-deg-s", "1", "--trials", "2"],
    ["availability", "track", "--n-orientations", "200", "--inclination-step-deg", "90",
     "--track-samples", "10", "--trials", "2"],
    pytest.param(["availability", "fidelity", "--trials", "2", "--frames", "2"],
                 marks=pytest.mark.slow),
    ["guide-stars", "simulate", "--trials", "20"],
    ["guide-stars", "select", "--center-deg", "10,10", "--lens-fov-deg", "20"],
    ["guide-stars", "field", "--trials", "5"],
    ["montecarlo", "--trials", "1", "--max-mag", "-5"],
    pytest.param(["datasheet", "--trials", "2", "--n-orientations", "200"],
                 marks=pytest.mark.slow),
]  # fmt: skip


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: " ".join(a[:2]))
def test_json_is_valid(argv, capsys):
    code = main([*argv, "--json"])
    out = capsys.readouterr().out
    assert code == 0
    payload = _strict(out)
    assert isinstance(payload, dict) and payload
    if argv[0] == "montecarlo":  # no star rendered: the error statistics are null, not NaN
        assert _nulls(payload) > 0


def test_solve_json_is_valid(tmp_path, capsys):
    frame = tmp_path / "f.png"
    assert main(["render", "--out", str(frame), "--max-mag", "5"]) == 0
    capsys.readouterr()
    code = main(["solve", str(frame), "--sensor", "st16", "--json"])
    payload = _strict(capsys.readouterr().out)
    assert code == 0 and payload["status"] == "solved"


def test_encoder_maps_non_finite_to_null():
    doc = {"a": math.nan, "b": np.float32(np.inf), "c": np.array([1.0, -np.inf]), "d": (1, 2)}
    assert _strict(json_text(doc)) == {"a": None, "b": None, "c": [1.0, None], "d": [1, 2]}
