"""Star-tracker availability: spatial static, spatial dynamic and along-track dynamic.

Dzamba & Enright 2014 (Sensors 14, 3939), sec. 1.1-1.3 and 4. Availability is the fraction of
sensor orientations at which at least ``N_min`` stars brighter than the detection threshold
``m_t`` fall inside the field of view: ``N_min = 2`` to track, 3 to solve lost-in-space, 4 as a
conservative allowance for pattern ambiguity.

* **Spatial static** (sec. 1.2, Figs. 4-6): ``N`` quasi-uniform boresights (a spherical
  Fibonacci lattice standing in for the paper's Marantis distribution) and a fixed ``m_t``.
* **Spatial dynamic** (sec. 3.1, Fig. 11): the same boresights, with ``m_t = m_t(w)`` read from
  the tolerable-slew curve of the detection simulation (Fig. 10), :class:`ThresholdCurve`.
* **Along-track dynamic** (sec. 4, Figs. 16-17, Table 2): the boresight follows a great circle of
  inclination ``i`` to the celestial equator, sampled at ``N_track`` equally spaced orientations,
  while the sensor slews along it at a constant rate (the streaks run along the detector rows,
  camera +x, as in the slew simulation).

The modules, along the seams of the computation:

* :mod:`.threshold`: :class:`ThresholdCurve`, ``m_t(w)``.
* :mod:`.pointings`: the field, the sky grid of boresights, the track families.
* :mod:`.field`: the stars in the field at each pointing (:class:`FieldStars`, the counting
  kernel: availability at any threshold is a lookup into sorted magnitudes).
* :mod:`.results`: the result dataclasses.
* :mod:`.analysis`: :class:`AvailabilityAnalysis`, configure then ask.
* :mod:`.fidelity`: rendered frames through the detector against the threshold model.
* :mod:`.checks`: the checks with rules of their own (rates, magnitude limits).
* :mod:`.entry`: :func:`static`, :func:`dynamic` and :func:`mission`, each the whole analysis in
  one call from a sensor and a catalogue.

Angles are radians and rates rad/s; results give degrees for output. The catalogue's positions
are used at its own epoch (proper motion over a few decades moves the bright stars by
arcseconds, nothing at the scale of a 7.5 deg field). Frame conventions are those of
:mod:`starsense.geometry.attitude`. The paper's published numbers are in
:mod:`starsense.references.dzamba2014`.
"""

from __future__ import annotations

from starsense.analysis.availability.analysis import (
    DEFAULT_INCLINATIONS,
    DEFAULT_N_ORIENTATIONS,
    DEFAULT_TRACK_SAMPLES,
    AvailabilityAnalysis,
    implied_threshold,
)
from starsense.analysis.availability.checks import Fov, check_fov, check_mag, check_rates
from starsense.analysis.availability.entry import dynamic, mission, static
from starsense.analysis.availability.fidelity import FidelityCheck, fidelity_check
from starsense.analysis.availability.field import (
    BrightestInField,
    FieldStars,
    catalog_stars,
    field_pairs,
)
from starsense.analysis.availability.pointings import (
    describe_fov,
    field_of_view,
    sky_attitudes,
    track_family_attitudes,
)
from starsense.analysis.availability.results import (
    N_MIN_CONSERVATIVE,
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    DynamicAvailability,
    StaticAvailability,
    TrackAvailability,
    static_result,
)
from starsense.analysis.availability.threshold import ThresholdCurve

__all__ = [
    "DEFAULT_INCLINATIONS",
    "DEFAULT_N_ORIENTATIONS",
    "DEFAULT_TRACK_SAMPLES",
    "N_MIN_CONSERVATIVE",
    "N_MIN_LOST_IN_SPACE",
    "N_MIN_TRACKING",
    "AvailabilityAnalysis",
    "BrightestInField",
    "DynamicAvailability",
    "FidelityCheck",
    "FieldStars",
    "Fov",
    "StaticAvailability",
    "ThresholdCurve",
    "TrackAvailability",
    "catalog_stars",
    "check_fov",
    "check_mag",
    "check_rates",
    "describe_fov",
    "dynamic",
    "fidelity_check",
    "field_of_view",
    "field_pairs",
    "implied_threshold",
    "mission",
    "sky_attitudes",
    "static",
    "static_result",
    "track_family_attitudes",
]
