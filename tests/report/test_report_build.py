"""The HTML report, built from a synthetic catalogue (no real catalogue needed)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from starsense.analysis.limits import brightest_curve
from starsense.errors import InputError
from starsense.photometry.stars import BlackBodyStars
from starsense.plotting.limits import plot_brightest_curves
from starsense.references.fialho2019 import TABLE2_MAS as TABLE2_PAPER_MAS
from starsense.report import build, build_report, fov_table, limit_section, table1_rows
from starsense.report.limits import TITLE

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def report(tmp_path_factory, fake_catalog):
    """One report built once for the module: (out_dir, html, json, progress messages)."""
    out = tmp_path_factory.mktemp("rep") / "report"
    sensors = out.parent / "sensors.csv"
    sensors.write_text(
        "name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec\n"
        "Example tracker,0.08,0.2,1.0,8.0\n",
        encoding="utf-8",
    )
    messages: list[str] = []
    index = build_report(
        out,
        catalog=fake_catalog,
        sensors_table=sensors,
        progress=messages.append,
        low_photon_trials=10,
    )
    assert index == out / "index.html"
    html = index.read_text(encoding="utf-8")
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    return out, html, doc, messages


def test_index_has_section_and_summary(report):
    out, html, _doc, messages = report
    assert (out / "index.html").is_file()
    assert "The physical limit (Fialho &amp; Mortari 2019)" in html
    assert TITLE.replace("&", "&amp;") in html
    assert "synthetic: 1,500 stars; 1,497 used, 3 skipped" in html
    assert "This sensor&#x27;s limit" in html or "This sensor's limit" in html
    assert messages and messages[-1].startswith("report written to")


def test_table2_rows_present(report):
    _out, html, doc, _ = report
    for fov, paper in TABLE2_PAPER_MAS.items():
        assert f"<tr><td>{fov:g}°</td>" in html
        assert f">{paper[0]:g}<" in html  # the paper's target-1 value beside ours
    rows = doc["sections"]["limit"]["fov_table"]["rows"]
    assert [r["fov_deg"] for r in rows] == list(TABLE2_PAPER_MAS)


def test_every_figure_exists_and_is_png(report):
    out, html, doc, _ = report
    srcs = re.findall(r'<img src="([^"]+)"', html)
    assert len(srcs) == 3
    assert sorted(srcs) == sorted(doc["sections"]["limit"]["figures"])
    for src in srcs:
        path = out / src
        assert path.is_file()
        assert path.read_bytes()[:8] == PNG_SIGNATURE
        assert "<figcaption>" in html and "Counterpart: paper" in html


def test_report_json_numbers(report):
    _out, _html, doc, _ = report
    assert doc["generator"] == "starsense.report"
    sec = doc["sections"]["limit"]
    assert set(sec["g_rad_m2_s05"]) == {"B-V", "V-I"}
    for g in sec["g_rad_m2_s05"].values():
        assert 0 < g < 1e-10
    assert sec["curves"]["B-V"]["n_stars_used"] == 1497
    assert len(sec["low_photon"]) == 4
    assert len(sec["table1"]) == 10
    # the user's sensor: its theta is G / (D^2 t^1/2) (eq. 23)
    s = sec["sensor"]
    assert s["theta_rms_rad"] * s["figure_of_merit_m2_s05"] == pytest.approx(
        sec["g_rad_m2_s05"]["B-V"], rel=1e-9
    )


def test_sensors_table_in_report(report):
    _out, html, doc, _ = report
    assert "Example tracker" in html
    (s,) = doc["sections"]["limit"]["sensors"]
    assert s["theta_rms_arcsec"] == pytest.approx(math.sqrt(2 * 1.0**2 + 8.0**2))


def test_table1_rows_match_paper_within_tolerance():
    # Table 1 of the paper, reproduced by the photometry layer: 3 % on sigma for UBV, 5 % H-Ks.
    for r in table1_rows():
        tol = 0.03 if r.colour == "B-V" else 0.05
        assert r.sigma_rad == pytest.approx(r.paper[2], rel=tol), r.name


def _stars_away_from_equator() -> BlackBodyStars:
    """Stars only at |Dec| >= 60 deg: the equatorial targets see none in narrow FOVs."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(600, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    v = v[np.abs(v[:, 2]) >= np.sin(np.radians(60))]
    n = len(v)
    return BlackBodyStars(
        vectors=v,
        temperature_k=np.full(n, 6000.0),
        dilution=np.full(n, 1e-18),
        magnitude=rng.uniform(0, 8, n),
        colour="B-V",
    )


