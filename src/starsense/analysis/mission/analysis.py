"""Availability along a mission: orbit, attitude profile, bright bodies and several heads.

Dzamba & Enright 2014, Fig. 1, last row: availability along the track a specific mission
follows. Per step and per head (all vectorised over the steps):

1. the spacecraft's position (:mod:`.orbit`, :mod:`.tle`), the Sun and the Moon
   (:mod:`.ephemeris`), the body attitude and rate (:mod:`.profiles`);
2. the head's attitude ``M * A_body`` and its cross-boresight rate ``|(M w)_xy|`` (the rate the
   tolerable-slew curve of :mod:`starsense.analysis.slew` is simulated for: streaks across
   the detector; a roll about the boresight smears less and is not counted);
3. bright-body exclusion: the boresight within the Sun's or the Moon's half-angle, or within
   the Earth-limb half-angle of the limb raised by the atmosphere (the Earth is a sphere of
   the WGS 84 equatorial radius: its angular radius is ``asin((R + h_atm) / |r|)``), or on
   the Earth's disc;
4. stars detected: inside the field and no fainter than ``m_t(w)``
   (:class:`~starsense.analysis.availability.ThresholdCurve`), none when blinded
   (:func:`.field.detected_counts`);
5. lost-in-space (>= N_min) and tracking (>= 2 once acquired): :func:`.results.tracking_state`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from starsense._validate import check_int
from starsense.analysis.availability.results import N_MIN_LOST_IN_SPACE, N_MIN_TRACKING
from starsense.analysis.mission.ephemeris import body_positions, directions_from
from starsense.analysis.mission.field import detected_counts
from starsense.analysis.mission.heads import Head
from starsense.analysis.mission.orbit import EARTH_RADIUS_M
from starsense.analysis.mission.profiles import AttitudeProfile, body_rates
from starsense.analysis.mission.results import HeadTimeline, MissionResult, tracking_state
from starsense.analysis.mission.timegrid import TimeGrid
from starsense.errors import InputError

__all__ = ["Geometry", "mission_availability", "mission_geometry"]


def _angle(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angle between unit vectors, row by row, rad.

    ``arccos`` of the dot product: within 1e-8 rad (2 mas) of the exact angle even near 0 and
    pi, far below the exclusion half-angles it is compared with.
    """
    return np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))


class Geometry:
    """Where the spacecraft is, where it points and where the bright bodies are, per step.

    Attributes
    ----------
    grid : TimeGrid
    r, v : ndarray, shape (N, 3)
        GCRS position (m) and velocity (m/s).
    sun, moon : ndarray, shape (N, 3)
        Unit vectors from the spacecraft to the Sun and the Moon.
    body : ndarray, shape (N, 3, 3)
        Body attitude matrices, ICRS -> body.
    rate_body : ndarray, shape (N, 3)
        Body angular velocity in body axes, rad/s.
    """

    def __init__(self, grid: TimeGrid, orbit: Any, profile: AttitudeProfile) -> None:
        if not isinstance(grid, TimeGrid):
            raise InputError("grid must be a TimeGrid")
        if not isinstance(profile, AttitudeProfile):
            raise InputError("profile must be an AttitudeProfile")
        self.grid = grid
        self.r, self.v = orbit.state(grid)
        self.sun = directions_from(body_positions(grid, "sun"), self.r)
        self.moon = directions_from(body_positions(grid, "moon"), self.r)
        self.body = profile.attitudes(grid, r=self.r, v=self.v, sun=self.sun)
        self.rate_body = body_rates(self.body, grid.step_s)

    def head_matrices(self, head: Head) -> NDArray[np.float64]:
        """Return the head's attitude matrices ICRS -> head, (N, 3, 3)."""
        return np.matmul(head.mounting.as_matrix(), self.body)

    def earth_limb_angle(self, boresight: NDArray[np.float64], atmosphere_m: float):
        """Return the angle from `boresight` (N, 3) to the Earth's limb, rad (< 0: on the disc)."""
        dist = np.linalg.norm(self.r, axis=1)
        radius = np.arcsin(np.minimum((EARTH_RADIUS_M + atmosphere_m) / dist, 1.0))
        return _angle(boresight, -self.r / dist[:, None]) - radius


