"""Orbits: Keplerian elements with the secular J2 drift, and the sun-synchronous helper.

Positions and velocities are GCRS, metres and m/s, vectorised over the time steps. The
two-body motion is solved from Kepler's equation (Newton iteration); the Earth's oblateness
enters through the secular rates of the node, the perigee and the mean anomaly (Vallado 2013,
*Fundamentals of Astrodynamics and Applications*, 4th ed., eqs. 9-41, 9-42 and 9-43), which
is what keeps a sun-synchronous orbit's node following the Sun. Short-period J2 terms (~10 km)
are not modelled: they move a 550 km orbit's nadir by < 0.1 deg.
TLEs are propagated by SGP4 (:mod:`.tle`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from astropy.time import Time
from numpy.typing import NDArray

from starsense._validate import check_scalar, finite_float
from starsense.analysis.mission.timegrid import TimeGrid, mean_sun_ra, quiet_future
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time

__all__ = [
    "EARTH_RADIUS_M",
    "GM_EARTH_M3_S2",
    "J2_EARTH",
    "KeplerOrbit",
    "sun_synchronous",
]

#: Earth's equatorial radius, m (WGS 84)
EARTH_RADIUS_M = 6_378_137.0
#: Earth's gravitational parameter, m^3/s^2 (WGS 84 / EGM96)
GM_EARTH_M3_S2 = 3.986004418e14
#: Earth's second zonal harmonic (EGM96, unnormalised)
J2_EARTH = 1.08262668e-3
#: the node's sun-synchronous rate: one turn per tropical year, rad/s
_SSO_NODE_RATE_RAD_S = 2.0 * math.pi / (365.2421897 * 86400.0)


def _rotation_pqw(raan, incl, argp) -> NDArray[np.float64]:
    """Perifocal -> inertial matrices R3(-raan) R1(-incl) R3(-argp), (N, 3, 3)."""
    co, so = np.cos(raan), np.sin(raan)
    ci, si = np.cos(incl), np.sin(incl)
    cw, sw = np.cos(argp), np.sin(argp)
    m = np.empty((np.size(raan), 3, 3))
    m[:, 0, 0] = co * cw - so * sw * ci
    m[:, 0, 1] = -co * sw - so * cw * ci
    m[:, 0, 2] = so * si
    m[:, 1, 0] = so * cw + co * sw * ci
    m[:, 1, 1] = -so * sw + co * cw * ci
    m[:, 1, 2] = -co * si
    m[:, 2, 0] = sw * si
    m[:, 2, 1] = cw * si
    m[:, 2, 2] = ci
    return m


def _eccentric_anomaly(mean_anomaly: NDArray[np.float64], e: float) -> NDArray[np.float64]:
    """Solve Kepler's equation ``E - e sin E = M`` by Newton's method (to 1e-13 rad)."""
    m = np.mod(mean_anomaly, 2.0 * math.pi)
    ecc = m + e * np.sin(m) if e < 0.8 else np.full_like(m, math.pi)
    for _ in range(50):
        delta = (ecc - e * np.sin(ecc) - m) / (1.0 - e * np.cos(ecc))
        ecc -= delta
        if np.max(np.abs(delta)) < 1e-13:
            break
    return ecc


@dataclass(frozen=True)
class KeplerOrbit:
    """An orbit from classical elements at an epoch, GCRS (mean equator and equinox of J2000).

    Parameters
    ----------
    semi_major_axis_m : float
        Semi-major axis a, m (perigee above the Earth's surface).
    eccentricity : float
        e, in [0, 1).
    inclination : float
        i, rad, in [0, pi].
    raan : float
        Right ascension of the ascending node, rad.
    arg_perigee : float
        Argument of perigee, rad.
    mean_anomaly : float
        Mean anomaly at `epoch`, rad (for a circular orbit: the argument of latitude).
    epoch : Time
        Epoch of the elements, UTC.
    j2 : bool
        Apply the secular J2 rates (Vallado 2013, eqs. 9-41 to 9-43).
    label : str
        What the orbit is, for reports.
    """

    semi_major_axis_m: float
    eccentricity: float
    inclination: float
    raan: float
    arg_perigee: float
    mean_anomaly: float
    epoch: Time
    j2: bool = True
    label: str = ""

    def __post_init__(self) -> None:
        check_scalar(self.eccentricity, "eccentricity", 0.0, 1.0, hi_open=True)
        check_scalar(self.inclination, "inclination", 0.0, math.pi)
        for name in ("raan", "arg_perigee", "mean_anomaly"):
            finite_float(getattr(self, name), name)
        a = check_scalar(self.semi_major_axis_m, "semi_major_axis_m", 0.0, None, lo_open=True)
        perigee = a * (1.0 - self.eccentricity)
        if perigee <= EARTH_RADIUS_M:
            raise InputError(
                f"perigee radius {perigee / 1e3:.1f} km is inside the Earth "
                f"({EARTH_RADIUS_M / 1e3:.1f} km): raise the semi-major axis or lower e"
            )
        object.__setattr__(self, "epoch", parse_time(self.epoch, "epoch"))

    @property
    def mean_motion_rad_s(self) -> float:
        """Two-body mean motion n, rad/s."""
        return math.sqrt(GM_EARTH_M3_S2 / self.semi_major_axis_m**3)

    @property
    def period_s(self) -> float:
        """Two-body period, s."""
        return 2.0 * math.pi / self.mean_motion_rad_s

    def secular_rates(self) -> tuple[float, float, float]:
        """Return (dRAAN/dt, dargp/dt, dM/dt), rad/s (Vallado 2013, eqs. 9-41 to 9-43)."""
        n = self.mean_motion_rad_s
        if not self.j2:
            return 0.0, 0.0, n
        e2 = self.eccentricity**2
        p = self.semi_major_axis_m * (1.0 - e2)
        k = 1.5 * n * J2_EARTH * (EARTH_RADIUS_M / p) ** 2
        ci = math.cos(self.inclination)
        return (
            -k * ci,
            0.5 * k * (5.0 * ci**2 - 1.0),
            n + 0.5 * k * math.sqrt(1.0 - e2) * (3.0 * ci**2 - 1.0),
        )

    def state(self, grid: TimeGrid) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return GCRS positions (m) and velocities (m/s) at the steps, each (n_steps, 3)."""
        with quiet_future():
            dt = grid.t_s + float((grid.start - self.epoch).to_value("s"))
        d_raan, d_argp, d_m = self.secular_rates()
        e = self.eccentricity
        ecc = _eccentric_anomaly(self.mean_anomaly + d_m * dt, e)
        a = self.semi_major_axis_m
        cos_e, sin_e = np.cos(ecc), np.sin(ecc)
        root = math.sqrt(1.0 - e * e)
        r = a * (1.0 - e * cos_e)
        pqw = np.stack([a * (cos_e - e), a * root * sin_e, np.zeros_like(ecc)], axis=1)
        speed = math.sqrt(GM_EARTH_M3_S2 * a) / r
        vqw = np.stack([-speed * sin_e, speed * root * cos_e, np.zeros_like(ecc)], axis=1)
        m = _rotation_pqw(
            self.raan + d_raan * dt,
            np.full_like(dt, self.inclination),
            self.arg_perigee + d_argp * dt,
        )
        return (m @ pqw[:, :, None])[:, :, 0], (m @ vqw[:, :, None])[:, :, 0]


def sun_synchronous(
    altitude_m: float, *, ltan_h: float, epoch: object, arg_latitude: float = 0.0
) -> KeplerOrbit:
    """Return the circular sun-synchronous orbit at `altitude_m` with the node at `ltan_h`.

    The inclination makes the J2 node drift equal to the mean Sun's motion,
    ``cos i = -2 a^{7/2} dOmega/dt / (3 J2 R^2 sqrt(mu))`` (Vallado 2013, eq. 9-41 with
    e = 0); the node's right ascension is the mean Sun's plus ``15 deg/h (LTAN - 12 h)``.

    Parameters
    ----------
    altitude_m : float
        Altitude above the equatorial radius, m (100 km ... 6000 km).
    ltan_h : float
        Local (mean solar) time of the ascending node, h, in [0, 24): 6 or 18 is dawn-dusk.
    epoch : Time or str
        Epoch, UTC; the spacecraft is at `arg_latitude` from the ascending node then.
    arg_latitude : float
        Argument of latitude at the epoch, rad.

    Returns
    -------
    KeplerOrbit
    """
    alt = check_scalar(altitude_m, "altitude_m", 100e3, 6000e3)
    ltan = check_scalar(ltan_h, "ltan_h", 0.0, 24.0, hi_open=True)
    t0 = parse_time(epoch, "epoch")
    a = EARTH_RADIUS_M + alt
    cos_i = (
        -2.0
        * a**3.5
        * _SSO_NODE_RATE_RAD_S
        / (3.0 * J2_EARTH * EARTH_RADIUS_M**2 * math.sqrt(GM_EARTH_M3_S2))
    )
    raan = (mean_sun_ra(t0) + (ltan - 12.0) * math.pi / 12.0) % (2.0 * math.pi)
    return KeplerOrbit(
        a,
        0.0,
        math.acos(cos_i),
        raan,
        0.0,
        finite_float(arg_latitude, "arg_latitude"),
        t0,
        label=f"sun-synchronous {alt / 1e3:g} km, LTAN {ltan:g} h",
    )
