"""Orbits from a two-line element set, propagated by SGP4 (the ``sgp4`` package).

The TLE is checked column by column before SGP4 sees it (Hoots & Roehrich 1980, Spacetrack
Report No. 3, the element-set format; Vallado et al. 2006, AIAA 2006-6753): a malformed set
raises :class:`~starsense.errors.InputError` naming the file, the line and the column. SGP4
gives TEME positions; they are rotated to the GCRS by ``NPB(t)^T R3(-EqE)`` (Vallado et al.
2006, sec. "TEME"; ERFA ``pnm06a`` and ``ee06a``), evaluated at the middle of the span
(precession and nutation change it by < 0.1 arcsec a day). A start far from the TLE's epoch
warns with the age (:class:`TleAgeWarning`): SGP4 drifts by kilometres a day.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import erfa
import numpy as np
from astropy.time import Time
from numpy.typing import NDArray
from sgp4.api import SGP4_ERRORS, Satrec

from starsense._io import read_text
from starsense.analysis.mission.timegrid import TimeGrid, quiet_future
from starsense.errors import InputError

__all__ = ["TLE_VALID_DAYS", "TleAgeWarning", "TleOrbit", "parse_tle", "teme_to_gcrs_matrix"]

#: how far from its epoch a TLE is trusted, days (SGP4 errors grow to ~10 km by then)
TLE_VALID_DAYS = 14.0

# (line, first column, last column (1-based, inclusive), field, kind)
_FIELDS = (
    (1, 3, 7, "satellite number", "int"),
    (1, 19, 20, "epoch year", "int"),
    (1, 21, 32, "epoch day", "float"),
    (1, 34, 43, "first derivative of mean motion", "float"),
    (1, 45, 52, "second derivative of mean motion", "exp"),
    (1, 54, 61, "B* drag term", "exp"),
    (2, 3, 7, "satellite number", "int"),
    (2, 9, 16, "inclination", "float"),
    (2, 18, 25, "right ascension of the node", "float"),
    (2, 27, 33, "eccentricity", "int"),
    (2, 35, 42, "argument of perigee", "float"),
    (2, 44, 51, "mean anomaly", "float"),
    (2, 53, 63, "mean motion", "float"),
)


# (line, first column, last column, field, lowest, highest): the values the format allows
# (Spacetrack Report No. 3: day 1.0 is 1 January 00:00; 366 days in a leap year; mean motion
# below 20 rev/day keeps the perigee above the Earth's surface for any eccentricity of a
# real orbit, and positive keeps a period)
_RANGES = (
    (1, 21, 32, "epoch day", 1.0, 367.0),
    (2, 9, 16, "inclination (deg)", 0.0, 180.0),
    (2, 18, 25, "right ascension of the node (deg)", 0.0, 360.0),
    (2, 35, 42, "argument of perigee (deg)", 0.0, 360.0),
    (2, 44, 51, "mean anomaly (deg)", 0.0, 360.0),
    (2, 53, 63, "mean motion (rev/day)", 1e-3, 20.0),
)


class TleAgeWarning(UserWarning):
    """The span is far from the TLE's epoch: SGP4's error grows with the age."""


def _checksum(line: str) -> int:
    return sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68]) % 10


def _check_field(text: str, kind: str) -> bool:
    s = text.strip()
    if kind == "int":
        return s.isdigit()
    if kind == "exp":  # " 12345-3": an implied-decimal mantissa and a signed exponent
        s = s.replace(" ", "")
        body = s[1:] if s[:1] in "+-" else s
        return len(body) >= 2 and body[:-2].isdigit() and body[-2] in "+-" and body[-1].isdigit()
    try:
        float(s)
    except ValueError:
        return False
    return True


def parse_tle(text: str, source: str = "TLE") -> tuple[str, str, str]:
    """Check a TLE and return (name, line 1, line 2).

    Parameters
    ----------
    text : str
        Two lines, or three with a name line first (blank lines ignored).
    source : str
        The file, for messages.

    Returns
    -------
    name, line1, line2 : str

    Raises
    ------
    InputError
        Naming `source`, the line and the column of the first fault.
    """
    raw = [(i, ln.rstrip("\r\n ")) for i, ln in enumerate(text.splitlines(), start=1)]
    lines = [(i, ln) for i, ln in raw if ln.strip()]
    if len(lines) not in (2, 3):
        raise InputError(f"{source}: a TLE has 2 lines (or 3 with a name line), found {len(lines)}")
    name = lines[0][1].strip() if len(lines) == 3 else ""
    body = lines[-2:]
    for want, (no, line) in enumerate(body, start=1):
        if line[:1] != str(want):
            raise InputError(
                f"{source}, line {no}, column 1: expected line number {want}, got {line[:1]!r}"
            )
        if len(line) != 69:
            col = min(len(line), 69) + 1
            raise InputError(
                f"{source}, line {no}, column {col}: a TLE line has 69 "
                f"characters, this one {len(line)}"
            )
    for want, first, last, label, kind in _FIELDS:
        no, line = body[want - 1]
        if not _check_field(line[first - 1 : last], kind):
            raise InputError(
                f"{source}, line {no}, columns {first}-{last}: {label} "
                f"{line[first - 1 : last].strip()!r} is not a number"
            )
    for want, first, last, label, lo, hi in _RANGES:
        no, line = body[want - 1]
        text = line[first - 1 : last].strip()
        value = float(text)
        if not lo <= value <= hi:
            raise InputError(
                f"{source}, line {no}, columns {first}-{last}: {label} {text} is out of range; "
                f"must be in [{lo:g}, {hi:g}]"
            )
    no, line = body[0]
    yy = int(line[18:20])
    year = 2000 + yy if yy < 57 else 1900 + yy  # the TLE convention: 57-99 are 1957-1999
    days = 366 if (year % 4 == 0 and year % 100 != 0) or year % 400 == 0 else 365
    if float(line[20:32]) >= days + 1:
        raise InputError(
            f"{source}, line {no}, columns 21-32: epoch day {line[20:32].strip()} is past the "
            f"end of {year} ({days} days)"
        )
    for no, line in body:
        if not line[68].isdigit() or int(line[68]) != _checksum(line):
            raise InputError(
                f"{source}, line {no}, column 69: checksum {line[68]!r} does not match the "
                f"line (expected {_checksum(line)})"
            )
    if body[0][1][2:7] != body[1][1][2:7]:
        raise InputError(
            f"{source}, line {body[1][0]}, columns 3-7: satellite number differs from line 1"
        )
    return name, body[0][1], body[1][1]


def teme_to_gcrs_matrix(t: Time) -> NDArray[np.float64]:
    """Return the TEME -> GCRS rotation at `t` (3, 3): ``NPB^T R3(-EqE)``."""
    with quiet_future():
        tt = t.tt
    npb = erfa.pnm06a(tt.jd1, tt.jd2)  # GCRS -> true equator and equinox of date
    eqe = erfa.ee06a(tt.jd1, tt.jd2)  # true minus mean equinox along the equator
    c, s = np.cos(eqe), np.sin(eqe)
    r3 = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # R3(-EqE): TEME -> TOD
    return npb.T @ r3


@dataclass(frozen=True)
class TleOrbit:
    """An orbit from a TLE, propagated by SGP4.

    Parameters
    ----------
    line1, line2 : str
        The element set (checked by :func:`parse_tle`).
    name : str
        The satellite's name (the TLE's name line).
    """

    line1: str
    line2: str
    name: str = ""

    @classmethod
    def from_file(cls, path: str | Path) -> TleOrbit:
        """Read and check a TLE file (2 or 3 lines)."""
        p = Path(path)
        name, l1, l2 = parse_tle(read_text(p, "TLE file"), str(p))
        return cls(l1, l2, name)

    @property
    def satrec(self):
        """The sgp4 ``Satrec`` of the element set."""
        return Satrec.twoline2rv(self.line1, self.line2)

    @property
    def epoch(self) -> Time:
        """The TLE's epoch, UTC."""
        sat = self.satrec
        with quiet_future():
            return Time(sat.jdsatepoch, sat.jdsatepochF, format="jd", scale="utc")

    @property
    def label(self) -> str:
        """What the orbit is, for reports."""
        return f"TLE {self.name or self.line1[2:7].strip()}"

    def state(self, grid: TimeGrid) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return GCRS positions (m) and velocities (m/s) at the steps, each (n_steps, 3).

        Warns (:class:`TleAgeWarning`) when a step is more than :data:`TLE_VALID_DAYS` from
        the epoch; raises :class:`InputError` when SGP4 fails (decay, eccentricity out of range).
        """
        epoch = self.epoch
        with quiet_future():
            age0 = (grid.start - epoch).to_value("day")
        ages = [age0, age0 + grid.duration_s / 86400.0]
        worst = max(ages, key=abs)
        age = (
            f"the span is {worst:+.1f} days from the TLE epoch {epoch.isot}: SGP4 is "
            f"trusted to ~{TLE_VALID_DAYS:g} days"
        )
        jd1, jd2 = grid.jd("utc")
        err, r_km, v_km_s = self.satrec.sgp4_array(jd1, jd2)
        if np.any(err != 0):
            k = int(np.flatnonzero(err)[0])
            why = SGP4_ERRORS.get(int(err[k]), "error " + str(int(err[k])))
            old = f" ({age})" if abs(worst) > TLE_VALID_DAYS else ""
            raise InputError(f"SGP4 fails {k * grid.step_s:g} s after the start{old}: {why}")
        if abs(worst) > TLE_VALID_DAYS:
            warnings.warn(f"{age}; positions may be off by many km", TleAgeWarning, stacklevel=2)
        mid = grid.times(np.array([0.5 * grid.duration_s]))[0]
        m = teme_to_gcrs_matrix(mid)
        return r_km @ m.T * 1e3, v_km_s @ m.T * 1e3