def mission_geometry(grid: TimeGrid, orbit: Any, profile: AttitudeProfile) -> Geometry:
    """Return the :class:`Geometry` of an orbit flown with an attitude profile."""
    return Geometry(grid, orbit, profile)


def _head_timeline(geo: Geometry, head: Head, vectors, magnitudes, tree, n_min: int):
    mats = geo.head_matrices(head)
    b = mats[:, 2, :]
    w = geo.rate_body @ head.mounting.as_matrix().T
    rate = np.hypot(w[:, 0], w[:, 1])
    exc = head.exclusion
    n = geo.grid.n_steps
    never = np.zeros(n, dtype=bool)
    sun_sep, moon_sep = _angle(b, geo.sun), _angle(b, geo.moon)
    limb = geo.earth_limb_angle(b, 0.0 if exc is None else exc.atmosphere_m)
    if exc is None:
        sun_b = moon_b = earth_b = never
    else:
        sun_b = never if exc.sun_rad is None else sun_sep < exc.sun_rad
        moon_b = never if exc.moon_rad is None else moon_sep < exc.moon_rad
        earth_b = never if exc.earth_limb_rad is None else limb < exc.earth_limb_rad
    m_t = head.curve(rate)
    m_t[sun_b | moon_b | earth_b] = -math.inf
    stars = detected_counts(
        head.fov, mats, vectors=vectors, magnitudes=magnitudes, threshold_mag=m_t, tree=tree
    )
    lis = stars >= n_min
    available = tracking_state(stars >= N_MIN_TRACKING, lis)
    return HeadTimeline(
        head.name,
        stars,
        rate,
        sun_sep,
        moon_sep,
        limb,
        sun_b,
        moon_b,
        earth_b,
        lis,
        available,
        head.describe(),
    )


def mission_availability(
    geometry: Geometry,
    heads: Sequence[Head],
    *,
    vectors: ArrayLike,
    magnitudes: ArrayLike,
    n_min: int = N_MIN_LOST_IN_SPACE,
    meta: dict | None = None,
) -> MissionResult:
    """Return the availability of each head and of the set along the mission.

    Parameters
    ----------
    geometry : Geometry
        Orbit, bright bodies and body attitude per step (:func:`mission_geometry`).
    heads : sequence of Head
        The heads (names unique).
    vectors : array_like, shape (S, 3)
        Star unit vectors, ICRS (the on-board catalogue).
    magnitudes : array_like, shape (S,)
        Their magnitudes.
    n_min : int
        Stars needed for a lost-in-space solution (tracking needs 2).
    meta : dict, optional
        Description of the run, copied into the result.

    Returns
    -------
    MissionResult
    """
    n_min = check_int(n_min, "n_min", N_MIN_TRACKING)
    heads = list(heads)
    if not heads:
        raise InputError("give at least one head")
    names = [h.name for h in heads]
    if len(set(names)) != len(names):
        raise InputError(f"head names must be unique, got {names}")
    v = np.asarray(vectors, dtype=np.float64)
    m = np.asarray(magnitudes, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or m.shape != (v.shape[0],) or m.size == 0:
        raise InputError(f"vectors must be (S, 3) and magnitudes (S,); got {v.shape}, {m.shape}")
    tree = cKDTree(v)
    timelines = [_head_timeline(geometry, h, v, m, tree, n_min) for h in heads]
    combined = np.logical_or.reduce([t.available for t in timelines])
    return MissionResult(
        geometry.grid.t_s,
        geometry.grid.step_s,
        timelines,
        combined,
        {"n_min": n_min, **(meta or {})},
    )
