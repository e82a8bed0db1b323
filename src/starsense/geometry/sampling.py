"""Points and attitudes on the sphere: quasi-uniform grids, random attitudes, great-circle tracks.

Frame conventions (ICRS unit vectors, attitudes as ICRS -> camera rotations) are those of
:mod:`starsense.geometry.attitude`.
"""

from __future__ import annotations

import operator
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import as_generator, finite_array
from starsense.errors import InputError

__all__ = [
    "GOLDEN_ANGLE_RAD",
    "fibonacci_sphere",
    "great_circle_track",
    "random_attitudes",
    "track_attitudes",
]

#: Golden angle, pi (3 - sqrt 5) rad (about 137.5 deg): the azimuth step of the golden spiral.
GOLDEN_ANGLE_RAD = np.pi * (3.0 - np.sqrt(5.0))


def _count(n: object, name: str, minimum: int = 1) -> int:
    """Validate a count: an integer (not bool) >= `minimum`."""
    if isinstance(n, bool | np.bool_):
        raise InputError(f"{name} must be an integer >= {minimum}, got {n!r}")
    try:
        value = operator.index(n)
    except TypeError as exc:
        raise InputError(f"{name} must be an integer >= {minimum}, got {n!r}") from exc
    if value < minimum:
        raise InputError(f"{name} = {value} is out of range; must be an integer >= {minimum}")
    return value


def fibonacci_sphere(n: int) -> NDArray[np.float64]:
    """Quasi-uniform points on the unit sphere (golden spiral / spherical Fibonacci lattice).

    Point ``i`` has ``z = 1 - (2 i + 1) / n`` (equal-area bands) and azimuth
    ``i * GOLDEN_ANGLE_RAD``, so every point represents a solid angle of ``4 pi / n``
    (González 2010, "Measurement of areas on a sphere using Fibonacci and latitude-longitude
    lattices", Math. Geosci. 42, 49).

    Parameters
    ----------
    n : int
        Number of points, >= 1.

    Returns
    -------
    ndarray, shape (n, 3)
        Unit vectors (read as ICRS directions).

    Raises
    ------
    InputError
        If `n` is not an integer >= 1.
    """
    n = _count(n, "n")
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    rho = np.sqrt((1.0 - z) * (1.0 + z))
    phi = np.mod(i * GOLDEN_ANGLE_RAD, 2.0 * np.pi)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=-1)


def random_attitudes(n: int, rng: np.random.Generator | int | None = None) -> Rotation:
    """Attitudes drawn uniformly (Haar measure) from SO(3).

    Parameters
    ----------
    n : int
        Number of attitudes, >= 1.
    rng : numpy.random.Generator, int or None
        Random generator, seed, or None for a fresh seed (read by
        :func:`starsense._validate.as_generator`).

    Returns
    -------
    Rotation, batch of n
        Attitudes (ICRS -> camera).

    Raises
    ------
    InputError
        If `n` is not an integer >= 1, or `rng` not None, a seed >= 0 or a Generator.
    """
    n = _count(n, "n")
    gen, _ = as_generator(rng)
    return Rotation.random(n, rng=gen)


def great_circle_track(
    inclination_rad: float, n: int, ascending_node_rad: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Equally spaced points around a great circle inclined to the celestial equator.

    Point ``k`` is at arc length ``t_k = 2 pi k / n`` from the node ``N`` (on the equator at
    RA = `ascending_node_rad`)::

        p(t) = cos t N + sin t W,    d(t) = -sin t N + cos t W,
        N = (cos O, sin O, 0),       W = (-sin O cos i, cos O cos i, sin i),

    with ``O`` the node RA and ``i`` the inclination. The circle's pole (angular momentum of
    the motion) is ``N × W = (sin O sin i, -cos O sin i, cos i)``, at angle ``|i|`` from the
    celestial north pole, so the largest declination on the track is ``|i|`` (reached at
    ``t = pi/2``). For ``i > 0`` the track heads north at the node (an ascending node); for
    ``i < 0`` it heads south; for ``i = 0`` it runs east along the equator.

    Parameters
    ----------
    inclination_rad : float
        Inclination to the celestial equator, rad, in [-pi/2, pi/2].
    n : int
        Number of points, >= 1.
    ascending_node_rad : float, optional
        RA of the node at ``t = 0``, rad (any finite value).

    Returns
    -------
    positions : ndarray, shape (n, 3)
        ICRS unit vectors on the track.
    directions : ndarray, shape (n, 3)
        Unit tangent at each point, in the direction of motion (increasing ``t``); orthogonal
        to the position.

    Raises
    ------
    InputError
        If the inclination is outside [-pi/2, pi/2] or not finite, or `n` < 1.
    """
    inc = float(finite_array(inclination_rad, "inclination_rad"))
    if abs(inc) > 0.5 * np.pi:
        raise InputError(
            f"inclination_rad = {inc} is out of range; must be in [-pi/2, pi/2] "
            f"([-1.5707963267948966, 1.5707963267948966])"
        )
    n = _count(n, "n")
    node = float(finite_array(ascending_node_rad, "ascending_node_rad"))
    node_vec = np.array([np.cos(node), np.sin(node), 0.0])
    w_vec = np.array([-np.sin(node) * np.cos(inc), np.cos(node) * np.cos(inc), np.sin(inc)])
    t = 2.0 * np.pi * np.arange(n) / n
    cos_t, sin_t = np.cos(t)[:, None], np.sin(t)[:, None]
    positions = cos_t * node_vec + sin_t * w_vec
    directions = -sin_t * node_vec + cos_t * w_vec
    return positions, directions


def track_attitudes(
    inclination_rad: float,
    n: int,
    *,
    ascending_node_rad: float = 0.0,
    along: Literal["x", "y"] = "x",
) -> Rotation:
    """Attitudes whose boresights follow :func:`great_circle_track`.

    The camera +z axis is the track position and the chosen camera axis (+x by default, i.e.
    towards increasing column) is the direction of motion, so stars drift across the image
    towards decreasing column (``along="x"``) or decreasing row (``along="y"``). The third
    axis completes a right-handed frame: for ``along="x"``, ``y = z × x``; for ``along="y"``,
    ``x = y × z``.

    Parameters
    ----------
    inclination_rad : float
        Inclination of the track to the celestial equator, rad, in [-pi/2, pi/2].
    n : int
        Number of attitudes, >= 1.
    ascending_node_rad : float, optional
        RA of the node at the first point, rad.
    along : {"x", "y"}, optional
        Camera axis aligned with the direction of motion.

    Returns
    -------
    Rotation, batch of n
        Attitudes (ICRS -> camera).

    Raises
    ------
    InputError
        On a bad inclination, `n` or `along`.
    """
    if along not in ("x", "y"):
        raise InputError(f"along = {along!r} is not allowed; must be 'x' or 'y'")
    positions, directions = great_circle_track(inclination_rad, n, ascending_node_rad)
    if along == "x":
        x_axis = directions
        y_axis = np.cross(positions, directions)
    else:
        y_axis = directions
        x_axis = np.cross(directions, positions)
    return Rotation.from_matrix(np.stack([x_axis, y_axis, positions], axis=-2))