def test_fov_table_singular_cells_do_not_crash():
    rows = fov_table(_stars_away_from_equator())
    by_fov = {r.fov_deg: r for r in rows}
    assert by_fov[360.0].merged.result is not None
    for fov in (4.0, 10.0, 25.0):
        for cell in (*by_fov[fov].heads, by_fov[fov].merged):
            assert cell.result is None
            assert cell.html() == "singular (0 stars)"


def test_report_from_stars_shows_singular(tmp_path):
    index = build_report(tmp_path / "r", stars=_stars_away_from_equator(), low_photon_trials=3)
    html = index.read_text(encoding="utf-8")
    assert "singular (0 stars)" in html
    assert "custom star set" in html


def test_failure_mid_build_leaves_no_report(tmp_path, monkeypatch, fake_catalog):
    def boom(ctx):
        raise RuntimeError("section exploded")

    # the limit section writes its figures first, then the next section fails
    monkeypatch.setattr(build, "SECTION_BUILDERS", [limit_section, boom])
    out = tmp_path / "report"
    with pytest.raises(RuntimeError, match="section exploded"):
        build_report(out, catalog=fake_catalog, low_photon_trials=2)
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []  # no temporary directory left behind


def test_failure_keeps_earlier_report(tmp_path, monkeypatch):
    stars = _stars_away_from_equator()
    out = tmp_path / "report"
    build_report(out, stars=stars, low_photon_trials=2)
    before = (out / "index.html").read_text(encoding="utf-8")

    def boom(ctx):
        raise RuntimeError("section exploded")

    monkeypatch.setattr(build, "SECTION_BUILDERS", [boom])
    with pytest.raises(RuntimeError):
        build_report(out, stars=stars, low_photon_trials=2)
    assert (out / "index.html").read_text(encoding="utf-8") == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]


def test_rebuild_replaces_earlier_report(tmp_path):
    stars = _stars_away_from_equator()
    out = tmp_path / "report"
    build_report(out, stars=stars, low_photon_trials=2)
    build_report(out, stars=stars, low_photon_trials=2, diameter_m=0.05)
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert doc["sensor"]["diameter_m"] == 0.05
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]


def test_refuses_to_replace_foreign_directory(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "precious.txt").write_text("keep me", encoding="utf-8")
    with pytest.raises(InputError, match="not empty and holds no earlier starsense report"):
        build_report(out, stars=_stars_away_from_equator(), low_photon_trials=2)
    assert (out / "precious.txt").read_text(encoding="utf-8") == "keep me"


def test_bad_aperture_rejected(tmp_path):
    with pytest.raises(InputError, match="diameter_m must be a finite number > 0"):
        build_report(tmp_path / "r", stars=_stars_away_from_equator(), diameter_m=0.0)
    assert not (tmp_path / "r").exists()


def test_catalog_without_v_i_gets_one_curve(tmp_path, catalog_factory):
    cat = catalog_factory(n=300, seed=5)
    del cat.colours["V-I"]
    index = build_report(tmp_path / "r", catalog=cat, low_photon_trials=2)
    doc = json.loads((index.parent / "report.json").read_text(encoding="utf-8"))
    assert list(doc["sections"]["limit"]["g_rad_m2_s05"]) == ["B-V"]


def test_plot_brightest_curves_writes_png(tmp_path):
    curve = brightest_curve(_stars_away_from_equator(), diameter_m=0.1, exposure_s=0.01)
    path = plot_brightest_curves([curve], tmp_path / "fig7.png", diameter_m=0.1, exposure_s=0.01)
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert [p.name for p in tmp_path.iterdir()] == ["fig7.png"]


def test_datasheet_first_papers_last(report):
    # the datasheet opens the report; the papers' reproductions close it as the
    # validation appendix
    _out, html, doc, _ = report
    assert next(iter(doc["sections"])) == "datasheet"
    assert html.index('id="datasheet"') < html.index('id="validation"') < html.index('id="limit"')
