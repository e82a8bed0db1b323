"""Attitude profiles: the body's attitude (ICRS -> body) at every step, and its rate.

Every profile fixes the body +z axis and a secondary axis, and the body frame is the
right-handed triad they give (the attitude matrix has the body axes, in ICRS/GCRS, as rows:
:mod:`starsense.geometry.attitude`):

* ``inertial``: +z at (RA, Dec), with the roll of :func:`attitude_from_radec_roll`.
* ``nadir``: +z at the Earth's centre, +x along the velocity (perpendicular part); with yaw
  steering, +x along the velocity relative to the rotating ground, ``v - w_E x r``, so the
  ground moves along -x in the field of a nadir camera (compensating the Earth's rotation).
* ``sun``: +z at the Sun, +y towards celestial north (perpendicular part).
* ``target``: +z at a ground point (WGS 84 geodetic latitude and longitude, on the
  ellipsoid), +x along the velocity (perpendicular part); the slew rate varies along a pass.
* ``quaternions``: a time series ICRS -> body from a CSV file, interpolated by SLERP.

The body rate follows from the attitudes: ``w_k`` from the rotation between neighbouring steps
(central difference; one-sided at the ends), rad/s, in body axes.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import erfa
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from starsense._io import read_text
from starsense._validate import check_scalar, finite_float, show
from starsense.analysis.mission.timegrid import EARTH_ROTATION_RAD_S, TimeGrid
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll

__all__ = ["PROFILES", "AttitudeProfile", "body_rates", "read_quaternions", "triad"]

PROFILES = ("inertial", "nadir", "sun", "target", "quaternions")


def _unit(v: NDArray[np.float64], what: str) -> NDArray[np.float64]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(n < 1e-12):
        raise InputError(f"attitude profile: {what} is undefined (zero vector)")
    return v / n


def triad(z: NDArray[np.float64], x_hint: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return attitude matrices with +z along `z` and +x along the part of `x_hint` normal to it.

    Parameters
    ----------
    z, x_hint : ndarray, shape (N, 3)
        Inertial directions (need not be unit vectors; `x_hint` not parallel to `z`).

    Returns
    -------
    ndarray, shape (N, 3, 3)
        ICRS -> body (rows: the body axes in ICRS), orthonormal to rounding.
    """
    zu = _unit(z, "the +z axis")
    x = _unit(
        x_hint - np.sum(x_hint * zu, axis=1, keepdims=True) * zu,
        "the secondary axis (parallel to +z)",
    )
    y = np.cross(zu, x)
    return np.stack([x, y, zu], axis=1)


