"""Stellar aberration and apparent places against ERFA and astropy."""

from __future__ import annotations

import erfa
import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import GCRS, ICRS, CartesianRepresentation, SkyCoord, get_sun
from astropy.time import Time

from starsense.catalog import Catalog
from starsense.catalog.apparent import apparent_places
from starsense.errors import InputError
from starsense.geometry.apparent import C_M_S, aberrate, observer_state, parse_time
from starsense.units import ARCSEC, MAS

T = "2019-07-29T20:47:26"


def _angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def test_aberrate_matches_erfa_ab_for_any_direction():
    # erfa.ab is ERFA's own relativistic aberration (Klioner 2003); its light-deflection term
    # w2 = SRS / s is 2e-8 / 1e6 here, so the two formulas must agree to rounding (1e-12 rad).
    rng = np.random.default_rng(3)
    p = rng.normal(size=(500, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    v = np.array([29.8e3, -7.5e3, 3.1e3])  # Earth orbit plus a low-Earth-orbit velocity, m/s
    beta = v / C_M_S
    ours = aberrate(p, v)
    ref = erfa.ab(p, beta, 1e6, np.sqrt(1 - beta @ beta))
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    assert np.max(_angle(ours, ref)) < 1e-12
    # a physical invariant: the shift is v sin(theta) / c to first order, at most 20.5" + 5.3"
    shift = _angle(ours, p)
    assert np.max(shift) == pytest.approx(np.linalg.norm(beta), rel=1e-3)


def test_apparent_direction_matches_astropy_gcrs_to_1_mas():
    # astropy's ICRS -> GCRS applies the Earth's barycentric velocity plus obsgeovel
    # (relativistic aberration, erfa.ab) and the Sun's light deflection, which we do not model.
    # The deflection vanishes opposite the Sun (4.07 mas cot(elongation / 2)); stars within
    # 10 deg of the antisolar point see below 0.4 mas of it, so a 1 mas bound leaves room for it.
    t = Time(T, scale="utc")
    sun = get_sun(t).cartesian.xyz.value
    anti = -sun / np.linalg.norm(sun)
    rng = np.random.default_rng(7)
    dirs = anti + 0.08 * rng.normal(size=(20, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    v_obs = np.array([-3.2e3, 6.1e3, 2.4e3])  # an orbit's velocity, m/s
    icrs = SkyCoord(CartesianRepresentation(dirs.T), frame=ICRS())
    gcrs = icrs.transform_to(GCRS(obstime=t, obsgeovel=CartesianRepresentation(v_obs * u.m / u.s)))
    ref = gcrs.cartesian.xyz.value.T
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    _, vel = observer_state(t, v_obs)
    ours = aberrate(dirs, vel)
    assert np.max(_angle(ours, ref)) < 1.0 * MAS
    assert np.min(_angle(ours, dirs)) > 10 * ARCSEC  # the correction itself is ~20 arcsec


def test_apparent_places_proper_motion_parallax_against_astropy():
    # A nearby high-proper-motion star (Barnard's star, Hipparcos values): astropy's
    # apply_space_motion + GCRS (with distance, so parallax) is the independent computation.
    # Tolerance: 1 mas plus the solar light deflection astropy applies and we do not.
    ra, dec = np.radians(269.45402), np.radians(4.66828)
    pm_ra, pm_dec = -798.58 * MAS, 10328.12 * MAS
    plx = 548.31 * MAS
    cat = Catalog.from_columns(
        name="barnard",
        source="test",
        epoch_yr=1991.25,
        ids=[87937],
        ra_deg=[269.45402],
        dec_deg=[4.66828],
        mags={"V": [9.5]},
        pm_ra_mas_yr=[-798.58],
        pm_dec_mas_yr=[10328.12],
        parallax_mas=[548.31],
    )
    res = apparent_places(cat, [0], T)
    t = Time(T, scale="utc")
    star = SkyCoord(
        ra=ra * u.rad,
        dec=dec * u.rad,
        distance=(1 / plx) * u.AU,
        pm_ra_cosdec=pm_ra * u.rad / u.yr,
        pm_dec=pm_dec * u.rad / u.yr,
        radial_velocity=0 * u.km / u.s,
        obstime=Time(1991.25, format="jyear", scale="tdb"),
    )
    moved = star.apply_space_motion(new_obstime=t)
    g = moved.transform_to(GCRS(obstime=t)).cartesian.xyz.value
    g /= np.linalg.norm(g)
    sun = get_sun(t).cartesian.xyz.value
    elong = _angle(sun / np.linalg.norm(sun), g)
    deflection = 4.07 * MAS / np.tan(elong / 2)  # what astropy adds and we leave out
    err = _angle(res.vectors[0], g)
    assert err < deflection + 1.0 * MAS
    assert res.proper_motion and res.parallax


def test_parse_time_forms_and_errors():
    assert parse_time("2019:07:29 20:47:26").isot == "2019-07-29T20:47:26.000"
    with pytest.raises(InputError, match="time must be an ISO 8601"):
        parse_time("yesterday")
    with pytest.raises(InputError, match="speed of light"):
        aberrate([0, 0, 1], [C_M_S, 0, 0])
