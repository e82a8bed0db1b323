"""Attitudes: rotations between the sky (ICRS) and the camera, and (RA, Dec, roll).

Frame conventions
-----------------
These are the conventions of the whole package; every other module refers here.

Sky
    Directions on the sky are ICRS unit vectors, shape ``(N, 3)`` (batch axis first):
    ``(cos dec cos ra, cos dec sin ra, sin dec)``. Angles are in radians inside the package;
    degrees appear only at the edges (CLI, TOML, reports).

Camera
    +z along the boresight (out of the lens, towards the sky), +x towards increasing column,
    +y towards increasing row. Rows increase *downward* in the displayed image (row 0 at the
    top), so "up" in the image is -y and "right" is +x. The frame is right-handed
    (x × y = z: right × down = into the scene).

Attitude
    The attitude is the :class:`scipy.spatial.transform.Rotation` ``A`` that takes ICRS vectors
    into the camera frame, ``v_cam = A.apply(v_icrs)``. Its matrix has the camera axes,
    expressed in ICRS, as rows; ``A.inv().apply([0, 0, 1])`` is the boresight on the sky.
    A batch of ``M`` attitudes is one ``Rotation`` of length ``M``.

(RA, Dec, roll)
    ``(ra, dec)`` is the direction of the boresight. ``roll`` follows the reference solutions
    in ``shared/data/images/esa/reference.json``: the rotation of celestial north relative to
    the image's "up" direction (towards row 0); zero when north and up coincide; positive
    means north is counter-clockwise from up, as seen in the displayed image (row 0 at the
    top, columns increasing to the right). In camera coordinates the local north and east
    directions at the boresight are therefore::

        north_cam = (-sin roll, -cos roll, 0)
        east_cam  = (-cos roll, +sin roll, 0)

    At roll 0 north is up (-y) and **east is to the left (-x)**, as on any image of the sky
    taken from inside the celestial sphere; going from north to east is counter-clockwise in
    the displayed image. At roll +90 deg north points to the left (-x) and east down (+y).
    (A frame that put east on the right with north up would be mirrored, i.e. left-handed.)

    Equivalently, the camera-to-ICRS rotation is the intrinsic z-y-z Euler sequence
    ``A.inv() = Rz(ra) Ry(pi/2 - dec) Rz(roll - pi/2)``.

    When the boresight is at a celestial pole (``cos dec`` below about ``1e-15``) RA is
    undefined; :func:`radec_roll_from_attitude` then returns ``ra = 0`` and measures roll
    against the north/east directions that the formulas above give for ``ra = 0``, so the
    rotation round-trips exactly (to rounding) through (RA, Dec, roll) everywhere, including
    at and near the poles, although the angles themselves do not.

Attitude errors
    :func:`small_rotation_angles` expresses the error of an estimate as the rotation vector of
    ``r_est * r_true.inv()`` in the camera frame: components x and y are the cross-boresight
    (pointing) errors, z is the roll error about the boresight.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import check_rotation
from starsense._validate import finite_array as _finite_array
from starsense._validate import vectors3 as _as_vectors
from starsense.errors import InputError
from starsense.geometry.projection import (
    POLE_COS_DEC,
    TWO_PI,
    radec_to_vectors,
    scalar_or_array,
    vectors_to_radec,
    wrap_two_pi,
)

__all__ = [
    "angular_separation",
    "attitude_from_radec_roll",
    "boresight",
    "east_north",
    "radec_roll_from_attitude",
    "radec_roll_from_matrix",
    "radec_roll_of_matrix",
    "radec_to_vectors",
    "small_rotation_angles",
    "vectors_to_radec",
]


def east_north(
    ra_rad: ArrayLike, dec_rad: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local east and north unit vectors (ICRS) at sky positions.

    East is the direction of increasing RA, north of increasing Dec; with the outward
    direction ``u`` they form a right-handed triad ``east × north = u``. At a pole the formulas
    are used as they stand (they stay orthonormal and depend on the RA passed in).

    Parameters
    ----------
    ra_rad, dec_rad : float or array_like, shape (N,)
        Position, rad.

    Returns
    -------
    east, north : ndarray, shape (N, 3) or (3,)
        ``east = (-sin ra, cos ra, 0)``, ``north = (-sin dec cos ra, -sin dec sin ra, cos dec)``.
    """
    ra = _finite_array(ra_rad, "ra_rad")
    dec = _finite_array(dec_rad, "dec_rad")
    ra, dec = np.broadcast_arrays(ra, dec)
    sin_ra, cos_ra = np.sin(ra), np.cos(ra)
    sin_dec, cos_dec = np.sin(dec), np.cos(dec)
    east = np.stack([-sin_ra, cos_ra, np.zeros_like(ra)], axis=-1)
    north = np.stack([-sin_dec * cos_ra, -sin_dec * sin_ra, cos_dec], axis=-1)
    return east, north


