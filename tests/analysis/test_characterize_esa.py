"""`characterize` on the ESA frames (a real camera; the shared image folder) and its command line.

A real camera has no true values to compare with; what must hold is that two disjoint sets of
its frames (same camera, same night, each set with frames at both altitudes, 40 and 60 deg, so
that the airmass's extinction and seeing are alike) give the same camera within the stated
uncertainties: 3 combined sigmas (a right sigma is outside that once in 370 comparisons).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from starsense.analysis.characterize import characterize, measured_values
from starsense.cli import main

#: values a camera keeps from one set of frames to another (the sky's level does not)
CAMERA_VALUES = ("focal_length_px", "psf_sigma_px", "zero_point", "gain_counts_per_e")


@pytest.fixture(scope="module")
def esa_frames(shared_dir):
    folder = shared_dir / "data" / "images" / "esa"
    files = sorted(folder.glob("*.tiff"))
    if len(files) != 8:
        pytest.skip(f"the eight ESA frames are not in {folder}")
    return files


@pytest.mark.slow
def test_disjoint_frames_give_the_same_camera(esa_frames):
    a, _ = measured_values(characterize([str(p) for p in esa_frames[0::2]], "esa_blackfly"))
    b, _ = measured_values(characterize([str(p) for p in esa_frames[1::2]], "esa_blackfly"))
    for key in CAMERA_VALUES:
        d = abs(a[key].value - b[key].value) / math.hypot(a[key].uncertainty, b[key].uncertainty)
        assert d < 3.0, (key, a[key], b[key])
    # the photon transfer of four frames tells the gain to better than 2 % (four sky levels,
    # thousands of boxes): the test fails if the gain were not measured or not constrained
    assert a["gain_counts_per_e"].uncertainty < 0.02 * a["gain_counts_per_e"].value


def test_cli_json_gives_value_uncertainty_unit(esa_frames, tmp_path, capsys):
    out = tmp_path / "esa.toml"
    frames = [str(p) for p in esa_frames[:2]]
    plot = tmp_path / "esa.png"
    argv = ["characterize", *frames, "--sensor", "esa_blackfly", "--out", str(out)]
    code = main([*argv, "--plot", str(plot), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    payload = json.loads(captured.out)
    for value in payload["values"].values():
        assert set(value) == {"value", "uncertainty", "unit"}
    assert payload["values"]["psf_sigma_px"]["unit"] == "px"
    assert "throughput" in payload["not_told"]  # no --exposure-s: said so
    assert out.is_file()
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _one_line_exit_2(capsys, argv) -> str:
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("error: ") and "\n" not in err, err
    return err


def test_cli_bad_input_one_line_no_file(tmp_path, capsys):
    out = tmp_path / "camera.toml"
    frame = tmp_path / "flat.npy"  # not an image format: refused by the loader
    np.save(frame, np.zeros((8, 8)))
    cases = [
        (["characterize", str(tmp_path / "missing.tiff"), "--out", str(out)], "not found"),
        (["characterize", str(frame), "--out", str(tmp_path / "c.txt")], ".toml"),
        (["characterize", str(frame), "--out", str(tmp_path / "no" / "c.toml")], "not found"),
        (["characterize", str(frame), "--out", str(out), "--exposure-s", "-1"], "exposure"),
        (["characterize", str(frame), "--out", str(out), "--exposure-s", "1,2"], "2 values"),
        (["characterize", str(frame), "--out", str(out)], "flat.npy"),
    ]
    for argv, words in cases:
        assert words in _one_line_exit_2(capsys, argv)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["flat.npy"]  # nothing left behind
