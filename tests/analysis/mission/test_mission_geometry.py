"""Mission geometry against astropy and hand computations: Sun, Moon, Earth limb, orbits, TLEs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.analysis.availability import ThresholdCurve
from starsense.analysis.mission import (
    EARTH_RADIUS_M,
    AttitudeProfile,
    Head,
    KeplerOrbit,
    TimeGrid,
    TleOrbit,
    mission_geometry,
    mounting_from_quaternion,
    sun_synchronous,
)
from starsense.analysis.mission.analysis import _angle
from starsense.analysis.mission.orbit import GM_EARTH_M3_S2
from starsense.analysis.mission.tle import teme_to_gcrs_matrix
from starsense.geometry.fov import CircularFov
from starsense.units import DEG

#: Vallado et al. 2006 (AIAA 2006-6753) verification set, satellite 00005 (epoch 2000-06-27)
TLE5 = (
    "1 00005U 58002B   00179.78495062  .00000023  00000-0  28098-4 0  4753\n"
    "2 00005  34.2682 348.7242 1859667 331.7664  19.3264 10.82419157413667\n"
)
CURVE = ThresholdCurve.constant(5.5)
FOV = CircularFov(7.5 * DEG)
PLUS_Y = mounting_from_quaternion([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])  # body +Y


def _separation_deg(a, b):
    from astropy import units as u
    from astropy.coordinates import angular_separation

    sa, sb = a.spherical, b.spherical
    return angular_separation(sa.lon, sa.lat, sb.lon, sb.lat).to_value(u.deg)


def test_sun_and_moon_separation_match_astropy_over_a_day():
    # Over a day at 10 min steps (between the ephemeris' 30 min spline knots), the Sun and Moon
    # seen from the spacecraft, against a head's boresight: astropy's get_body, transformed to
    # a GCRS frame centred on the spacecraft (its own parallax handling), and the separation
    # formula of SkyCoord.separation (astropy's angular_separation, Vincenty), in that frame.
    # Tolerance 0.01 deg (36 arcsec); measured 2 arcsec (Sun) and 5 arcsec (Moon): aberration
    # by the spacecraft's 7.6 km/s and light time.
    from astropy import units as u
    from astropy.coordinates import GCRS, CartesianRepresentation, SkyCoord, get_body

    grid = TimeGrid.span("2025-06-01T00:00:00", 86400.0, 600.0)
    geo = mission_geometry(
        grid, sun_synchronous(550e3, ltan_h=10.5, epoch=grid.start), AttitudeProfile("nadir")
    )
    head = Head("+Y", FOV, CURVE, PLUS_Y)
    b = geo.head_matrices(head)[:, 2, :]
    times = grid.times()
    frame = GCRS(
        obstime=times,
        obsgeoloc=CartesianRepresentation(geo.r.T * u.m),
        obsgeovel=CartesianRepresentation(geo.v.T * u.m / u.s),
    )
    bore = SkyCoord(CartesianRepresentation(b.T), frame=frame)
    for body, ours in (("sun", geo.sun), ("moon", geo.moon)):
        ref = get_body(body, times).transform_to(frame)
        expected = _separation_deg(bore, ref)
        got = _angle(b, ours) / DEG
        assert np.max(np.abs(got - expected)) < 0.01, body
    # the Moon's parallax from 550 km is up to ~1 deg: it must matter, or the test is vacuous
    geocentric = get_body("moon", times).transform_to(GCRS(obstime=times))
    bore0 = SkyCoord(CartesianRepresentation(b.T), frame=GCRS(obstime=times))
    assert np.max(np.abs(_separation_deg(bore0, geocentric) - _angle(b, geo.moon) / DEG)) > 0.3


def test_earth_limb_angle_hand_computation_circular_orbit():
    # Circular equatorial orbit (no J2), radius a = R + 550 km. A boresight at the celestial
    # pole is always 90 deg from nadir: limb angle 90 deg - asin(R/a). A boresight at RA 0 in
    # the orbit plane is pi - u from nadir at argument of latitude u = n t (0 <= u <= pi).
    a = EARTH_RADIUS_M + 550e3
    grid = TimeGrid.span("2025-01-01T00:00:00", 2400.0, 60.0)
    orbit = KeplerOrbit(a, 0.0, 0.0, 0.0, 0.0, 0.0, grid.start, j2=False)
    rho = math.asin(EARTH_RADIUS_M / a)
    pole = mission_geometry(grid, orbit, AttitudeProfile("inertial", dec=math.pi / 2))
    limb = pole.earth_limb_angle(pole.body[:, 2, :], 0.0)
    assert np.allclose(limb, math.pi / 2 - rho, atol=1e-9)
    plane = mission_geometry(grid, orbit, AttitudeProfile("inertial"))
    n = math.sqrt(GM_EARTH_M3_S2 / a**3)
    u_lat = n * grid.t_s
    assert u_lat[-1] < math.pi
    limb = plane.earth_limb_angle(plane.body[:, 2, :], 100e3)
    expected = math.pi - u_lat - math.asin((EARTH_RADIUS_M + 100e3) / a)
    assert np.allclose(limb, expected, atol=1e-9)


def test_sso_node_follows_the_mean_sun_and_circular_radius_constant():
    # Sun-synchronous: the orbit normal turns about the pole by 360 deg per tropical year,
    # 0.98565 deg/day (the definition; J2 secular rate, Vallado eq. 9-41). Tolerance 1e-6 deg.
    grid = TimeGrid.span("2025-03-20T00:00:00", 86400.0 + 1.0, 1.0)
    orbit = sun_synchronous(550e3, ltan_h=6.0, epoch=grid.start)
    r, v = orbit.state(grid)
    h0, h1 = np.cross(r[0], v[0]), np.cross(r[-1], v[-1])
    node0, node1 = math.atan2(h0[0], -h0[1]), math.atan2(h1[0], -h1[1])
    drift = math.degrees(node1 - node0) * 86400.0 / grid.t_s[-1]
    assert drift == pytest.approx(360.0 / 365.2421897, abs=1e-6)
    assert np.allclose(np.linalg.norm(r, axis=1), EARTH_RADIUS_M + 550e3, rtol=1e-12)
    # Wertz & Larson, SMAD 3rd ed., Fig. 6-8: 97.6 deg at 550 km (read to 0.1 deg)
    assert math.degrees(orbit.inclination) == pytest.approx(97.6, abs=0.1)


def test_elliptical_orbit_vis_viva():
    # Two-body energy: v^2/2 - mu/r = -mu/(2a) at every step (no J2), to 1e-9 relative.
    grid = TimeGrid.span("2025-01-01T00:00:00", 20000.0, 17.0)
    a = 12000e3
    orbit = KeplerOrbit(a, 0.4, 1.0, 0.3, 2.0, 0.5, grid.start, j2=False)
    r, v = orbit.state(grid)
    energy = 0.5 * np.sum(v * v, axis=1) - GM_EARTH_M3_S2 / np.linalg.norm(r, axis=1)
    assert np.allclose(energy, -GM_EARTH_M3_S2 / (2 * a), rtol=1e-9)


def test_teme_to_gcrs_matches_astropy():
    # Our ERFA rotation (NPB^T R3(-EqE)) against astropy's TEME -> GCRS at the TLE's epoch
    # (inside the bundled IERS-B table: no download). 1 m on a 7000 km vector = 0.03 arcsec.
    from astropy import units as u
    from astropy.coordinates import GCRS, TEME, CartesianRepresentation
    from astropy.utils import iers

    orbit = TleOrbit(*TLE5.splitlines())
    grid = TimeGrid.span(orbit.epoch, 120.0, 60.0)
    r, _ = orbit.state(grid)
    _, r_teme, _ = orbit.satrec.sgp4_array(*grid.jd("utc"))
    with iers.conf.set_temp("auto_download", False), iers.conf.set_temp("auto_max_age", None):
        teme = TEME(CartesianRepresentation(r_teme.T * u.km), obstime=grid.times())
        ref = teme.transform_to(GCRS(obstime=grid.times())).cartesian.xyz.to_value(u.m).T
    assert np.max(np.linalg.norm(r - ref, axis=1)) < 1.0
    m = teme_to_gcrs_matrix(grid.start)
    assert np.allclose(m @ m.T, np.eye(3), atol=1e-14)


def test_two_heads_opposite_never_both_sun_blinded_and_sun_profile():
    # Invariant: boresights 180 deg apart are never both within < 90 deg of the Sun.
    grid = TimeGrid.span("2025-06-01T00:00:00", 6 * 3600.0, 30.0)
    orbit = sun_synchronous(550e3, ltan_h=10.5, epoch=grid.start)
    geo = mission_geometry(grid, orbit, AttitudeProfile("nadir", yaw_steering=True))
    minus_y = mounting_from_quaternion([-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])
    seps = [
        _angle(geo.head_matrices(Head(n, FOV, CURVE, m))[:, 2, :], geo.sun)
        for n, m in (("+Y", PLUS_Y), ("-Y", minus_y))
    ]
    assert np.allclose(seps[0] + seps[1], math.pi, atol=1e-9)
    assert not np.any((seps[0] < 89.99 * DEG) & (seps[1] < 89.99 * DEG))
    # sun-pointing: body +z on the Sun to rounding (arccos of a dot product: 1.5e-8 rad)
    sun = mission_geometry(grid, orbit, AttitudeProfile("sun"))
    assert np.max(_angle(sun.body[:, 2, :], sun.sun)) < 1e-7


def test_ground_point_in_gcrs_matches_astropy_and_target_profile():
    # GCRS <- ITRS from ERFA (UT1 taken as UTC, no polar motion) against astropy's
    # EarthLocation.get_gcrs (IERS-B, 2020: no download). UT1 - UTC was -0.18 s in June 2020:
    # 0.18 s x 465 m/s x cos(45 deg) = 60 m; tolerance 150 m (0.0013 deg seen from the centre).
    import erfa
    from astropy import units as u
    from astropy.coordinates import EarthLocation
    from astropy.utils import iers

    grid = TimeGrid.span("2020-06-01T00:00:00", 86400.0, 3600.0)
    lat, lon = 45.0, 7.0
    ours = np.einsum(
        "nij,j->ni", grid.gcrs_from_itrs(), np.asarray(erfa.gd2gc(1, lon * DEG, lat * DEG, 0.0))
    )
    with iers.conf.set_temp("auto_download", False), iers.conf.set_temp("auto_max_age", None):
        site = EarthLocation.from_geodetic(lon * u.deg, lat * u.deg, 0.0 * u.m)
        ref = site.get_gcrs(grid.times()).cartesian.xyz.to_value(u.m).T
    assert np.max(np.linalg.norm(ours - ref, axis=1)) < 150.0
    # the target profile's +z passes through that ground point
    orbit = sun_synchronous(550e3, ltan_h=10.5, epoch=grid.start)
    geo = mission_geometry(grid, orbit, AttitudeProfile("target", lat=lat * DEG, lon=lon * DEG))
    to_site = ours - geo.r
    to_site /= np.linalg.norm(to_site, axis=1, keepdims=True)
    assert np.max(_angle(geo.body[:, 2, :], to_site)) < 1e-7


def test_yaw_steering_aligns_ground_velocity_with_body_x():
    # With yaw steering the velocity relative to the rotating ground, v - w_E x r, has no body
    # +y component (to rounding). Without it, at the equator crossings the ground's eastward
    # w_E a is almost across the near-polar track: the ratio peaks at w_E a sin(i) / v
    # (0.066, the ~3.8 deg yaw-steering amplitude of a sun-synchronous orbit); 3 % tolerance
    # (the relative velocity's own change of length).
    grid = TimeGrid.span("2025-06-01T00:00:00", 6000.0, 20.0)
    orbit = sun_synchronous(550e3, ltan_h=10.5, epoch=grid.start)
    w_e = 7.292115e-5 * grid.earth_axis()
    a = orbit.semi_major_axis_m
    peak = 7.292115e-5 * a * math.sin(orbit.inclination) / math.sqrt(GM_EARTH_M3_S2 / a)
    for yaw, lo, hi in ((True, 0.0, 1e-9), (False, 0.97 * peak, 1.03 * peak)):
        geo = mission_geometry(grid, orbit, AttitudeProfile("nadir", yaw_steering=yaw))
        ground = geo.v - np.cross(w_e, geo.r)
        y = np.einsum("nj,nj->n", geo.body[:, 1, :], ground) / np.linalg.norm(ground, axis=1)
        assert lo <= np.max(np.abs(y)) < hi, (yaw, np.max(np.abs(y)))