def attitude_from_radec_roll(
    ra_rad: ArrayLike, dec_rad: ArrayLike, roll_rad: ArrayLike
) -> Rotation:
    """Attitude (ICRS -> camera rotation) from boresight (RA, Dec) and roll.

    See the module docstring for the roll convention (that of the ESA reference solutions:
    north counter-clockwise from image up by `roll_rad`; east is left of north at roll 0).
    The camera axes, in ICRS, are::

        x = -sin(roll) north - cos(roll) east
        y = -cos(roll) north + sin(roll) east
        z = boresight

    Parameters
    ----------
    ra_rad : float or array_like, shape (M,)
        Boresight right ascension, rad.
    dec_rad : float or array_like, shape (M,)
        Boresight declination, rad, in [-pi/2, pi/2].
    roll_rad : float or array_like, shape (M,)
        Roll, rad (any finite value). The three arguments are broadcast together.

    Returns
    -------
    Rotation
        A single rotation for scalar inputs, otherwise a batch of ``M``; ``v_cam = A.apply(v)``.

    Raises
    ------
    InputError
        If a value is not finite, a declination is outside [-pi/2, pi/2], or the shapes do not
        broadcast to a scalar or a 1-D batch.

    Examples
    --------
    >>> import numpy as np
    >>> from starsense.geometry.attitude import attitude_from_radec_roll, radec_roll_from_attitude
    >>> rotation = attitude_from_radec_roll(np.radians(83.8), np.radians(-5.4), 0.0)
    >>> np.degrees(radec_roll_from_attitude(rotation)[:2]).round(6).tolist()
    [83.8, -5.4]
    """
    ra = _finite_array(ra_rad, "ra_rad")
    dec = _finite_array(dec_rad, "dec_rad")
    roll = _finite_array(roll_rad, "roll_rad")
    try:
        ra, dec, roll = np.broadcast_arrays(ra, dec, roll)
    except ValueError as exc:
        raise InputError(
            f"ra_rad {ra.shape}, dec_rad {dec.shape} and roll_rad {roll.shape} do not broadcast"
        ) from exc
    if ra.ndim > 1:
        raise InputError(f"angles must be scalars or 1-D arrays, got shape {ra.shape}")
    z = radec_to_vectors(ra, dec)
    east, north = east_north(ra, dec)
    sin_roll = np.sin(roll)[..., None]
    cos_roll = np.cos(roll)[..., None]
    x = -sin_roll * north - cos_roll * east
    y = -cos_roll * north + sin_roll * east
    matrix = np.stack([x, y, z], axis=-2)  # rows are the camera axes in ICRS
    return Rotation.from_matrix(matrix)


def boresight(rot: Rotation) -> NDArray[np.float64]:
    """ICRS direction of the camera +z axis.

    Parameters
    ----------
    rot : Rotation, single or batch of M
        Attitude(s), ICRS -> camera.

    Returns
    -------
    ndarray, shape (M, 3) or (3,)
        Boresight unit vectors (the third row of each attitude matrix).
    """
    check_rotation(rot, "rot")
    return rot.as_matrix()[..., 2, :]


