"""The report's guide-star section (Lin et al. 2024): Table 1, Figs. 5-6 and the area layout."""

from __future__ import annotations

import json

import numpy as np
import pytest

import starsense.report.guide_stars as report_gs
from starsense.geometry.areas import polygon_area, polygon_centroid
from starsense.photometry.stars import BlackBodyStars
from starsense.plotting.guide_stars import field_angle_deg
from starsense.references import lin2024
from starsense.report.build import SECTION_BUILDERS
from starsense.report.section import ReportContext
from starsense.sensor import load_sensor

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _stars(n: int = 50) -> BlackBodyStars:
    rng = np.random.default_rng(0)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    ones = np.ones(n)
    return BlackBodyStars(v, 6000 * ones, 1e-16 * ones, rng.uniform(0, 6, n), "B-V")


def _ctx(tmp_path, sensor) -> ReportContext:
    return ReportContext(
        work_dir=tmp_path,
        catalog_name="synthetic",
        n_catalog=50,
        stars={"B-V": _stars()},
        diameter_m=0.1,
        exposure_s=0.01,
        sensor=sensor,
    )


@pytest.fixture(scope="module")
def lin_section(tmp_path_factory):
    """The section for the lin2024 sensor (which defines areas), with few trials."""
    mp = pytest.MonkeyPatch()
    mp.setattr(report_gs, "REPORT_TRIALS", 400)
    try:
        ctx = _ctx(tmp_path_factory.mktemp("gs"), load_sensor("lin2024"))
        yield ctx, report_gs.guide_stars_section(ctx)
    finally:
        mp.undo()


def test_registered_last():
    assert SECTION_BUILDERS[-1] is report_gs.guide_stars_section


def test_section_builds_and_writes_pngs(lin_section):
    ctx, section = lin_section
    assert section.key == "guide_stars"
    assert section.figures == ("guide_stars_fig5_6_ratio.png", "guide_stars_areas.png")
    for name in section.figures:
        path = ctx.work_dir / name
        assert path.read_bytes()[:8] == PNG_SIGNATURE
        assert path.stat().st_size > 5000
        assert f'src="{name}"' in section.html


def test_table_has_paper_values(lin_section):
    section = lin_section[1]
    # the paper's Table 1 beside ours: four areas at 0.3", one area at 0.01", its saturation
    t1 = lin2024.TABLE1_PERCENT
    for paper in (
        t1["four"][0],
        t1["one"][-1],
        t1["four"][-1],
        t1["two_symmetric"][-1],
        t1["two_adjacent"][0],
    ):
        assert f">{paper:.2f}<" in section.html
    assert "400 random placements" in section.html
    assert "Cramér-Rao" in section.html and "3σ" in section.html


def test_data_is_json_and_has_no_per_trial_arrays(lin_section):
    section = lin_section[1]
    text = json.dumps(section.data, allow_nan=False)
    assert len(text) < 20_000  # summaries only, no per-trial arrays
    d = section.data
    assert d["n_trials"] == 400
    assert set(d["probability"]) == {"one", "two_adjacent", "two_symmetric", "three", "four"}
    assert d["paper_percent"]["four"][0] == pytest.approx(lin2024.TABLE1_PERCENT["four"][0])
    for series in d["probability"].values():
        assert all(0.0 <= p <= 1.0 for p in series)
    assert len(d["four_3sigma"]["probability"]) == 7
    assert set(d["by_triangle_ratio"]) == {"0.1", "0.3"}
    assert sum(d["by_triangle_ratio"]["0.1"]["four"]["count"]) == 400
    assert d["layout"]["from_sensor"] is True


def test_layout_sizes_are_the_papers_057_v2(lin_section):
    section = lin_section[1]
    lay = section.data["layout"]
    v_deg = 2 * lay["science_half_deg"]
    # Lin et al. 2024, sec. 2.2: the four segments total (pi/2 - 1) V^2 = 0.5708 V^2; the
    # polygons (256 vertices per arc) fall short by ~1e-4 relative
    assert lay["total_area_deg2"] / v_deg**2 == pytest.approx(np.pi / 2 - 1, rel=1e-3)
    assert [a["name"] for a in lay["areas"]] == ["1", "2", "3", "4"]
    assert "deg²" in section.html and "0.571 V²" in section.html


def test_summary_rows(lin_section):
    section = lin_section[1]
    labels = [label for label, _ in section.summary]
    assert any("σ = 0.1″" in label for label in labels)
    saturation = lin2024.TABLE1_PERCENT["four"][-1]
    assert any(f"paper {saturation:.2f} %" in value for _, value in section.summary)


def test_sensor_without_areas_draws_the_paper_layout(tmp_path, monkeypatch):
    monkeypatch.setattr(report_gs, "REPORT_TRIALS", 100)
    section = report_gs.guide_stars_section(_ctx(tmp_path, load_sensor("st16")))
    assert section.data["layout"]["from_sensor"] is False
    assert "lin2024" in section.data["layout"]["source"]
    assert "defines no attitude-determination areas" in section.html
    assert (tmp_path / "guide_stars_areas.png").is_file()


def test_no_sensor(tmp_path):
    section = report_gs.guide_stars_section(_ctx(tmp_path, None))
    assert "No sensor" in section.html and section.figures == ()


def test_polygon_helpers():
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    assert polygon_area(square) == pytest.approx(2.0)
    assert polygon_centroid(square) == pytest.approx([1.0, 0.5])
    assert field_angle_deg([1.0, 0.0]) == pytest.approx([45.0, 0.0])
