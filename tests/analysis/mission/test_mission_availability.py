"""Mission availability: invariants, the static availability it must reduce to, the kernels."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.analysis.availability import (
    FieldStars,
    ThresholdCurve,
    catalog_stars,
    sky_attitudes,
)
from starsense.analysis.mission import (
    AttitudeProfile,
    Head,
    TimeGrid,
    mission_availability,
    mission_geometry,
    outages,
    sun_synchronous,
    tracking_state,
)
from starsense.analysis.mission.field import detected_counts
from starsense.catalog import load_catalog
from starsense.geometry.attitude import radec_roll_from_attitude
from starsense.geometry.fov import CircularFov, RectangularFov
from starsense.sensor.exclusion import Exclusion
from starsense.units import DEG

CURVE = ThresholdCurve(np.array([0.0, 1.0 * DEG, 2.0 * DEG]), np.array([5.5, 4.85, 4.2]))
FOV = CircularFov(7.5 * DEG)


@pytest.fixture(scope="module")
def stars():
    return catalog_stars(load_catalog("hipparcos"), 5.75)


def test_tracking_state_by_hand():
    # acquire needs >= 3 (lis), keep needs >= 2 (track); a drop below 2 loses the attitude
    track = np.array([0, 1, 1, 1, 1, 0, 1, 1, 1, 1], bool)
    lis = np.array([0, 0, 1, 0, 0, 0, 0, 0, 1, 0], bool)
    want = np.array([0, 0, 1, 1, 1, 0, 0, 0, 1, 1], bool)
    assert np.array_equal(tracking_state(track, lis), want)
    n, longest, spans = outages(want, 2.0)
    assert (n, longest) == (2, 6.0)
    assert spans.tolist() == [[0, 2], [5, 8]]


def test_outages_count_runs():
    a = np.array([1, 0, 0, 1, 0, 1, 1, 0], bool)
    n, longest, spans = outages(a, 10.0)
    assert n == 3 and longest == 20.0
    assert spans.tolist() == [[1, 3], [4, 5], [7, 8]]
    assert outages(np.ones(5, bool), 1.0)[:2] == (0, 0.0)


@pytest.mark.parametrize("fov", [FOV, RectangularFov(10.0 * DEG, 7.6 * DEG)])
def test_block_kernel_equals_spatial_field_stars(stars, fov):
    # Along a nadir-pointing day segment, the block kernel's counts equal the spatial
    # analysis' FieldStars (one k-d tree query per pointing) at every step: exact, no tolerance.
    v, m = stars
    grid = TimeGrid.span("2025-03-20T00:00:00", 3000.0, 1.5)
    geo = mission_geometry(
        grid, sun_synchronous(550e3, ltan_h=6.0, epoch=grid.start), AttitudeProfile("nadir")
    )
    mats = geo.head_matrices(Head("z", fov, CURVE))
    thresholds = np.full(grid.n_steps, 5.0)
    thresholds[::7] = 4.0
    got = detected_counts(fov, mats, vectors=v, magnitudes=m, threshold_mag=thresholds)
    field = FieldStars.build(fov, Rotation.from_matrix(mats), v, m)
    want = np.where(thresholds == 5.0, field.counts(5.0), field.counts(4.0))
    assert np.array_equal(got, want)
    assert got.max() > got.min()  # the field moves across stars: not a constant


def test_inertial_without_bright_bodies_equals_static_availability(stars):
    # Inertial attitude, no bright body: every step sees the static field of its boresight,
    # with m_t = m_t(0). Per boresight the outcome equals the spatial analysis' (FieldStars
    # counts >= N_min), and the fraction over the boresights equals its availability.
    v, m = stars
    _, attitudes = sky_attitudes(24, roll_rad=0.3, rng=0)
    ra, dec, roll = radec_roll_from_attitude(attitudes)
    grid = TimeGrid.span("2025-03-20T00:00:00", 600.0, 60.0)
    orbit = sun_synchronous(550e3, ltan_h=6.0, epoch=grid.start)
    fov = RectangularFov(10.0 * DEG, 7.6 * DEG)
    field = FieldStars.build(fov, attitudes, v, m)
    m_t = float(CURVE([0.0])[0])
    static_counts = field.counts(m_t)
    outcome = []
    for k in range(len(ra)):
        prof = AttitudeProfile("inertial", ra=ra[k], dec=dec[k], roll=roll[k])
        res = mission_availability(
            mission_geometry(grid, orbit, prof), [Head("h", fov, CURVE)], vectors=v, magnitudes=m
        )
        h = res.heads[0]
        assert np.all(h.stars == static_counts[k])
        assert np.all(h.rate_rad_s < 1e-12)
        outcome.append(bool(h.available.all()))
        assert h.available.all() == h.available.any()
    assert np.mean(outcome) == pytest.approx(field.availability(m_t, 3))
    assert static_counts.max() > static_counts.min()  # distinct fields, not one repeated


def test_ecliptic_pole_head_never_sun_blinded():
    # The Sun stays within 0.003 deg of the ecliptic (parallax from LEO: 9 arcsec), so a head at
    # the ecliptic pole is 90 deg from it all year: never inside a 45 deg exclusion.
    grid = TimeGrid.span("2025-01-01T00:00:00", 365.25 * 86400.0, 43200.0)
    pole = AttitudeProfile("inertial", ra=270.0 * DEG, dec=(90.0 - 23.4392911) * DEG)
    geo = mission_geometry(grid, sun_synchronous(550e3, ltan_h=6.0, epoch=grid.start), pole)
    head = Head("pole", FOV, CURVE, exclusion=Exclusion(sun_rad=45.0 * DEG))
    res = mission_availability(geo, [head], vectors=np.eye(3), magnitudes=np.zeros(3))
    h = res.heads[0]
    assert not h.sun_blinded.any()
    assert np.allclose(h.sun_sep, math.pi / 2, atol=0.01 * DEG)


def test_nadir_head_always_earth_blinded_and_zenith_never(stars):
    v, m = stars
    grid = TimeGrid.span("2025-03-20T00:00:00", 6000.0, 5.0)
    geo = mission_geometry(
        grid, sun_synchronous(550e3, ltan_h=6.0, epoch=grid.start), AttitudeProfile("nadir")
    )
    exc = Exclusion(sun_rad=45 * DEG, moon_rad=10 * DEG, earth_limb_rad=0.0, atmosphere_m=0.0)
    zenith = Rotation.from_euler("x", 180.0, degrees=True)
    res = mission_availability(
        geo,
        [Head("nadir", FOV, CURVE, exclusion=exc), Head("zenith", FOV, CURVE, zenith, exc)],
        vectors=v,
        magnitudes=m,
    )
    nadir, up = res.heads
    assert nadir.earth_blinded.all() and not nadir.available.any()
    assert np.all(nadir.stars == 0)
    assert not up.earth_blinded.any()
    # orbital rate 360 deg / 5739 s = 0.0627 deg/s, cross-boresight for both heads (1 %)
    assert np.allclose(up.rate_rad_s, 2 * math.pi / 5739.0, rtol=0.01)
    d = res.to_dict()
    assert d["heads"][0]["earth_blinded_fraction"] == 1.0
    assert d["combined"]["available_fraction"] == d["heads"][1]["available_fraction"]


def test_future_dates_do_not_warn(stars):
    # 2030 is past astropy's leap-second table: ERFA's "dubious year" is silenced (a leap
    # second or two of UTC - TT does not matter here); any other warning fails
    v, m = stars
    grid = TimeGrid.span("2030-01-01T00:00:00", 1200.0, 10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        geo = mission_geometry(
            grid,
            sun_synchronous(700e3, ltan_h=22.0, epoch=grid.start),
            AttitudeProfile("target", lat=45 * DEG, lon=7 * DEG),
        )
    res = mission_availability(geo, [Head("h", FOV, CURVE)], vectors=v, magnitudes=m)
    assert res.steps == 120
