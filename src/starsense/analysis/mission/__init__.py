"""Availability over a mission: orbits, attitude profiles, the Sun, the Moon and the Earth.

Dzamba & Enright 2014 (Sensors 14, 3939), Fig. 1, last row: the availability of one or
several star-tracker heads along the track a specific mission flies, with the bright bodies
that blind them and the detection threshold at the rate the body turns.

The modules, along the seams of the computation:

* :mod:`.timegrid`: the time steps and the Earth's orientation (ERFA).
* :mod:`.orbit`: Keplerian orbits with secular J2, the sun-synchronous helper.
* :mod:`.tle`: TLEs (checked column by column) propagated by SGP4.
* :mod:`.ephemeris`: the Sun and the Moon (astropy's built-in ephemeris, splined).
* :mod:`.profiles`: attitude profiles and the body rate.
* :mod:`.heads`: heads, their mounting and exclusion.
* :mod:`.field`: stars detected along a continuous attitude history.
* :mod:`.results`: tracking logic, outages, the result.
* :mod:`.analysis`: :func:`mission_geometry`, :func:`mission_availability`.

Radians, metres and seconds inside; the JSON gives fractions and seconds.
"""

from __future__ import annotations

from starsense.analysis.mission.analysis import Geometry, mission_availability, mission_geometry
from starsense.analysis.mission.heads import Head, mounting_from_euler, mounting_from_quaternion
from starsense.analysis.mission.orbit import EARTH_RADIUS_M, KeplerOrbit, sun_synchronous
from starsense.analysis.mission.profiles import AttitudeProfile, body_rates
from starsense.analysis.mission.results import (
    HeadTimeline,
    MissionResult,
    outages,
    tracking_state,
)
from starsense.analysis.mission.timegrid import TimeGrid
from starsense.analysis.mission.tle import TleAgeWarning, TleOrbit, parse_tle
from starsense.geometry.apparent import parse_time

__all__ = [
    "EARTH_RADIUS_M",
    "AttitudeProfile",
    "Geometry",
    "Head",
    "HeadTimeline",
    "KeplerOrbit",
    "MissionResult",
    "TimeGrid",
    "TleAgeWarning",
    "TleOrbit",
    "body_rates",
    "mission_availability",
    "mission_geometry",
    "mounting_from_euler",
    "mounting_from_quaternion",
    "outages",
    "parse_time",
    "parse_tle",
    "sun_synchronous",
    "tracking_state",
]
