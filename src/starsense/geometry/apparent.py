"""Stellar aberration and the observer's place: from catalogue directions to apparent ones.

A star seen by an observer moving with velocity ``v`` (barycentric, BCRS axes = ICRS) appears
displaced towards the direction of motion by up to ``|v| / c`` (20.5 arcsec for the Earth's
orbital motion). :func:`aberrate` applies the special-relativistic formula (Klioner 2003,
AJ 125, 1580, eq. 14; the form ERFA's ``eraAb`` uses, without its solar light-deflection
term)::

    p' = (p / gamma + (1 + (p . beta) / (1 + 1 / gamma)) beta) / (1 + p . beta)

with ``beta = v / c`` and ``gamma = 1 / sqrt(1 - beta^2)``. :func:`observer_state` gives the
Earth's barycentric position and velocity at a time from astropy's built-in ephemeris (ERFA
``epv00``, accurate to a few cm/s), to which an observer's own velocity relative to the geocentre
(an orbit, or a ground site's rotation) is added. The sum is Galilean: the relativistic
composition of two velocities differs by ``|v1| |v2| / c^2`` (below 3e-9 rad, 0.6 mas, for
Earth orbit).

Light deflection by the Sun (4 mas at 90 deg from it, more close to it) is not modelled.
"""

from __future__ import annotations

import datetime
import re
import warnings

import numpy as np

from starsense._validate import finite_array, vectors3
from starsense.errors import InputError

__all__ = ["AU_M", "C_M_S", "aberrate", "observer_state", "parse_time"]

#: speed of light, m/s (exact, SI)
C_M_S = 299_792_458.0
#: astronomical unit, m (exact, IAU 2012 resolution B2)
AU_M = 149_597_870_700.0


def aberrate(vectors, velocity_m_s) -> np.ndarray:
    """Return apparent directions for an observer moving with ``velocity_m_s`` (module formula).

    Parameters
    ----------
    vectors : array_like, shape (N, 3) or (3,)
        Unit vectors towards the stars as seen by an observer at rest (ICRS axes).
    velocity_m_s : array_like, shape (3,)
        Observer's velocity relative to the barycentre (ICRS axes), m/s; below c.

    Returns
    -------
    ndarray, shape of ``vectors``
        Apparent unit vectors.
    """
    p = vectors3(vectors, "vectors")
    beta = finite_array(velocity_m_s, "velocity_m_s") / C_M_S
    if beta.shape != (3,):
        raise InputError(f"velocity_m_s must have 3 components, got shape {beta.shape}")
    b2 = float(beta @ beta)
    if b2 >= 1.0:
        raise InputError("velocity_m_s must be below the speed of light")
    inv_gamma = np.sqrt(1.0 - b2)
    pdb = p @ beta
    w = 1.0 + pdb / (1.0 + inv_gamma)
    out = (inv_gamma * p + w[..., None] * beta) / (1.0 + pdb)[..., None]
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _without_offset(text: str) -> str:
    """Return an ISO 8601 time with a UTC offset (``+02:00``, ``Z``) as the UTC time it names."""
    if not re.search(r"T.*(Z|[+-]\d\d:?\d\d)$", text):
        return text
    try:
        when = datetime.datetime.fromisoformat(text)
    except ValueError:
        return text  # not ISO 8601: astropy says so
    if when.tzinfo is None:
        return text
    return when.astimezone(datetime.UTC).replace(tzinfo=None).isoformat()


def parse_time(value, name: str = "time"):
    """Return a scalar UTC astropy ``Time`` from a ``Time`` or a text: the one time parser.

    Parameters
    ----------
    value : str or astropy.time.Time
        ``"2019-07-29T20:47:26"`` (ISO 8601; any form astropy reads, such as
        ``"2019-07-29 20:47:26"``), ``"2019:07:29 20:47:26"`` (EXIF) or a Time.
    name : str
        Parameter (or option) name for the message.

    Returns
    -------
    astropy.time.Time
        A scalar time, UTC scale. Times past the leap-second table (the future) are accepted
        without ERFA's "dubious year" warning: unannounced leap seconds move UTC by a second or
        two.
    """
    from astropy.time import Time
    from erfa import ErfaWarning

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*dubious year", category=ErfaWarning)
        if isinstance(value, Time):
            t = value
        else:
            text = str(value).strip()
            if len(text) >= 19 and text[4] == ":" and text[7] == ":":  # EXIF 'YYYY:MM:DD HH:MM:SS'
                text = text[:4] + "-" + text[5:7] + "-" + text[8:10] + "T" + text[11:]
            try:
                t = Time(_without_offset(text), scale="utc")
            except ValueError:
                raise InputError(
                    f"{name} must be an ISO 8601 time such as 2019-07-29T20:47:26 (UTC); "
                    f"{value!r} is not an ISO 8601 time"
                ) from None
        if not t.isscalar:
            raise InputError(f"{name} must be a single time")
        return t.utc


def observer_state(time, observer_velocity_m_s=None) -> tuple[np.ndarray, np.ndarray]:
    """Return the observer's barycentric position (m) and velocity (m/s) at ``time``.

    The Earth's barycentric state comes from astropy's built-in ephemeris
    (``get_body_barycentric_posvel``, ERFA ``epv00``); ``observer_velocity_m_s`` (the observer's
    velocity relative to the geocentre: an orbit, or the rotation of a ground site, up to
    0.46 km/s) is added to the velocity. The observer's offset from the geocentre (below 1e-4
    AU) is neglected in the position, which serves only the annual parallax.

    Parameters
    ----------
    time : str or astropy.time.Time
        The observation time (ISO 8601 UTC string or Time).
    observer_velocity_m_s : array_like, shape (3,), optional
        Velocity relative to the geocentre, ICRS (GCRS) axes, m/s.

    Returns
    -------
    position_m, velocity_m_s : ndarray, shape (3,)
    """
    from astropy import units as u
    from astropy.coordinates import get_body_barycentric_posvel

    t = parse_time(time)
    pos, vel = get_body_barycentric_posvel("earth", t)
    position = pos.get_xyz().to_value(u.m)
    velocity = vel.get_xyz().to_value(u.m / u.s)
    if observer_velocity_m_s is not None:
        extra = finite_array(observer_velocity_m_s, "observer_velocity_m_s")
        if extra.shape != (3,):
            raise InputError(
                f"observer_velocity_m_s must have 3 components, got shape {extra.shape}"
            )
        velocity = velocity + extra
    return np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
