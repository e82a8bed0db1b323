"""Geocentric Sun and Moon positions at the time steps, from astropy's built-in ephemeris.

``astropy.coordinates.get_body`` with the built-in (offline) ephemeris (ERFA ``epv00`` for the
Sun, the ELP-2000/82 series of Meeus for the Moon) gives GCRS positions. It is evaluated at knots
``KNOT_S`` apart (or at the steps, when they are as coarse) and interpolated by a cubic spline
on the Cartesian positions: over 30 min the Moon moves 0.27 deg along a smooth orbit and the
spline's error is below a milliarcsecond, far inside the 0.01 deg the exclusion test needs.
Directions from the spacecraft subtract its position (the Moon's parallax from a 550 km orbit
reaches 1 deg).

The star vectors are ICRS (barycentric, catalogue) and the body directions GCRS (geocentric,
with aberration): the two differ by < 21 arcsec, negligible against exclusion half-angles of
degrees.
"""

from __future__ import annotations

import numpy as np
from astropy import units as u
from astropy.coordinates import get_body, solar_system_ephemeris
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from starsense.analysis.mission.timegrid import TimeGrid, quiet_future

__all__ = ["KNOT_S", "body_positions", "directions_from"]

#: spacing of the ephemeris knots, s
KNOT_S = 1800.0


def body_positions(grid: TimeGrid, body: str) -> NDArray[np.float64]:
    """Return the geocentric GCRS position of `body` ("sun" or "moon") at the steps, m, (N, 3).

    Parameters
    ----------
    grid : TimeGrid
        The steps.
    body : {"sun", "moon"}
        The body.

    Returns
    -------
    ndarray, shape (n_steps, 3)
    """
    end = grid.t_s[-1]
    n_knots = max(4, int(np.ceil(end / KNOT_S)) + 3)
    direct = grid.n_steps <= n_knots  # steps as coarse as the knots: evaluate at the steps
    knots = grid.t_s if direct else (np.arange(n_knots) - 1.0) * KNOT_S  # 1 before, 2 after
    with solar_system_ephemeris.set("builtin"), quiet_future():
        coord = get_body(body, grid.times(knots))
    xyz = coord.cartesian.xyz.to_value(u.m).T
    return xyz if direct else CubicSpline(knots, xyz, axis=0)(grid.t_s)


def directions_from(position_m: NDArray[np.float64], origin_m: NDArray[np.float64]):
    """Return unit vectors from `origin_m` to `position_m` (both (N, 3), m), (N, 3)."""
    d = position_m - origin_m
    return d / np.linalg.norm(d, axis=1, keepdims=True)
