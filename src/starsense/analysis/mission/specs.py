"""The text forms of orbits, attitude profiles and head mountings (degrees and km).

The command line (``--orbit``, ``--attitude``, ``--heads``) and the sensor TOML's ``[mission]``
table write them the same way; this is their one parser. Messages name `where` the text came
from (an option, or a TOML key), the value and the allowed range.

* orbit: ``sso:ALT_KM[:LTAN_H]`` (LTAN default 6 h, dawn-dusk),
  ``circular:ALT_KM:INC_DEG[:RAAN_DEG[:ARGLAT_DEG]]``,
  ``kepler:A_KM,E,INC_DEG,RAAN_DEG,ARGP_DEG,MEAN_ANOMALY_DEG``;
* attitude: ``inertial:RA,DEC,ROLL`` | ``nadir`` | ``nadir:yaw`` | ``sun`` |
  ``target:LAT,LON`` | ``quaternions:FILE``;
* head: ``SENSOR[@qx,qy,qz,qw | @SEQ:ANGLES_DEG][=NAME]``.
"""

from __future__ import annotations

import math
from typing import Any

from starsense._validate import check_scalar
from starsense.analysis.mission.heads import mounting_from_euler, mounting_from_quaternion
from starsense.analysis.mission.orbit import EARTH_RADIUS_M, KeplerOrbit, sun_synchronous
from starsense.analysis.mission.profiles import AttitudeProfile
from starsense.errors import InputError
from starsense.units import DEG

__all__ = ["ATTITUDE_FORMS", "ORBIT_FORMS", "parse_attitude", "parse_head", "parse_orbit"]

ORBIT_FORMS = (
    "sso:ALT_KM[:LTAN_H] (sun-synchronous, circular; LTAN default 6 = dawn-dusk), "
    "circular:ALT_KM:INC_DEG[:RAAN_DEG[:ARGLAT_DEG]], or "
    "kepler:A_KM,E,INC_DEG,RAAN_DEG,ARGP_DEG,MEAN_ANOMALY_DEG (elements at the start)"
)
ATTITUDE_FORMS = (
    "inertial:RA,DEC,ROLL (deg) | nadir | nadir:yaw (yaw steering on) | sun | "
    "target:LAT,LON (deg, geodetic) | quaternions:FILE (CSV t_s,qx,qy,qz,qw, ICRS -> body)"
)


#: largest orbit radius, km: the Earth's sphere of influence (~0.9 million km; Vallado 2013,
#: sec. 12.2) rounded up; beyond it the Sun, not the Earth, shapes the orbit
MAX_ORBIT_KM = 1e6


def _angle(value: float, where: str) -> float:
    """Return an angle in degrees within one turn either way ([-360, 360]), or raise."""
    return check_scalar(value, where, -360.0, 360.0)


def numbers(text: str, where: str, *, n_lo: int, n_hi: int) -> list[float]:
    """Return the comma-separated finite numbers of `text`, between `n_lo` and `n_hi` of them."""
    parts = [p for p in text.split(",") if p.strip()] if text else []
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"{where} expects numbers, got {text!r}") from None
    if not n_lo <= len(values) <= n_hi or not all(math.isfinite(v) for v in values):
        want = f"{n_lo}" if n_lo == n_hi else f"{n_lo} to {n_hi}"
        raise InputError(f"{where} expects {want} finite numbers, got {text!r}")
    return values


