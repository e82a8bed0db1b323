"""The per-set peer comparison (bench/peers/frame_sets.py, per_set.py) on sets made here.

Both layouts of reference.json that the shared real frame sets use (a frame's reference wrapped in
``{"reference": ...}`` or given directly), a set without a tolerance or a camera, the scoring
against the tolerance and the time ratios, computed by hand beside the code.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

PEERS = Path(__file__).resolve().parents[1] / "bench" / "peers"


@pytest.fixture
def modules(monkeypatch):
    monkeypatch.syspath_prepend(str(PEERS.parent))
    monkeypatch.syspath_prepend(str(PEERS))
    return importlib.import_module("frame_sets"), importlib.import_module("per_set")


def _write_set(folder: Path, meta: dict) -> Path:
    folder.mkdir()
    for name in meta["frames"]:
        Image.fromarray(np.zeros((48, 64), np.uint8)).save(folder / name)
    (folder / "reference.json").write_text(json.dumps(meta))
    return folder


def _sets(tmp_path: Path) -> Path:
    _write_set(
        tmp_path / "wrapped",
        {
            "camera": {"plate_scale_arcsec_per_px": 36.0, "width_px": 1000},
            "tolerance_arcsec": 60,
            "frames": {"a.png": {"reference": {"ra_deg": 10.0, "dec_deg": 0.0}}, "b.png": {}},
        },
    )
    _write_set(
        tmp_path / "direct",
        {"frames": {"c.png": {"ra_deg": 10.0, "dec_deg": 0.0, "roll_deg": 3.0}}},
    )
    (tmp_path / "not-a-set").mkdir()
    return tmp_path


def test_both_layouts_default_tolerance_and_field(modules, tmp_path):
    frame_sets, per_set = modules
    images = _sets(tmp_path)
    assert frame_sets.discover(images) == ["direct", "wrapped"]
    sets = per_set.load_sets(None, images)
    wrapped, direct = sets["wrapped"], sets["direct"]
    assert wrapped["references"] == [{"ra_deg": 10.0, "dec_deg": 0.0}, None]
    assert wrapped["tolerance_arcsec"] == 60.0 and wrapped["tolerance_stated"]
    assert wrapped["fov_deg"] == pytest.approx(10.0)  # 36 arcsec x 1000 px = 10 deg
    assert direct["references"][0]["ra_deg"] == 10.0
    assert direct["fov_deg"] is None  # no camera: unknown to every solver
    assert direct["tolerance_arcsec"] == frame_sets.DEFAULT_TOLERANCE_ARCSEC
    assert not direct["tolerance_stated"]


def test_scores_and_time_ratios(modules, tmp_path):
    _frame_sets, per_set = modules
    fs = per_set.load_sets(["wrapped"], _sets(tmp_path))["wrapped"]
    # frame a: reference (10, 0). 0.01 deg north along the meridian is 36 arcsec (within 60);
    # 0.02 deg is 72 arcsec (wrong). Frame b has no reference: a solution there is "claimed".
    ours = [
        {"solved": True, "ra_deg": 10.0, "dec_deg": 0.01, "ms": 2.0},
        {"solved": True, "ra_deg": 50.0, "dec_deg": 5.0, "ms": 4.0},
    ]
    theirs = [
        {"solved": True, "ra_deg": 10.0, "dec_deg": 0.02, "ms": 1000.0},
        {"solved": False, "ms": 3000.0},
    ]
    row = per_set.compare_set(fs, ours, theirs)
    s, a = row["starsense"], row["astrometry.net"]
    assert (s["solved"], s["wrong"], s["claimed_without_reference"]) == (1, 0, 1)
    assert (a["solved"], a["wrong"], a["claimed_without_reference"]) == (1, 1, 0)
    assert s["per_frame_arcsec"][0] == pytest.approx(36.0, abs=1e-6)
    assert row["ratio_median_all"] == pytest.approx(2000.0 / 3.0)  # medians 2000 ms / 3 ms
    assert row["n_both_correct"] == 0 and row["ratio_median_both_correct"] is None
    text = per_set.table({"wrapped": row}, "0.93", True, 60)
    assert '| wrapped/ | 2 (1) | 60" | 1/1 (+1 w/o ref.) | 0 | 3 | 1/1 | 1 | 2 | 667 |' in text
    assert "--cpulimit 60 s" in text


def test_astrometry_missing_is_said(modules, tmp_path):
    _frame_sets, per_set = modules
    fs = per_set.load_sets(["direct"], _sets(tmp_path))["direct"]
    row = per_set.compare_set(fs, [{"solved": False, "ms": 5.0}], None)
    text = per_set.table({"direct": row}, "solve-field not on PATH", False, 60)
    assert text.count("not run") == 6  # five cells and the line saying why
    assert "astrometry.net not run: solve-field not on PATH" in text
    assert '15" (default)' in text
