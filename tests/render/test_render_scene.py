"""Whole frames (render_frame) and single-star stamps."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render import (
    check_on_detector,
    render_frame,
    render_star_stamp,
    streak_stamp_expected,
)
from starsense.render.noise import quantise
from starsense.render.psf import gaussian_stamp
from starsense.units import DEG

RATE = np.array([0.8, -0.6, 0.1]) * DEG  # ~1 deg/s


def centroid(image: np.ndarray, r0: int = 0, c0: int = 0) -> tuple[float, float]:
    rows, cols = np.indices(image.shape)
    total = image.sum()
    return float((image * (cols + c0)).sum() / total), float((image * (rows + r0)).sum() / total)


@pytest.fixture(scope="module")
def frame(st16, attitude, catalog):
    return render_frame(st16, attitude, catalog, rate_rad_s=RATE, rng=7)


def test_frame_shape_dtype_and_truth_columns(frame, st16) -> None:
    assert frame.image.shape == (st16.detector.rows, st16.detector.columns)
    assert frame.image.dtype == np.uint16
    assert frame.image.max() <= 4095
    assert frame.expected_e.dtype == np.float32
    stars = frame.truth.stars
    assert len(stars) > 10
    for name in ("mag", "electrons", "x_start", "y_mid", "x_end", "on_detector", "n_segments"):
        assert getattr(stars, name).shape == (len(stars),)
    assert frame.truth.seed == 7 and frame.truth.sensor == "st16"
    assert frame.truth.band == "V" and frame.truth.model == "reed"


def test_seeded_frames_are_reproducible(frame, st16, attitude, catalog) -> None:
    again = render_frame(st16, attitude, catalog, rate_rad_s=RATE, rng=7)
    assert np.array_equal(again.image, frame.image)
    other = render_frame(st16, attitude, catalog, rate_rad_s=RATE, rng=8, keep_expected=False)
    assert not np.array_equal(other.image, frame.image)
    assert other.expected_e is None
    np.testing.assert_array_equal(other.truth.stars.x_mid, frame.truth.stars.x_mid)


def test_truth_positions_are_the_mid_exposure_projection(frame, st16, attitude, catalog) -> None:
    stars = frame.truth.stars
    rows = catalog.index_of(stars.ids)
    x, y = st16.project(attitude.apply(catalog.vectors[rows]))
    np.testing.assert_allclose(stars.x_mid, x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(stars.y_mid, y, rtol=0, atol=1e-9)
    # start and end straddle the middle: the mid point lies between them, ~half way (the
    # tracks are ~13 px long and almost straight and uniform: within 0.01 px of half way)
    start = np.stack([stars.x_start, stars.y_start], axis=1)
    mid = np.stack([stars.x_mid, stars.y_mid], axis=1)
    end = np.stack([stars.x_end, stars.y_end], axis=1)
    assert np.all(np.einsum("ij,ij->i", mid - start, end - mid) > 0)
    np.testing.assert_allclose(mid, (start + end) / 2, atol=0.01)
    length = np.hypot(*(end - start).T)
    eq1 = st16.streak_length_px(np.hypot(RATE[0], RATE[1]))
    assert np.all(np.abs(length / eq1 - 1) < 0.05)  # roll adds < 1 px, off-axis a few %


def test_stars_near_the_boresight_are_present_with_their_flux(frame, st16, catalog) -> None:
    stars = frame.truth.stars
    assert 1000 in stars.ids.tolist()  # star 0 of the synthetic catalogue is on the boresight
    cx, cy = st16.principal_point_px
    i = stars.ids.tolist().index(1000)
    assert abs(stars.x_mid[i] - cx) < 1e-6 and abs(stars.y_mid[i] - cy) < 1e-6
    inside = stars.on_detector & (stars.x_mid > 20) & (stars.x_mid < st16.detector.columns - 20)
    inside &= (stars.y_mid > 20) & (stars.y_mid < st16.detector.rows - 20)
    assert inside.sum() >= 5
    # flux conservation over the whole frame: a star well inside keeps all but the 5-8 sigma
    # tails (< 1.2e-6) of its electrons; float32 accumulation adds ~1e-7.
    np.testing.assert_allclose(
        stars.electrons_on_detector[inside], stars.electrons[inside], rtol=2e-6
    )
    total = float(frame.expected_e.sum(dtype=np.float64))
    assert total == pytest.approx(stars.electrons_on_detector.sum(), rel=1e-5)
    # the image shows the central star: its brightest expected pixel (p electrons) reads
    # 6.5 p counts within 5 standard deviations of shot and read noise, 6.5 sqrt(p + 3.5^2)
    r, c = round(cy), round(cx)
    near = frame.expected_e[r - 10 : r + 11, c - 10 : c + 11]
    dr, dc = np.unravel_index(np.argmax(near), near.shape)
    p = float(near[dr, dc])
    counts = float(frame.image[r - 10 + dr, c - 10 + dc])
    assert p > 50
    assert abs(counts - 6.5 * p) < 5 * 6.5 * math.sqrt(p + 3.5**2) + 1


def test_noiseless_symmetric_star_centroids_on_its_truth(st16, attitude, make_catalog) -> None:
    # A single star off-centre; static and at a cross-axis rate. The intensity-weighted
    # centroid of the expected image equals the truth: the static Gaussian's centre, or for a
    # straight uniform streak its midpoint (start + end) / 2 (equal to x_mid within the
    # ~1e-4 px by which an off-axis streak is not exactly uniform). The box truncation at
    # >= 5 sigma biases it by < 1e-5 px; ask 0.01 px.
    cat = make_catalog(n=1, seed=3)
    for rate in [(0, 0, 0), (0.5 * DEG, 0.9 * DEG, 0.0)]:
        att = attitude * Rotation.from_rotvec([0.01, -0.02, 0.0])
        f = render_frame(st16, att, cat, rate_rad_s=rate, noise=False)
        s = f.truth.stars
        assert len(s) == 1 and s.on_detector[0]
        r0, c0 = round(s.y_mid[0]) - 40, round(s.x_mid[0]) - 40  # the star and its tails
        window = f.expected_e[r0 : r0 + 81, c0 : c0 + 81].astype(np.float64)
        assert window.sum() == pytest.approx(f.expected_e.sum(dtype=np.float64), rel=1e-12)
        cx, cy = centroid(window, r0, c0)
        assert abs(cx - (s.x_start[0] + s.x_end[0]) / 2) < 0.01
        assert abs(cy - (s.y_start[0] + s.y_end[0]) / 2) < 0.01
        assert abs(cx - s.x_mid[0]) < 0.01 and abs(cy - s.y_mid[0]) < 0.01


def test_zero_rate_frame_is_the_static_gaussian(st16, attitude, make_catalog) -> None:
    cat = make_catalog(n=1, seed=3)
    f = render_frame(st16, attitude, cat, noise=False)
    s = f.truth.stars
    ref, r0, c0 = gaussian_stamp(s.x_mid[0], s.y_mid[0], sigma_px=1.5, electrons=s.electrons[0])
    got = f.expected_e[r0 : r0 + ref.shape[0], c0 : c0 + ref.shape[1]]
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-6)  # float32 storage
    assert np.array_equal(f.image, quantise(f.expected_e, st16))


def test_empty_selection_gives_noise_only(st16, catalog, pointing) -> None:
    ra0, dec0, roll0 = pointing
    away = attitude_from_radec_roll(ra0 + math.pi, -dec0, roll0)  # the opposite sky
    # bias 0 (the preset's is 168 counts): the read noise clipped at zero has a mean of its own
    sensor = st16.with_(detector=dataclasses.replace(st16.detector, bias_counts=0.0))
    f = render_frame(sensor, away, catalog, rng=1)
    assert len(f.truth.stars) == 0
    assert f.expected_e.max() == 0
    assert 0 < f.image.mean() < 20  # read noise only (mean 9.1 counts, see the noise tests)
    d = f.truth_dict()
    assert d["n_stars"] == 0 and d["stars"]["ids"] == []
    json.dumps(d, allow_nan=False)


def test_truth_dict_is_json(frame, pointing) -> None:
    ra0, dec0, roll0 = pointing
    d = frame.truth_dict()
    text = json.dumps(d, allow_nan=False)
    back = json.loads(text)
    assert back["sensor"] == "st16" and back["seed"] == 7
    assert back["attitude"]["ra_deg"] == pytest.approx(math.degrees(ra0))
    assert back["attitude"]["dec_deg"] == pytest.approx(math.degrees(dec0))
    assert back["attitude"]["roll_deg"] == pytest.approx(math.degrees(roll0))
    assert back["rate_rad_s"] == pytest.approx(RATE.tolist())
    assert len(back["stars"]["x_mid"]) == len(frame.truth.stars)
    assert back["stars"]["colour_index"][0] is None  # NaN -> null for the reed model


def test_max_mag_models_and_bands(st16, attitude, catalog) -> None:
    bright = render_frame(st16, attitude, catalog, max_mag=4.0, noise=False)
    assert np.all(bright.truth.stars.mag <= 4.0)
    liebe = render_frame(st16, attitude, catalog, max_mag=4.0, model="liebe", noise=False)
    # Liebe predicts ~2.2 x the Reed electrons at m = 0 (sec. 2.2); eq. 6 divides by 2.5^m
    # where eq. 8 multiplies by 10^(-0.4 m), so the ratio grows as (10^0.4 / 2.5)^m.
    m = bright.truth.stars.mag
    ratio = liebe.truth.stars.electrons / bright.truth.stars.electrons / (10**0.4 / 2.5) ** m
    assert np.allclose(ratio, ratio[0], rtol=1e-12) and 2.0 < ratio[0] < 2.5
    bb = render_frame(st16, attitude, catalog, max_mag=4.0, model="blackbody", noise=False)
    assert bb.truth.colour == "B-V" and bb.truth.band == "V"
    assert np.all(np.isfinite(bb.truth.stars.colour_index))
    with pytest.raises(InputError, match="available bands"):
        render_frame(st16, attitude, catalog, band="G")
    with pytest.raises(InputError, match="sensitivity model"):
        render_frame(st16, attitude, catalog, model="vega")


def test_bad_rate_exposure_and_attitude(st16, attitude, catalog) -> None:
    with pytest.raises(InputError, match="3 components"):
        render_frame(st16, attitude, catalog, rate_rad_s=(0.0, 0.1))
    with pytest.raises(InputError, match="finite"):
        render_frame(st16, attitude, catalog, rate_rad_s=(0.0, np.inf, 0.0))
    with pytest.raises(InputError, match="exposure_s"):
        render_frame(st16, attitude, catalog, exposure_s=-0.1)
    with pytest.raises(InputError, match="attitude"):
        render_frame(st16, np.eye(3), catalog)


def test_exposure_override_scales_electrons_and_streaks(st16, attitude, catalog) -> None:
    a = render_frame(st16, attitude, catalog, rate_rad_s=RATE, max_mag=4.0, noise=False)
    b = render_frame(
        st16, attitude, catalog, rate_rad_s=RATE, max_mag=4.0, noise=False, exposure_s=0.2
    )
    assert b.truth.exposure_s == 0.2
    common = np.intersect1d(a.truth.stars.ids, b.truth.stars.ids)
    ia = np.searchsorted(a.truth.stars.ids, common)
    ib = np.searchsorted(b.truth.stars.ids, common)
    np.testing.assert_allclose(b.truth.stars.electrons[ib], 2 * a.truth.stars.electrons[ia])
    la = np.hypot(
        a.truth.stars.x_end - a.truth.stars.x_start, a.truth.stars.y_end - a.truth.stars.y_start
    )
    lb = np.hypot(
        b.truth.stars.x_end - b.truth.stars.x_start, b.truth.stars.y_end - b.truth.stars.y_start
    )
    np.testing.assert_allclose(lb[ib] / la[ia], 2.0, rtol=1e-3)


# -- single stars -----------------------------------------------------------------------------


def test_streak_stamp_expected_is_linear_and_conserves_flux(st16) -> None:
    unit, r0, c0 = streak_stamp_expected(st16, x0=10.2, y0=20.7, x1=22.9, y1=20.7)
    big, r1, c1 = streak_stamp_expected(st16, x0=10.2, y0=20.7, x1=22.9, y1=20.7, electrons=5000.0)
    assert (r0, c0) == (r1, c1)
    np.testing.assert_allclose(big, 5000.0 * unit, rtol=1e-14)
    assert unit.sum() == pytest.approx(1.0, abs=2e-6)
    cx, cy = centroid(unit, r0, c0)
    assert abs(cx - (10.2 + 22.9) / 2) < 1e-4 and abs(cy - 20.7) < 1e-4


def test_render_star_stamp_rate_and_streak_agree(st16) -> None:
    # At the boresight a cross-axis rate gives a straight streak of eq. 1's length centred on
    # the star (mid-exposure); the same streak given in pixels renders the same image.
    w = np.array([0.0, 1.0, 0.0]) * DEG
    length = 2 * st16.focal_length_px * math.tan(1.0 * DEG * st16.exposure_s / 2)
    by_rate = render_star_stamp(st16, 4000.0, rate_rad_s=w, noise=False, offset_px=(0.3, -0.2))
    by_streak = render_star_stamp(
        st16, 4000.0, streak_px=(-length, 0.0), noise=False, offset_px=(0.3, -0.2)
    )
    assert by_rate.shape == by_streak.shape
    assert np.abs(by_rate.astype(int) - by_streak.astype(int)).max() <= 1  # rounding ties
    noisy = render_star_stamp(st16, 4000.0, rate_rad_s=w, rng=1)
    assert np.array_equal(noisy, render_star_stamp(st16, 4000.0, rate_rad_s=w, rng=1))


def test_render_star_stamp_refuses_tracks_off_the_detector(st16) -> None:
    # 300 deg/s for 0.1 s sweeps 30 deg, more than the 20 deg field: the star leaves.
    with pytest.raises(InputError, match="leaves the detector"):
        render_star_stamp(st16, 1000.0, rate_rad_s=(300 * DEG, 0.0, 0.0))
    # a 10 deg/s rate is fine for 0.1 s but not for a 3 s exposure
    render_star_stamp(st16, 1000.0, rate_rad_s=(10 * DEG, 0.0, 0.0), noise=False)
    with pytest.raises(InputError, match="leaves the detector"):
        render_star_stamp(st16, 1000.0, rate_rad_s=(10 * DEG, 0.0, 0.0), exposure_s=3.0)
    with pytest.raises(InputError, match="leaves the detector"):
        render_star_stamp(st16, 1000.0, streak_px=(3000.0, 0.0))
    with pytest.raises(InputError, match="not both"):
        render_star_stamp(st16, 1000.0, rate_rad_s=(0, 0, 0), streak_px=(1.0, 0.0))
    with pytest.raises(InputError, match="exposure_s"):
        render_star_stamp(st16, 1000.0, rate_rad_s=(0, 0, 0), exposure_s=-1.0)
    with pytest.raises(InputError, match="3 components"):
        render_star_stamp(st16, 1000.0, rate_rad_s=(0, 0, 0, 0))
    with pytest.raises(InputError, match="leaves the detector"):
        check_on_detector(st16, [0.0, 2591.5], [0.0, 0.0])
    check_on_detector(st16, [-0.5, 2591.49], [-0.5, 1943.49])