def body_rates(matrices: NDArray[np.float64], step_s: float) -> NDArray[np.float64]:
    """Return the body angular velocity at each step, rad/s, in body axes, (N, 3).

    ``A_{k+1} = exp(-[w x] dt) A_k`` for an attitude matrix ``A`` (ICRS -> body), so the
    rotation vector of ``D = A_{k+1} A_k^T`` is ``-w dt``: its axis times ``sin(angle)`` is the
    antisymmetric part of ``D`` and ``cos(angle) = (tr D - 1) / 2``. The two neighbouring
    intervals are averaged.

    Parameters
    ----------
    matrices : ndarray, shape (N, 3, 3)
        Attitudes, ICRS -> body, N >= 2.
    step_s : float
        Time step, s.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    if len(matrices) < 2:
        raise InputError("body rates need at least 2 steps")
    d = matrices[1:] @ matrices[:-1].transpose(0, 2, 1)
    vee = 0.5 * np.stack(
        [d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], axis=1
    )
    sin = np.linalg.norm(vee, axis=1)
    angle = np.arctan2(sin, 0.5 * (np.trace(d, axis1=1, axis2=2) - 1.0))
    scale = np.where(sin > 1e-300, angle / np.maximum(sin, 1e-300), 1.0)
    seg = -vee * scale[:, None] / step_s  # (N-1, 3)
    w = np.empty((len(matrices), 3))
    w[0], w[-1] = seg[0], seg[-1]
    w[1:-1] = 0.5 * (seg[1:] + seg[:-1])
    return w


def read_quaternions(path: str | Path) -> tuple[NDArray[np.float64], Rotation]:
    """Read a CSV of ``t_s,qx,qy,qz,qw`` (seconds from the start; ICRS -> body, scalar last).

    A header line naming the columns comes first. Quaternions are normalised; one whose norm
    is not 1 within 1e-3 is refused as not a rotation.

    Returns
    -------
    t_s : ndarray, shape (K,)
        Strictly increasing times, s.
    attitudes : Rotation, batch of K
    """
    p = Path(path)
    rows = list(csv.reader(read_text(p, "quaternion file").splitlines()))
    header = [h.strip() for h in rows[0]] if rows else []
    want = ["t_s", "qx", "qy", "qz", "qw"]
    if header != want:
        raise InputError(f"{p}, line 1: header must be {','.join(want)}, got {','.join(header)}")
    values, line_of = [], []
    for no, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != 5:
            raise InputError(f"{p}, line {no}: expected 5 columns, got {len(row)}")
        try:
            values.append([float(c) for c in row])
            line_of.append(no)
        except ValueError:
            col = next(i for i, c in enumerate(row, start=1) if not _is_float(c))
            raise InputError(
                f"{p}, line {no}, column {col} ({want[col - 1]}): "
                f"{row[col - 1].strip()!r} is not a number"
            ) from None
    a = np.asarray(values, dtype=np.float64).reshape(-1, 5)
    finite = np.isfinite(a)
    if not finite.all():
        row, col = np.argwhere(~finite)[0]
        raise InputError(
            f"{p}, line {line_of[row]}, column {col + 1} ({want[col]}): "
            f"{show(a[row, col])} is not a finite number"
        )
    if len(a) < 2:
        raise InputError(f"{p}: need at least 2 rows of t_s,qx,qy,qz,qw, found {len(a)}")
    back = np.flatnonzero(np.diff(a[:, 0]) <= 0)
    if back.size:
        k = back[0] + 1
        raise InputError(
            f"{p}, line {line_of[k]}: t_s = {show(a[k, 0])} is not after the previous "
            f"{show(a[k - 1, 0])}; t_s must be strictly increasing"
        )
    norms = np.linalg.norm(a[:, 1:], axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-3)
    if bad.size:
        raise InputError(
            f"{p}, line {line_of[bad[0]]}: quaternion norm {norms[bad[0]]:.4g} is not 1: "
            "not a rotation"
        )
    return a[:, 0], Rotation.from_quat(a[:, 1:] / norms[:, None])


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class AttitudeProfile:
    """How the body points: one of :data:`PROFILES` and its parameters.

    Parameters
    ----------
    kind : str
        ``inertial``, ``nadir``, ``sun``, ``target`` or ``quaternions``.
    ra, dec, roll : float
        ``inertial``: boresight and roll, rad.
    yaw_steering : bool
        ``nadir``: compensate the Earth's rotation.
    lat, lon : float
        ``target``: geodetic latitude and longitude of the ground point, rad.
    path : str
        ``quaternions``: the CSV file (:func:`read_quaternions`).
    """

    kind: str
    ra: float = 0.0
    dec: float = 0.0
    roll: float = 0.0
    yaw_steering: bool = False
    lat: float = 0.0
    lon: float = 0.0
    path: str = ""

    def __post_init__(self) -> None:
        if self.kind not in PROFILES:
            raise InputError(
                f"attitude profile must be one of {', '.join(PROFILES)}, got {self.kind!r}"
            )
        finite_float(self.ra, "ra")
        check_scalar(self.dec, "dec", -math.pi / 2, math.pi / 2)
        finite_float(self.roll, "roll")
        check_scalar(self.lat, "lat", -math.pi / 2, math.pi / 2)
        finite_float(self.lon, "lon")

    @property
    def label(self) -> str:
        """Short description, degrees at the edge."""
        d = 180.0 / math.pi
        if self.kind == "inertial":
            return f"inertial RA {self.ra * d:g}, Dec {self.dec * d:g}, roll {self.roll * d:g} deg"
        if self.kind == "nadir":
            return "nadir, yaw steering " + ("on" if self.yaw_steering else "off")
        if self.kind == "target":
            return f"target lat {self.lat * d:g}, lon {self.lon * d:g} deg"
        if self.kind == "quaternions":
            return f"quaternions from {self.path}"
        return "sun-pointing"

    def attitudes(
        self,
        grid: TimeGrid,
        *,
        r: NDArray[np.float64],
        v: NDArray[np.float64],
        sun: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Return the body attitudes (ICRS -> body) at the steps.

        Parameters
        ----------
        grid : TimeGrid
            The steps.
        r, v : ndarray, shape (N, 3)
            Spacecraft GCRS position (m) and velocity (m/s).
        sun : ndarray, shape (N, 3)
            Unit vector from the spacecraft to the Sun.

        Returns
        -------
        ndarray, shape (N, 3, 3)
            ICRS -> body.
        """
        n = grid.n_steps
        if self.kind == "inertial":
            one = attitude_from_radec_roll(self.ra, self.dec, self.roll)
            return np.broadcast_to(one.as_matrix(), (n, 3, 3)).copy()
        if self.kind == "nadir":
            hint = v
            if self.yaw_steering:
                hint = v - EARTH_ROTATION_RAD_S * np.cross(grid.earth_axis(), r)
            return triad(-r, hint)
        if self.kind == "sun":
            return triad(sun, np.cross(np.array([0.0, 0.0, 1.0]), sun))  # +y ~ north
        if self.kind == "target":
            g_itrs = np.asarray(erfa.gd2gc(1, self.lon, self.lat, 0.0))  # WGS 84, m
            g = np.einsum("nij,j->ni", grid.gcrs_from_itrs(), g_itrs)
            return triad(g - r, v)
        t_s, quats = read_quaternions(self.path)
        if t_s[0] > grid.t_s[0] or t_s[-1] < grid.t_s[-1]:
            raise InputError(
                f"{self.path}: the quaternions cover t_s {t_s[0]:g} ... {t_s[-1]:g} s; the "
                f"span needs 0 ... {grid.t_s[-1]:g} s"
            )
        return Slerp(t_s, quats)(grid.t_s).as_matrix()
