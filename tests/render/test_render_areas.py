"""Rendering and detection per attitude-determination area (Lin et al. 2024)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.detect.areas import detect_in_areas
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render.areas import (
    area_pixel_index,
    focal_plane_sensor,
    render_areas,
)
from starsense.sensor import load_sensor


@pytest.fixture(scope="module")
def lin():
    return load_sensor("lin2024")


def test_focal_plane_sensor_covers_the_lens_circle(lin):
    fp = focal_plane_sensor(lin)
    radius_px = lin.attitude_areas.lens_radius * lin.focal_length_px
    assert fp.detector.columns == fp.detector.rows >= 2 * radius_px
    assert fp.focal_length_px == lin.focal_length_px
    # 2048 px square inside a circle of 2048 sqrt 2 = 2896 px (paper Table 2)
    assert 2896 <= fp.detector.columns <= 2896 + 12


def test_pixel_areas_match_the_segment_area(lin):
    fp = focal_plane_sensor(lin)
    pa = area_pixel_index(fp)
    # each segment holds (pi/8 - 1/4) V^2 with V = 2048 px: 292,500 pixels; the pixel-centre
    # count differs by the boundary's pixels (~ perimeter ~ 3,000) at most
    expected = (math.pi / 8 - 0.25) * 2048**2
    counts = np.bincount(pa.ravel(), minlength=5)[1:]
    assert np.all(np.abs(counts - expected) < 3000)


def test_render_and_detect_per_area(lin):
    hip = load_catalog("hipparcos")
    att = attitude_from_radec_roll(math.radians(240.0), math.radians(-80.0), 0.0)
    af = render_areas(lin, att, hip, rng=7)
    outside = af.pixel_area == 0
    # no detector outside the areas: the bias level, no noise
    assert np.all(af.frame.image[outside] == round(af.sensor.detector.bias_counts))
    det, area = detect_in_areas(af)
    truth_area = af.star_area[af.star_area > 0]
    # the four Hipparcos stars in the segments (V 7.7-9.5, 1 s, 15 cm) are all detected, in
    # their own areas, and nothing is detected elsewhere
    assert sorted(truth_area.tolist()) == [2, 2, 4, 4]
    assert sorted(area.tolist()) == sorted(truth_area.tolist())
    st = af.frame.truth.stars
    inside = af.star_area > 0
    for x, y in zip(st.x_mid[inside], st.y_mid[inside], strict=True):
        assert np.min(np.hypot(det.x - x, det.y - y)) < 0.5  # pixels


def test_sensor_without_areas():
    with pytest.raises(InputError, match="no \\[attitude_areas\\]"):
        focal_plane_sensor(load_sensor("st16"))


def test_cli_render_areas(tmp_path, capsys):
    out = tmp_path / "areas.png"
    args = ["render", "--sensor", "lin2024", "--ra-deg", "240", "--dec-deg", "-80", "--areas"]
    assert main([*args, "--out", str(out)]) == 0
    assert "in the areas 1: 0, 2: 2, 3: 0, 4: 2" in capsys.readouterr().out
    assert out.is_file() and (tmp_path / "areas.png.json").is_file()
    assert main(["render", "--sensor", "st16", "--areas", "--out", str(tmp_path / "x.png")]) == 2
    assert "no [attitude_areas]" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()