def radec_roll_from_attitude(
    rot: Rotation,
) -> tuple[
    NDArray[np.float64] | np.float64,
    NDArray[np.float64] | np.float64,
    NDArray[np.float64] | np.float64,
]:
    """Boresight (RA, Dec) and roll of attitudes; the inverse of :func:`attitude_from_radec_roll`.

    Parameters
    ----------
    rot : Rotation, single or batch of M
        Attitude(s), ICRS -> camera.

    Returns
    -------
    ra_rad : ndarray, shape (M,), or float
        Boresight right ascension in [0, 2 pi), rad; 0 when the boresight is at a pole.
    dec_rad : ndarray, shape (M,), or float
        Boresight declination in [-pi/2, pi/2], rad.
    roll_rad : ndarray, shape (M,), or float
        Roll in [0, 2 pi), rad, measured against the north/east directions of the returned
        (RA, Dec), so that ``attitude_from_radec_roll(*radec_roll_from_attitude(A))`` equals
        ``A`` to rounding everywhere, poles included.
    """
    check_rotation(rot, "rot")
    matrix = rot.as_matrix()
    x, y, z = matrix[..., 0, :], matrix[..., 1, :], matrix[..., 2, :]
    ra, dec = vectors_to_radec(z)
    east, north = east_north(ra, dec)
    # north_cam = (-sin roll, -cos roll), east_cam = (-cos roll, sin roll); both estimates are
    # combined so that the result is well conditioned whatever the rounding in x, y.
    x_north = np.einsum("...i,...i->...", x, north)
    y_north = np.einsum("...i,...i->...", y, north)
    x_east = np.einsum("...i,...i->...", x, east)
    y_east = np.einsum("...i,...i->...", y, east)
    roll = wrap_two_pi(np.arctan2(y_east - x_north, -y_north - x_east))
    return ra, dec, scalar_or_array(np.asarray(roll))


def radec_roll_from_matrix(matrix: ArrayLike) -> tuple[float, float, float]:
    """(RA, Dec, roll) of one attitude given as its matrix, rad: a per-frame loop's form.

    :func:`radec_roll_from_attitude` of ``Rotation.from_matrix(matrix)`` when ``matrix`` is
    that Rotation's ``as_matrix()``: the same NumPy operations on the same values, equal bit
    for bit, without the checks of a user's input and the batch handling (a third of the time).

    Parameters
    ----------
    matrix : array_like, shape (3, 3)
        Attitude matrix (ICRS -> camera), rows the camera axes in ICRS.

    Returns
    -------
    ra_rad, dec_rad, roll_rad : float
        As :func:`radec_roll_from_attitude`.
    """
    m = np.asarray(matrix, dtype=np.float64)
    x, y, z = m[0], m[1], m[2]
    # vectors_to_radec(z)
    rho = np.hypot(z[0], z[1])
    if rho == 0.0 and z[2] == 0.0:
        raise InputError("vectors contains a zero vector, which has no direction")
    ra = wrap_two_pi(np.arctan2(z[1], z[0]))
    ra = np.where(rho <= POLE_COS_DEC * np.abs(z[2]), 0.0, ra)
    dec = np.arctan2(z[2], rho)
    # east_north(ra, dec) and the roll, as radec_roll_from_attitude
    sin_ra, cos_ra = np.sin(ra), np.cos(ra)
    sin_dec, cos_dec = np.sin(dec), np.cos(dec)
    east = np.array([-sin_ra, cos_ra, 0.0])  # np.stack of the 0-d values, without its cost
    north = np.array([-sin_dec * cos_ra, -sin_dec * sin_ra, cos_dec])
    x_north = np.einsum("...i,...i->...", x, north)
    y_north = np.einsum("...i,...i->...", y, north)
    x_east = np.einsum("...i,...i->...", x, east)
    y_east = np.einsum("...i,...i->...", y, east)
    roll = wrap_two_pi(np.arctan2(y_east - x_north, -y_north - x_east))
    return float(ra), float(dec), float(roll)