def parse_orbit(text: str, start: Any, where: str = "orbit") -> KeplerOrbit:
    """Return the orbit written as `text`, with its elements at `start` (UTC)."""
    kind, _, rest = str(text).partition(":")
    if kind == "sso":
        vals = numbers(rest.replace(":", ","), f"{where} sso", n_lo=1, n_hi=2)
        alt = check_scalar(vals[0], f"{where} sso altitude (km)", 100.0, 6000.0)
        ltan = check_scalar(
            vals[1] if len(vals) > 1 else 6.0, f"{where} sso LTAN (h)", 0.0, 24.0, hi_open=True
        )
        return sun_synchronous(alt * 1e3, ltan_h=ltan, epoch=start)
    if kind == "circular":
        vals = [*numbers(rest.replace(":", ","), f"{where} circular", n_lo=2, n_hi=4), 0.0, 0.0]
        alt = check_scalar(vals[0], f"{where} circular altitude (km)", 100.0, MAX_ORBIT_KM)
        inc = check_scalar(vals[1], f"{where} circular inclination (deg)", 0.0, 180.0)
        _angle(vals[2], f"{where} circular RAAN (deg)")
        _angle(vals[3], f"{where} circular argument of latitude (deg)")
        return KeplerOrbit(
            EARTH_RADIUS_M + alt * 1e3,
            0.0,
            inc * DEG,
            vals[2] * DEG,
            0.0,
            vals[3] * DEG,
            start,
            label=f"circular {alt:g} km, i = {inc:g} deg",
        )
    if kind == "kepler":
        a, e, i, raan, argp, m = numbers(rest, f"{where} kepler", n_lo=6, n_hi=6)
        check_scalar(a, f"{where} kepler semi-major axis (km)", 0.0, MAX_ORBIT_KM, lo_open=True)
        check_scalar(e, f"{where} kepler eccentricity", 0.0, 1.0, hi_open=True)
        check_scalar(i, f"{where} kepler inclination (deg)", 0.0, 180.0)
        for value, label in ((raan, "RAAN"), (argp, "argument of perigee"), (m, "mean anomaly")):
            _angle(value, f"{where} kepler {label} (deg)")
        return KeplerOrbit(
            a * 1e3,
            e,
            i * DEG,
            raan * DEG,
            argp * DEG,
            m * DEG,
            start,
            label=f"Keplerian a = {a:g} km, e = {e:g}, i = {i:g} deg",
        )
    raise InputError(f"{where} must be {ORBIT_FORMS}; got {text!r}")


def parse_attitude(text: str, where: str = "attitude") -> AttitudeProfile:
    """Return the attitude profile written as `text` (angles in degrees)."""
    kind, _, rest = str(text).partition(":")
    if kind == "inertial":
        ra, dec, roll = numbers(rest, f"{where} inertial:RA,DEC,ROLL", n_lo=3, n_hi=3)
        check_scalar(dec, f"{where} inertial Dec (deg)", -90.0, 90.0)
        return AttitudeProfile("inertial", ra=ra * DEG, dec=dec * DEG, roll=roll * DEG)
    if kind == "nadir" and rest in ("", "yaw"):
        return AttitudeProfile("nadir", yaw_steering=rest == "yaw")
    if kind == "sun" and not rest:
        return AttitudeProfile("sun")
    if kind == "target":
        lat, lon = numbers(rest, f"{where} target:LAT,LON", n_lo=2, n_hi=2)
        check_scalar(lat, f"{where} target latitude (deg)", -90.0, 90.0)
        _angle(lon, f"{where} target longitude (deg)")
        return AttitudeProfile("target", lat=lat * DEG, lon=lon * DEG)
    if kind == "quaternions" and rest:
        return AttitudeProfile("quaternions", path=rest)
    raise InputError(f"{where} must be {ATTITUDE_FORMS}; got {text!r}")


def parse_head(spec: str, where: str = "heads") -> tuple[str, str, Any]:
    """Return (sensor, name, mounting Rotation or None) of ``SENSOR[@MOUNT][=NAME]``.

    ``MOUNT`` is a quaternion ``qx,qy,qz,qw`` (body -> head, scalar last) or Euler angles
    ``SEQ:A[,B[,C]]`` in degrees (a scipy sequence of 1-3 axes); without it the head looks
    along the body +z axis. The name defaults to the spec itself.
    """
    body, eq, name = spec.partition("=")
    name = name.strip()
    if eq and not name:
        raise InputError(f"{where} {spec}: no name after '='; give SENSOR[@MOUNT]=NAME or drop '='")
    sensor, at, mount = body.partition("@")
    if not sensor:
        raise InputError(f"{where} {spec}: name a sensor before '@'")
    if not at:
        return sensor, name or spec, None
    here = f"{where} {spec}"
    seq, colon, angles = mount.partition(":")
    if colon:
        vals = numbers(angles, here, n_lo=len(seq), n_hi=len(seq))
        return sensor, name or spec, mounting_from_euler(seq, [v * DEG for v in vals], here)
    return (
        sensor,
        name or spec,
        mounting_from_quaternion(numbers(mount, here, n_lo=4, n_hi=4), here),
    )
