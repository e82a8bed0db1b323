"""The mission's time steps and the Earth's orientation at them.

Times are UTC, held as an :class:`astropy.time.Time` start and offsets in seconds. The Earth's
orientation comes from ERFA (the IAU 2006/2000A models astropy itself uses), vectorised over the
steps:

* GCRS <- ITRS: ``C2I(t)^T R3(-ERA(t))`` (IERS Conventions 2010, eq. 5.1, CIO-based), with
  UT1 taken as UTC (|UT1 - UTC| < 0.9 s: < 0.004 deg of Earth rotation) and polar motion
  neglected (< 1 arcsec). ``C2I`` changes by milliarcseconds over a day: it is evaluated at
  knots one day apart and the nearest is used.
* The mean Sun's right ascension for the local time of the node (Meeus 1998, eq. 25.2).
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property

import erfa
import numpy as np
from astropy import units as u
from astropy.time import Time
from erfa import ErfaWarning
from numpy.typing import NDArray

from starsense._validate import check_scalar
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time

__all__ = [
    "EARTH_ROTATION_RAD_S",
    "MAX_STEPS",
    "TimeGrid",
    "mean_sun_ra",
    "quiet_future",
]

#: Earth's rotation rate, rad/s (IERS Conventions 2010, Table 1.1)
EARTH_ROTATION_RAD_S = 7.292115e-5
#: largest number of time steps of one run (memory: ~100 floats per step and head)
MAX_STEPS = 20_000_000
_DAY_S = 86400.0
#: the years the Sun's and the Moon's positions are computed for (ERFA ``epv00``'s range)
EPHEMERIS_YEARS = (1900, 2100)


@contextlib.contextmanager
def quiet_future() -> Iterator[None]:
    """Silence ERFA's "dubious year" for times past the leap-second table (the future).

    Leap seconds not yet announced move UTC against TT by a second or two: nothing at the
    scale of this analysis.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*dubious year", category=ErfaWarning)
        yield


def _check_years(start: Time, duration_s: float) -> None:
    """Refuse a span outside the years the Sun's and Moon's ephemeris covers (1900-2100)."""
    with quiet_future():
        first = int(start.utc.ymdhms["year"])
        last = int((start + duration_s * u.s).utc.ymdhms["year"])
    if first < EPHEMERIS_YEARS[0] or last > EPHEMERIS_YEARS[1]:
        raise InputError(
            f"the span {first}-{last} is outside {EPHEMERIS_YEARS[0]}-{EPHEMERIS_YEARS[1]}, "
            "the years the built-in Sun and Moon ephemeris (ERFA epv00) holds: start within them"
        )


@dataclass(frozen=True)
class TimeGrid:
    """Equally spaced time steps ``t_k = start + k step_s``, ``k = 0 ... n_steps - 1``.

    Parameters
    ----------
    start : Time
        First step, UTC.
    step_s : float
        Step, s (> 0).
    n_steps : int
        Number of steps (>= 2).
    """

    start: Time
    step_s: float
    n_steps: int

    @classmethod
    def span(cls, start: object, duration_s: float, step_s: float) -> TimeGrid:
        """Return the grid covering `duration_s` from `start` at `step_s` (s).

        Each step stands for the interval ``[t_k, t_k + step_s)``: ``ceil(duration/step)``
        steps.
        """
        t0 = parse_time(start, "start")
        step = check_scalar(step_s, "step_s", 0.0, None, lo_open=True)
        duration = check_scalar(duration_s, "duration_s", 0.0, None, lo_open=True)
        n = math.ceil(duration / step - 1e-9)
        if n < 2:
            raise InputError(
                f"duration_s = {duration:g} s at step_s = {step:g} s gives {n} step; "
                "need at least 2 (shorten the step)"
            )
        if n > MAX_STEPS:
            raise InputError(
                f"{duration:g} s at {step:g} s steps is {n} steps, more than {MAX_STEPS}; "
                "lengthen the step"
            )
        _check_years(t0, n * step)
        return cls(t0, step, n)

    @cached_property
    def t_s(self) -> NDArray[np.float64]:
        """Offsets from the start, s, (n_steps,)."""
        return np.arange(self.n_steps, dtype=np.float64) * self.step_s

    @property
    def duration_s(self) -> float:
        """Time covered, ``n_steps * step_s``, s."""
        return self.n_steps * self.step_s

    def jd(self, scale: str = "utc") -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the two-part Julian dates of the steps in `scale` (``utc`` or ``tt``)."""
        with quiet_future():
            t = getattr(self.start, scale)
        return np.full(self.n_steps, t.jd1), t.jd2 + self.t_s / _DAY_S

    def times(self, t_s: NDArray[np.float64] | None = None) -> Time:
        """Return the steps (or the offsets `t_s`, s) as a :class:`Time` array, UTC."""
        offsets = self.t_s if t_s is None else np.asarray(t_s, dtype=np.float64)
        with quiet_future():
            return self.start + offsets * u.s

    def gcrs_from_itrs(self) -> NDArray[np.float64]:
        """Return the rotation matrices GCRS <- ITRS at every step, (n_steps, 3, 3)."""
        ut1, ut2 = self.jd("utc")  # UT1 ~ UTC (see module notes)
        era = erfa.era00(ut1, ut2)
        c, s = np.cos(era), np.sin(era)
        r3 = np.zeros((self.n_steps, 3, 3))  # R3(-ERA): TIRS -> CIRS
        r3[:, 0, 0], r3[:, 0, 1], r3[:, 1, 0], r3[:, 1, 1], r3[:, 2, 2] = c, -s, s, c, 1.0
        return np.einsum("nji,njk->nik", self._c2i(), r3)

    def _c2i(self) -> NDArray[np.float64]:
        """GCRS -> CIRS matrices at the steps, from knots a day apart (n_steps, 3, 3)."""
        tt1, tt2 = self.jd("tt")
        knots = np.arange(0.0, self.duration_s + _DAY_S, _DAY_S)
        mats = erfa.c2i06a(np.full(knots.size, tt1[0]), tt2[0] + knots / _DAY_S)
        idx = np.clip(np.rint(self.t_s / _DAY_S).astype(np.intp), 0, knots.size - 1)
        return mats[idx]

    def earth_axis(self) -> NDArray[np.float64]:
        """Return the Earth's rotation axis (the CIP) in the GCRS at every step, (n_steps, 3)."""
        return self._c2i()[:, 2, :]


def mean_sun_ra(t: Time) -> float:
    """Return the right ascension of the mean Sun at `t`, rad (Meeus 1998, eq. 25.2).

    The geometric mean longitude ``L0 = 280.46646 + 36000.76983 T + 0.0003032 T^2`` deg (T in
    Julian centuries of TT from J2000) is the right ascension of the fictitious mean Sun that
    defines mean local solar time, to a few arcseconds.
    """
    with quiet_future():
        tt = t.tt
    centuries = ((tt.jd1 - 2451545.0) + tt.jd2) / 36525.0
    deg = 280.46646 + 36000.76983 * centuries + 0.0003032 * centuries**2
    return math.radians(deg % 360.0)
