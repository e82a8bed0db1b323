"""Projections: RA/Dec <-> unit vectors and the gnomonic (tangent-plane) projection.

The one copy of each, used by every stage. Frames are those of :mod:`starsense.geometry.attitude`:
ICRS unit vectors on the sky; in the camera frame +z is the boresight and the tangent plane is
``z = 1``, so a camera vector ``(x, y, z)`` projects to ``(x/z, y/z)`` (radians near the centre;
multiply by the focal length for metres on the focal plane).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import finite_array as _finite_array
from starsense._validate import vectors3 as _as_vectors
from starsense.errors import InputError

__all__ = [
    "POLE_COS_DEC",
    "radec_to_vectors",
    "scalar_or_array",
    "tangent_to_vectors",
    "vectors_to_radec",
    "vectors_to_tangent",
    "wrap_two_pi",
    "xy_points",
]

TWO_PI = 2.0 * np.pi
HALF_PI = 0.5 * np.pi

#: Below this value of cos(dec) a direction is treated as being exactly at a pole and RA is set
#: to 0 (a few ulp of a unit vector component).
POLE_COS_DEC = 1e-15


def wrap_two_pi(angle_rad: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to [0, 2 pi).

    ``np.mod`` alone can return exactly 2 pi for tiny negative angles; those become 0.

    Parameters
    ----------
    angle_rad : array_like
        Angles, rad, any shape.

    Returns
    -------
    ndarray
        The angles in [0, 2 pi), rad, same shape.
    """
    wrapped = np.mod(angle_rad, TWO_PI)
    return np.where(wrapped >= TWO_PI, 0.0, wrapped)


def scalar_or_array(arr: NDArray[np.float64]) -> NDArray[np.float64] | np.float64:
    """Return a 0-d array as a NumPy scalar and any other array unchanged.

    Parameters
    ----------
    arr : ndarray
        Any array.

    Returns
    -------
    numpy.float64 or ndarray
        ``arr[()]`` when ``arr`` is 0-d, else ``arr`` itself.
    """
    return arr[()] if arr.ndim == 0 else arr


def radec_to_vectors(ra_rad: ArrayLike, dec_rad: ArrayLike) -> NDArray[np.float64]:
    """Compute unit vectors from right ascension and declination.

    Parameters
    ----------
    ra_rad : float or array_like, shape (N,)
        Right ascension, rad (any finite value; taken modulo 2 pi).
    dec_rad : float or array_like, shape (N,)
        Declination, rad, in [-pi/2, pi/2]. Broadcast against `ra_rad`.

    Returns
    -------
    ndarray, shape (N, 3) or (3,) for scalar input
        ICRS unit vectors ``(cos dec cos ra, cos dec sin ra, sin dec)``.

    Raises
    ------
    InputError
        If a value is not finite or a declination is outside [-pi/2, pi/2].
    """
    ra = _finite_array(ra_rad, "ra_rad")
    dec = _finite_array(dec_rad, "dec_rad")
    # |dec| <= pi/2 from the extremes (finite already checked): no |dec| temporary
    if dec.size and max(-float(dec.min()), float(dec.max())) > HALF_PI:
        bad = dec[np.abs(dec) > HALF_PI].flat[0]
        raise InputError(f"dec_rad = {bad} is out of range; must be in [-pi/2, pi/2]")
    try:
        shape = np.broadcast_shapes(ra.shape, dec.shape)
    except ValueError as exc:
        raise InputError(
            f"ra_rad (shape {ra.shape}) and dec_rad (shape {dec.shape}) do not broadcast"
        ) from exc
    # written into one (..., 3) buffer: catalogues of millions of stars pass through here
    out = np.empty((*shape, 3))
    cos_dec = np.cos(dec)
    out[..., 0] = cos_dec * np.cos(ra)
    out[..., 1] = cos_dec * np.sin(ra)
    out[..., 2] = np.sin(dec)
    return out


def vectors_to_radec(
    vectors: ArrayLike,
) -> tuple[NDArray[np.float64] | np.float64, NDArray[np.float64] | np.float64]:
    """Right ascension and declination of direction vectors.

    Parameters
    ----------
    vectors : array_like, shape (N, 3) or (3,)
        Directions in ICRS; need not be normalised, must be non-zero and finite.

    Returns
    -------
    ra_rad : ndarray, shape (N,), or float
        Right ascension in [0, 2 pi), rad. Zero for vectors along the poles.
    dec_rad : ndarray, shape (N,), or float
        Declination in [-pi/2, pi/2], rad.

    Raises
    ------
    InputError
        If the shape is not (N, 3) or (3,), a value is not finite or a vector is zero.
    """
    v = _as_vectors(vectors, "vectors")
    rho = np.hypot(v[..., 0], v[..., 1])
    if np.any((rho == 0.0) & (v[..., 2] == 0.0)):
        raise InputError("vectors contains a zero vector, which has no direction")
    ra = wrap_two_pi(np.arctan2(v[..., 1], v[..., 0]))
    ra = np.where(rho <= POLE_COS_DEC * np.abs(v[..., 2]), 0.0, ra)
    dec = np.arctan2(v[..., 2], rho)
    return scalar_or_array(ra), scalar_or_array(dec)


def xy_points(xy: ArrayLike, name: str = "xy") -> NDArray[np.float64]:
    """Check and return points of a plane (tangent plane or focal plane) as a float array.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Points (x, y), in the caller's unit.
    name : str
        The argument's name, for the error message.

    Returns
    -------
    ndarray, shape (..., 2)
        The points as float64.

    Raises
    ------
    InputError
        If the last axis is not of length 2 or a value is not finite.
    """
    arr = np.asarray(xy, dtype=np.float64)
    if arr.ndim < 1 or arr.shape[-1] != 2:
        raise InputError(f"{name} must have shape (..., 2), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} has non-finite values")
    return arr


def tangent_to_vectors(xy: ArrayLike) -> NDArray[np.float64]:
    """Camera-frame unit vectors (..., 3) of tangent-plane points (..., 2)."""
    p = xy_points(xy)
    v = np.concatenate([p, np.ones((*p.shape[:-1], 1))], axis=-1)
    # np.linalg.norm(v, axis=-1, keepdims=True) without its wrapper (the same reduction)
    return v / np.sqrt(np.add.reduce(v * v, axis=-1, keepdims=True))


def vectors_to_tangent(vectors: ArrayLike) -> NDArray[np.float64]:
    """Tangent-plane points (..., 2) of camera-frame vectors (..., 3) with v_z > 0."""
    v = np.asarray(vectors, dtype=np.float64)
    if v.shape[-1] != 3:
        raise InputError(f"vectors must have shape (..., 3), got {v.shape}")
    if np.any(v[..., 2] <= 0):
        raise InputError("vectors must lie in front of the camera (v_z > 0)")
    return v[..., :2] / v[..., 2:3]