def radec_roll_of_matrix(matrix: np.ndarray) -> tuple[float, float, float]:
    """(RA, Dec, roll) of one attitude matrix in Python floats: a solve's per-call form.

    The formulas of :func:`radec_roll_from_matrix` term by term on Python floats, ~10x faster
    (no NumPy scalar per step). Equal to it to rounding: the ``math`` module's sin, cos and
    atan2 (the C library's) may differ from NumPy's in the last bit where NumPy has its own.

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
        Attitude matrix (ICRS -> camera), rows the camera axes in ICRS, finite, orthonormal.

    Returns
    -------
    ra_rad, dec_rad, roll_rad : float
        As :func:`radec_roll_from_attitude`.
    """
    (x0, x1, x2), (y0, y1, y2), (z0, z1, z2) = matrix.tolist()
    rho = math.hypot(z0, z1)
    if rho == 0.0 and z2 == 0.0:
        raise InputError("vectors contains a zero vector, which has no direction")
    ra = 0.0 if rho <= POLE_COS_DEC * abs(z2) else _wrap(math.atan2(z1, z0))
    dec = math.atan2(z2, rho)
    sin_ra, cos_ra = math.sin(ra), math.cos(ra)
    sin_dec, cos_dec = math.sin(dec), math.cos(dec)
    # east = (-sin ra, cos ra, 0), north = (-sin dec cos ra, -sin dec sin ra, cos dec)
    n0, n1 = -sin_dec * cos_ra, -sin_dec * sin_ra
    x_north = x0 * n0 + x1 * n1 + x2 * cos_dec
    y_north = y0 * n0 + y1 * n1 + y2 * cos_dec
    x_east = x0 * -sin_ra + x1 * cos_ra
    y_east = y0 * -sin_ra + y1 * cos_ra
    return ra, dec, _wrap(math.atan2(y_east - x_north, -y_north - x_east))


def _wrap(angle: float) -> float:
    """:func:`~starsense.geometry.projection.wrap_two_pi` of one Python float."""
    wrapped = angle % TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


def angular_separation(u: ArrayLike, v: ArrayLike) -> NDArray[np.float64] | np.float64:
    """Angle between directions, ``atan2(|u × v|, u · v)``, accurate at all separations.

    Parameters
    ----------
    u, v : array_like, shape (N, 3) or (3,)
        Direction vectors (need not be normalised); broadcast against each other.

    Returns
    -------
    ndarray, shape (N,), or float
        Separation in [0, pi], rad.
    """
    a = _as_vectors(u, "u")
    b = _as_vectors(v, "v")
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.einsum("...i,...i->...", a, b)
    return scalar_or_array(np.asarray(np.arctan2(cross, dot)))


def small_rotation_angles(r_true: Rotation, r_est: Rotation) -> NDArray[np.float64]:
    """Attitude error as a rotation vector in the camera frame.

    The error rotation ``r_est * r_true.inv()`` takes the true camera frame to the estimated
    one; its rotation vector has components (x, y) about the cross-boresight axes (pointing
    error) and z about the boresight (roll error). For small errors these are the usual
    per-axis error angles.

    Parameters
    ----------
    r_true, r_est : Rotation, single or batch of N
        True and estimated attitudes (ICRS -> camera); a single rotation broadcasts.

    Returns
    -------
    ndarray, shape (N, 3) or (3,)
        Rotation vector, rad; its norm is the total error angle in [0, pi].
    """
    check_rotation(r_true, "r_true")
    check_rotation(r_est, "r_est")
    if not r_true.single and not r_est.single and len(r_true) != len(r_est):
        raise InputError(
            f"r_true and r_est must have the same length, got {len(r_true)} and {len(r_est)}"
        )
    return (r_est * r_true.inv()).as_rotvec()
