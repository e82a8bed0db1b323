"""The report's availability section, with a given threshold curve (no slew Monte Carlo)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import starsense.report.availability as report_av
import starsense.report.availability_track as report_track
from starsense.analysis.availability import ThresholdCurve
from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.photometry.stars import BlackBodyStars
from starsense.report import build
from starsense.report.section import ReportContext
from starsense.sensor import load_sensor

PAPER_IMPLIED = ThresholdCurve(
    np.radians([0.0, 1.0, 1.5, 2.0, 3.0]), [5.75, 4.78, 4.40, 3.875, 3.60], label="paper-implied"
)


def synthetic_stars(n=6000, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    # a magnitude distribution with ~log-uniform counts, ~3,800 stars <= 5.75
    mag = 6.3 - rng.exponential(1.1, n)
    ones = np.ones(n)
    return BlackBodyStars(v, 6000 * ones, 1e-16 * ones, mag, "B-V")


@pytest.fixture
def ctx(tmp_path):
    return ReportContext(
        work_dir=tmp_path,
        catalog_name="synthetic",
        n_catalog=6000,
        stars={"B-V": synthetic_stars()},
        diameter_m=0.1,
        exposure_s=0.01,
        sensor=load_sensor("st16"),
    )


@pytest.mark.slow
def test_availability_section_builds(ctx, monkeypatch):
    monkeypatch.setattr(report_av, "_slew_curve", lambda ctx, model: PAPER_IMPLIED)
    monkeypatch.setattr(report_track, "FIDELITY_RATES_DEG_S", ())  # rendered frames: own test
    monkeypatch.setattr(report_track, "TRACK_RATES_DEG_S", (1.0, 2.0))
    monkeypatch.setattr(report_track, "TRACK_NODES_DEG", (0.0, 90.0))
    monkeypatch.setattr(report_av, "DYNAMIC_RATES_DEG_S", np.arange(0.0, 3.01, 0.5))
    section = report_av.availability_section(ctx)
    assert section.key == "availability"
    for name in section.figures:
        assert (ctx.work_dir / name).stat().st_size > 1000
    assert "availability_fig4_map.png" in section.figures
    assert "availability_fig17_track_n3.png" in section.figures
    json.dumps(section.data)  # JSON-serialisable
    assert set(section.data) >= {"static", "dynamic", "track", "track_by_node"}
    assert section.data["static"]["n_stars"] == int((ctx.primary.magnitude <= 5.75).sum())
    assert "93.3 / 80.9" in section.html  # the paper's Table 2 beside ours
    assert "Not run (no rates configured)" in section.html
    assert len(section.summary) == 2


def test_availability_section_fidelity_part(ctx, monkeypatch):
    monkeypatch.setattr(report_track, "FIDELITY_FRAMES", 2)
    monkeypatch.setattr(report_track, "FIDELITY_RATES_DEG_S", (1.0,))
    ctx.catalog = load_catalog("hipparcos")  # the section prefers the catalogue when given
    data: dict = {}
    html = report_track.fidelity_part(
        ctx, ctx.sensor, stars=ctx.primary, curve=PAPER_IMPLIED, data=data
    )
    assert "Full-fidelity check" in html and "Skipped" not in html
    assert data["fidelity"][0]["n_frames"] == 2


def test_no_sensor(ctx):
    ctx.sensor = None
    assert "No sensor" in report_av.availability_section(ctx).html


@pytest.mark.slow
def test_report_from_bsc5_path_runs_the_fidelity_part(bsc5_path, tmp_path, monkeypatch):
    """The loaded catalogue travels in ReportContext, whatever the --catalog spec.

    The report is built from ``bsc5:PATH`` through build_report (the availability section
    only, a few frames at one rate, a given threshold curve): the full-fidelity check renders
    from that catalogue instead of printing "Skipped".
    """

    monkeypatch.setattr(build, "SECTION_BUILDERS", [report_av.availability_section])
    monkeypatch.setattr(report_av, "_slew_curve", lambda ctx, model: PAPER_IMPLIED)
    monkeypatch.setattr(report_track, "FIDELITY_FRAMES", 2)
    monkeypatch.setattr(report_track, "FIDELITY_RATES_DEG_S", (1.0,))
    monkeypatch.setattr(report_track, "TRACK_RATES_DEG_S", (1.0,))
    monkeypatch.setattr(report_track, "TRACK_NODES_DEG", (0.0,))
    monkeypatch.setattr(report_av, "DYNAMIC_RATES_DEG_S", np.arange(0.0, 3.01, 1.0))
    out = tmp_path / "report"
    build.build_report(
        out, catalog_spec=f"bsc5:{bsc5_path}", sensor=load_sensor("st16"), low_photon_trials=2
    )
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "Full-fidelity check" in html
    assert "Skipped" not in html
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    fidelity = data["sections"]["availability"]["fidelity"]
    assert fidelity[0]["n_frames"] == 2
    assert fidelity[0]["rate_deg_s"] == 1.0


@pytest.mark.slow
def test_report_command_from_bsc5_path_runs_every_part(bsc5_path, tmp_path):
    """The same, as a user runs it: `starsense report --catalog bsc5:PATH --out DIR` (~1 min)."""

    out = tmp_path / "report"
    assert main(["report", "--catalog", f"bsc5:{bsc5_path}", "--out", str(out)]) == 0
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "Full-fidelity check" in html
    assert "Skipped" not in html
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert data["sections"]["availability"]["fidelity"]
