"""Where the sensor points: the field, the sky grid of boresights and the great-circle tracks.

Frame conventions are those of :mod:`starsense.geometry.attitude`. Angles are radians.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import (
    as_generator,
    check_count,
    check_int,
    check_scalar,
    finite_array,
    finite_float,
)
from starsense.analysis.availability.checks import Fov
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.geometry.fov import CircularFov
from starsense.geometry.projection import vectors_to_radec
from starsense.geometry.sampling import fibonacci_sphere, track_attitudes
from starsense.units import RAD_TO_DEG

__all__ = [
    "MAX_ORIENTATIONS",
    "ORIENTATION_COST",
    "describe_fov",
    "field_of_view",
    "sky_attitudes",
    "track_family_attitudes",
]

#: most orientations (sky boresights, or samples over all tracks) of one availability run: the
#: analysis holds ~1.3 KB per orientation (attitude, stars in its field, per-n_min magnitudes;
#: measured by peak RSS of ``availability static`` at 10,000 and 400,000 orientations, and
#: ~1.0 KB per track sample), so the cap keeps a run near 1.3 GB, within the 2 GB a run may take
MAX_ORIENTATIONS = 1_000_000
ORIENTATION_COST = "~1.3 KB of memory per orientation"


def field_of_view(sensor: Any, kind: str = "circular", half_fov: float | None = None) -> Fov:
    """Return the field used by the availability analysis.

    Parameters
    ----------
    sensor : starsense.sensor.Sensor
        The star tracker.
    kind : {"circular", "rectangular"}
        ``circular``: a cone with the detector's minor half-axis (or `half_fov`), the paper's
        "7.5 deg half-axis field". ``rectangular``: the detector's real field
        (:meth:`Sensor.fov`), where roll matters.
    half_fov : float, optional
        Half-angle of the circular field, rad (0 < a <= pi/2).

    Returns
    -------
    CircularFov or RectangularFov

    Raises
    ------
    InputError
        Unknown `kind`, or `half_fov` with a rectangular field or out of range.
    """
    if kind == "rectangular":
        if half_fov is not None:
            raise InputError(
                "half_fov sets the circular field only; the rectangular field is the "
                "detector's (give half_fov=None or kind='circular')"
            )
        return sensor.fov()
    if kind != "circular":
        raise InputError(f"kind must be 'circular' or 'rectangular', got {kind!r}")
    if half_fov is None:
        return CircularFov(min(sensor.half_fov_rad))
    return CircularFov(check_scalar(half_fov, "half_fov", 0.0, math.pi / 2, lo_open=True))


def describe_fov(fov: Fov) -> str:
    """Return a short text: ``circular, half-angle 7.50 deg`` or ``rectangular 20.2 x 15.2 deg``."""
    if isinstance(fov, CircularFov):
        return f"circular, half-angle {fov.half_angle_rad * RAD_TO_DEG:.2f} deg"
    return (
        f"rectangular {2 * fov.half_width_rad * RAD_TO_DEG:.2f} x "
        f"{2 * fov.half_height_rad * RAD_TO_DEG:.2f} deg"
    )


def sky_attitudes(
    n: int, roll_rad: float | None = None, rng: int | np.random.Generator | None = 0
) -> tuple[NDArray[np.float64], Rotation]:
    """Return quasi-uniform boresights (spherical Fibonacci lattice) and attitudes with a roll.

    Parameters
    ----------
    n : int
        Number of orientations (>= 1).
    roll_rad : float or None
        Roll of every attitude, rad (convention of :mod:`starsense.geometry.attitude`); None
        draws each roll uniformly in [0, 2 pi) from `rng`. Irrelevant for a circular field.
    rng : None, int or numpy.random.Generator
        Source of the random rolls (an int: its seed).

    Returns
    -------
    boresights : ndarray, shape (n, 3)
        ICRS unit vectors.
    attitudes : Rotation, batch of n
        ICRS -> camera.
    """
    n = check_count(n, "n_orientations", MAX_ORIENTATIONS, ORIENTATION_COST)
    boresights = fibonacci_sphere(n)
    ra, dec = vectors_to_radec(boresights)
    if roll_rad is None:
        rolls = as_generator(rng)[0].uniform(0.0, 2.0 * np.pi, n)
    else:
        rolls = np.full(n, finite_float(roll_rad, "roll_rad"))
    return boresights, attitude_from_radec_roll(np.atleast_1d(ra), np.atleast_1d(dec), rolls)


def track_family_attitudes(
    inclinations: ArrayLike, n_samples: int, node_rad: float = 0.0
) -> Rotation:
    """Return attitudes along great-circle tracks, one block of `n_samples` per inclination.

    Each track (:func:`starsense.geometry.sampling.track_attitudes`) starts at the node (on the
    equator at RA = `node_rad`), has the given inclination to the celestial equator, and the
    camera +x axis points along the motion, so the streaks run along the detector rows as in
    the slew simulation.

    Parameters
    ----------
    inclinations : array_like, shape (I,)
        Track inclinations to the celestial equator, rad, in [-pi/2, pi/2].
    n_samples : int
        Orientations per track (>= 1).
    node_rad : float
        Right ascension of the tracks' common ascending node, rad.

    Returns
    -------
    Rotation, batch of ``I * n_samples``
        Track-major order: samples of the first inclination first.
    """
    incl = np.atleast_1d(finite_array(inclinations, "inclinations"))
    if incl.ndim != 1 or incl.size == 0:
        raise InputError(f"inclinations must be a non-empty list of numbers, got {incl}")
    if np.any(np.abs(incl) > math.pi / 2):
        raise InputError(f"inclinations must lie in [-pi/2, pi/2] rad, got {incl.tolist()}")
    n = check_int(n_samples, "n_samples", 1)
    if n * incl.size > MAX_ORIENTATIONS:
        raise InputError(
            f"n_samples = {n:,} on {incl.size:,} tracks is {n * incl.size:,} orientations, above "
            f"the cap of {MAX_ORIENTATIONS:,} ({ORIENTATION_COST}); ask for fewer samples or tracks"
        )
    node = finite_float(node_rad, "node_rad")
    mats = [track_attitudes(i, n, ascending_node_rad=node).as_matrix() for i in incl.tolist()]
    return Rotation.from_matrix(np.concatenate(mats, axis=0))
