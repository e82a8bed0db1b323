"""Availability in one call: static, under slew, and along a mission (``starsense.availability``).

Each function composes what the ``starsense availability`` and ``starsense mission`` commands
compose (the field of view, the catalogue cut, the threshold curve of the slew Monte Carlo, the
analysis) and returns the existing result types.

The mission's analysis module is imported as a module (``mission_analysis``), not by name: the
mission builds on this package's kernels, so when the mission package is imported first it is
still being initialised while this module loads, and its names are read at call time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

import starsense.analysis.mission.analysis as mission_analysis
from starsense.analysis.availability.analysis import DEFAULT_N_ORIENTATIONS, AvailabilityAnalysis
from starsense.analysis.availability.field import catalog_stars
from starsense.analysis.availability.pointings import field_of_view
from starsense.analysis.availability.results import (
    N_MIN_LOST_IN_SPACE,
    DynamicAvailability,
    StaticAvailability,
)
from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.analysis.inputs import DEFAULT_CATALOG_SPEC, as_catalog, as_sensor, root_seed
from starsense.analysis.mission.heads import Head
from starsense.analysis.mission.profiles import AttitudeProfile
from starsense.analysis.mission.results import MissionResult
from starsense.analysis.mission.specs import parse_attitude, parse_orbit
from starsense.analysis.mission.timegrid import TimeGrid
from starsense.analysis.slew import SlewResult, simulate_slew
from starsense.geometry.apparent import parse_time
from starsense.units import DEG

__all__ = ["DEFAULT_RATES_RAD_S", "DEFAULT_START", "dynamic", "mission", "static"]

#: the rates of ``starsense availability dynamic``: 0-3 deg/s by 0.25, then to 5 by 0.5 (rad/s)
DEFAULT_RATES_RAD_S = (
    np.array([0, 0.25, 0.5, 0.75, 1, 1.25, 1.5, 1.75, 2, 2.25, 2.5, 2.75, 3, 3.5, 4, 4.5, 5]) * DEG
)
#: the start of a mission whose orbit is written as text and no start is given (UTC)
DEFAULT_START = "2025-03-20T12:00:00"


def _analysis(
    sensor, catalog, *, fov, half_fov_rad, max_mag, n_orientations, roll_rad, rng, band, progress
):
    """Return (sensor, analysis) of the options every function shares."""
    sens = as_sensor(sensor)
    field = field_of_view(sens, fov, half_fov_rad)
    cat = as_catalog(catalog)
    analysis = AvailabilityAnalysis.from_catalog(
        cat,
        field,
        max_mag,
        band=band,
        n_orientations=n_orientations,
        roll_rad=roll_rad,
        rng=root_seed(rng),
        progress=progress,
    )
    return sens, analysis


def static(
    sensor,
    catalog=None,
    *,
    max_mag: float = 5.75,
    n_min: int = N_MIN_LOST_IN_SPACE,
    fov: str = "circular",
    half_fov_rad: float | None = None,
    n_orientations: int = DEFAULT_N_ORIENTATIONS,
    roll_rad: float | None = None,
    rng: int | np.random.Generator | None = 0,
    band: str = "V",
    progress: Callable[[str, int, int], None] | None = None,
) -> StaticAvailability:
    """Return the static availability: the fraction of the sky with >= ``n_min`` stars.

    Dzamba & Enright 2014, sec. 1.2: quasi-uniform boresights, a fixed detection threshold
    (the catalogue cut ``max_mag``). The same as ``starsense availability static``.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The sensor, a preset name or a sensor TOML file (its field).
    catalog : Catalog, str or None
        The catalogue, a specification or None for the bundled Hipparcos.
    max_mag : float
        Detection threshold m_t in ``band`` (stars fainter are never counted).
    n_min : int
        Stars needed (3: lost in space, 2: tracking).
    fov : {"circular", "rectangular"}
        The paper's cone of the detector's minor half-axis (or ``half_fov_rad``), or the
        detector's real field (where roll matters).
    half_fov_rad : float, optional
        Half-angle of the circular field, rad.
    n_orientations : int
        Boresights (spherical Fibonacci lattice).
    roll_rad : float, optional
        Roll of every boresight, rad (None: uniform random from ``rng``).
    rng : None, int or numpy.random.Generator
        Seed of the random rolls.
    band : str
        Magnitude band of ``max_mag``.
    progress : callable(label, done, total), optional
        Progress of the slow steps.

    Returns
    -------
    StaticAvailability
    """
    _, analysis = _analysis(
        sensor,
        catalog,
        fov=fov,
        half_fov_rad=half_fov_rad,
        max_mag=max_mag,
        n_orientations=n_orientations,
        roll_rad=roll_rad,
        rng=rng,
        band=band,
        progress=progress,
    )
    return analysis.static(n_min)


def _curve(sens, curve, model: str, n_slew_trials: int, seed: int, progress) -> ThresholdCurve:
    """Return m_t(w): given, from a slew result, or from a new slew Monte Carlo."""
    if isinstance(curve, ThresholdCurve):
        return curve
    if isinstance(curve, SlewResult):
        return ThresholdCurve.from_slew(curve)
    report = None if progress is None else (lambda d, t: progress("slew Monte Carlo", d, t))
    slew = simulate_slew(sens, model=model, n_trials=n_slew_trials, rng=seed, progress=report)
    return ThresholdCurve.from_slew(slew)


def dynamic(
    sensor,
    catalog=None,
    *,
    rates_rad_s: ArrayLike = DEFAULT_RATES_RAD_S,
    curve: ThresholdCurve | SlewResult | None = None,
    model: str = "reed",
    n_slew_trials: int = 20,
    max_mag: float = 5.75,
    n_min: int = N_MIN_LOST_IN_SPACE,
    fov: str = "circular",
    half_fov_rad: float | None = None,
    n_orientations: int = DEFAULT_N_ORIENTATIONS,
    roll_rad: float | None = None,
    rng: int | np.random.Generator | None = 0,
    progress: Callable[[str, int, int], None] | None = None,
) -> DynamicAvailability:
    """Return the availability against slew rate, the threshold m_t(w) falling with the rate.

    Dzamba & Enright 2014, sec. 3.1, Fig. 11: the static sky grid, with the threshold read from
    the tolerable-slew curve of the sensor's detection (the slew Monte Carlo, unless ``curve``
    is given). The same as ``starsense availability dynamic``.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The sensor, a preset name or a sensor TOML file.
    catalog : Catalog, str or None
        The catalogue, a specification or None for the bundled Hipparcos.
    rates_rad_s : array_like (R,)
        Slew rates, rad/s (default 0-5 deg/s, as the command).
    curve : ThresholdCurve or SlewResult, optional
        The threshold against rate (default: simulated for ``sensor`` with ``model``,
        ``n_slew_trials`` and ``rng``).
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model of the slew Monte Carlo.
    n_slew_trials : int
        Renders per (magnitude, rate) of the slew Monte Carlo.
    max_mag : float
        Catalogue cut (V).
    n_min : int
        Stars needed.
    fov : {"circular", "rectangular"}
        Shape of the field, as for :func:`static`.
    half_fov_rad : float or None
        Half-angle of a circular field, rad (None: from the sensor).
    n_orientations : int
        Boresights of the sky grid.
    roll_rad : float or None
        Roll of a rectangular field, rad (None: random per boresight).
    rng : None, int or numpy.random.Generator
        Root seed of the rolls and of the slew Monte Carlo.
    progress : callable(label, done, total), optional
        Progress of the slow steps.

    Returns
    -------
    DynamicAvailability
    """
    seed = root_seed(rng)
    sens, analysis = _analysis(
        sensor,
        catalog,
        fov=fov,
        half_fov_rad=half_fov_rad,
        max_mag=max_mag,
        n_orientations=n_orientations,
        roll_rad=roll_rad,
        rng=seed,
        band="V",
        progress=progress,
    )
    m_t = _curve(sens, curve, model, n_slew_trials, seed, progress)
    return analysis.dynamic(m_t, rates_rad_s, n_min)


def _catalog_label(catalog, cat) -> str:
    """Name the catalogue as the command does: its specification, else its name."""
    if isinstance(catalog, str):
        return catalog
    return DEFAULT_CATALOG_SPEC if catalog is None else getattr(cat, "name", "")


def _head(spec, seed: int) -> Head:
    """Return a head: given, or a sensor looking along the body +z with its own curve."""
    if isinstance(spec, Head):
        return spec
    sens = as_sensor(spec)
    slew = simulate_slew(sens, model="reed", rng=seed)
    return Head(
        sens.name,
        field_of_view(sens, "circular"),
        ThresholdCurve.from_slew(slew),
        exclusion=sens.exclusion,
    )


def mission(
    heads: Sequence[Any],
    orbit: Any,
    catalog=None,
    *,
    attitude: AttitudeProfile | str = "nadir",
    start: Any = None,
    duration_s: float = 86400.0,
    step_s: float = 1.0,
    max_mag: float = 5.75,
    n_min: int = N_MIN_LOST_IN_SPACE,
    rng: int | np.random.Generator | None = 0,
) -> MissionResult:
    """Return the availability of star-tracker heads along a mission.

    Dzamba & Enright 2014, sec. 4 and Fig. 1: the orbit flown with an attitude profile, the
    Sun, the Moon and the Earth that blind each head, the threshold at the rate the body turns
    (:func:`starsense.analysis.mission.mission_availability`). The same as ``starsense
    mission``.

    Parameters
    ----------
    heads : sequence of Head, Sensor or str
        The heads (:class:`~starsense.analysis.mission.Head`), or sensors (objects or preset
        names) looking along the body +z axis through their circular field, with the
        threshold curve of their own slew Monte Carlo.
    orbit : KeplerOrbit, TleOrbit or str
        The orbit, or its text form (``"sso:ALT_KM[:LTAN_H]"``, as ``--orbit``).
    catalog : Catalog, str or None
        The on-board catalogue, a specification or None for the bundled Hipparcos.
    attitude : AttitudeProfile or str
        The attitude profile, or its text form (``"nadir"``, ``"inertial:RA,DEC,ROLL"``, ...).
    start : astropy.time.Time or str, optional
        First step, UTC (default: the orbit's epoch; for an orbit as text,
        :data:`DEFAULT_START`).
    duration_s, step_s : float
        Span and step, s.
    max_mag : float
        Catalogue cut (V).
    n_min : int
        Stars a lost-in-space solution needs (tracking needs 2).
    rng : None, int or numpy.random.Generator
        Seed of the heads' slew Monte Carlo (heads given as sensors).

    Returns
    -------
    MissionResult
    """
    if isinstance(orbit, str):
        t0 = parse_time(start or DEFAULT_START, "start")
        orb = parse_orbit(orbit, t0, "orbit")
    else:
        orb = orbit
        t0 = orb.epoch if start is None else parse_time(start, "start")
    profile = parse_attitude(attitude, "attitude") if isinstance(attitude, str) else attitude
    seed = root_seed(rng)
    head_list = [_head(h, seed) for h in heads]
    grid = TimeGrid.span(t0, duration_s, step_s)
    geo = mission_analysis.mission_geometry(grid, orb, profile)
    cat = as_catalog(catalog)
    vectors, mags = catalog_stars(cat, max_mag)
    meta = {
        "start": t0.isot,
        "orbit": getattr(orb, "label", ""),
        "attitude": profile.label,
        "duration_h": duration_s / 3600.0,
        "catalog": _catalog_label(catalog, cat),
        "max_mag": max_mag,
    }
    return mission_analysis.mission_availability(
        geo, head_list, vectors=vectors, magnitudes=mags, n_min=n_min, meta=meta
    )
