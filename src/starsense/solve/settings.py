"""A Solver's configuration: :class:`SolverSettings`, checked once when the Solver is built."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, TypeAlias

import numpy as np

from starsense._validate import check_int, check_scalar, finite_array, show
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.geometry.apparent import C_M_S
from starsense.units import DEG

if TYPE_CHECKING:
    from starsense.sensor import Sensor

__all__ = [
    "FOV_RANGE_RAD",
    "MAX_PATTERNS",
    "Algorithm",
    "BackgroundMode",
    "SolverSettings",
    "solver_settings",
]

#: the Solver's accepted range of a given horizontal field, rad (0.5-120 deg)
FOV_RANGE_RAD = (0.5 * DEG, 120.0 * DEG)

#: The default work budget of one solve, 4-star patterns looked up over all its identification
#: attempts (the given field; with a field that is an estimate, the scale search over 3 ranges
#: and 2 x 2 distortion guesses; then the mirror image): a set that does not identify stops
#: there, the same on every machine. A mirrored frame whose field is given as an estimate
#: spends up to 8 x 495 = 3,960 patterns before its mirror's first attempt, which this leaves
#: room for; on the shared frame sets solved with nothing known no solve spent more than 1,486,
#: and no centroid set of bench/peers more than 321. A set that identifies nowhere looks up
#: this many, not the ~7,000-8,000 of every attempt run to its end.
MAX_PATTERNS = 5000

#: Lost-in-space identification algorithms.
Algorithm: TypeAlias = Literal["hashing", "triangle"]
#: "auto": a background map and noise estimated from the frame; "known": the sensor's bias.
BackgroundMode: TypeAlias = Literal["auto", "known"]


@dataclass(frozen=True, kw_only=True, eq=False)
class SolverSettings:
    """How a :class:`~starsense.solve.solver.Solver` was configured (its sensor aside).

    Built and checked by the Solver (:func:`solver_settings`); read by tracking.

    Attributes
    ----------
    catalog : Catalog or str
        The catalogue as given: an object, or a spec (:func:`starsense.catalog.load_catalog`).
    algorithm : {"hashing", "triangle"}
        Lost-in-space algorithm.
    threshold_sigma : float
        Lit-pixel threshold above the background map, noise sigmas.
    centroid_sigma_px : float or "snr"
        Centroid noise assumed for the attitude covariance, px, or "snr" (each star's own).
    background : {"auto", "known"}
        Background mode.
    extraction : {"auto", "quick", "robust"}
        Star extraction (:mod:`starsense.solve.extraction`).
    apparent : bool
        Fit to the stars' apparent places when the frame's time is known.
    observer_velocity_m_s : ndarray, shape (3,), or None
        The observer's velocity relative to the geocentre, ICRS axes, m/s.
    fov_rad : float or None
        Horizontal field across the image width (pinhole), rad, when no sensor is given.
    sky : Catalog or str or None
        The catalogue whose stars the model fit draws as neighbours (None: the solver's own).
    refine : {"model", "cog"}
        The attitude's last step: "model" fits the forward model to the identified stars'
        pixels (:mod:`starsense.solve.refine`; needs a sensor), "cog" keeps the attitude fitted
        to the centroids.
    max_patterns : int or None
        The work budget of one solve: 4-star patterns looked up (hashing), summed over its
        identification attempts, after which it stops with status "timeout"; None: no bound.
    """

    catalog: Catalog | str = "hipparcos"
    algorithm: Algorithm = "hashing"
    threshold_sigma: float = 5.0
    centroid_sigma_px: float | Literal["snr"] | None = None
    background: BackgroundMode = "auto"
    extraction: str = "auto"
    apparent: bool = True
    observer_velocity_m_s: np.ndarray | None = None
    fov_rad: float | None = None
    refine: str | None = None
    sky: Catalog | str | None = None
    max_patterns: int | None = MAX_PATTERNS


def solver_settings(sensor: Sensor | None, **options) -> SolverSettings:
    """Check a Solver's options against each other and its sensor; return its settings.

    Parameters
    ----------
    sensor : Sensor or None
        The Solver's sensor (known optics and detection floors), None without one.
    **options
        The fields of :class:`SolverSettings`.

    Returns
    -------
    SolverSettings

    Raises
    ------
    InputError
        A value out of range, or options that need a sensor given without one.
    """
    s = SolverSettings(**options)
    fov_rad = s.fov_rad
    if sensor is not None and fov_rad is not None:
        raise InputError("give sensor or fov_rad, not both")
    if fov_rad is not None:
        fov_rad = check_scalar(fov_rad, "fov_rad", *FOV_RANGE_RAD)
    if s.sky is not None and not isinstance(s.sky, Catalog | str):
        raise InputError(f"sky must be a Catalog, a spec string or None, got {show(s.sky)}")
    if not isinstance(s.catalog, Catalog | str):
        raise InputError(f"catalog must be a Catalog or a spec string, got {show(s.catalog)}")
    if s.algorithm not in ("hashing", "triangle"):
        raise InputError(f"algorithm must be hashing or triangle, got {s.algorithm!r}")
    if sensor is None and fov_rad is None and s.algorithm == "triangle":
        raise InputError("the triangle algorithm needs a known field: give sensor or fov_rad")
    sigma = s.centroid_sigma_px
    if sigma is None:  # 0.3 px: real frames' centroids carry more than their photons' noise
        sigma = 0.3
    refine = s.refine if s.refine is not None else ("model" if sensor is not None else "cog")
    if refine not in ("model", "cog"):
        raise InputError(f"refine must be 'model' or 'cog', got {show(refine)}")
    if refine == "model" and sensor is None:
        raise InputError("refine='model' fits the sensor's forward model: give a sensor")
    number = isinstance(sigma, int | float) and not isinstance(sigma, bool)
    if sigma != "snr" and not (number and math.isfinite(sigma) and sigma > 0):
        raise InputError(f"centroid_sigma_px must be > 0 or 'snr', got {show(sigma)}")
    if s.background not in ("auto", "known"):
        raise InputError(f"background must be 'auto' or 'known', got {s.background!r}")
    if s.extraction not in ("auto", "quick", "robust"):
        raise InputError(f"extraction must be 'auto', 'quick' or 'robust', got {s.extraction!r}")
    if s.extraction == "quick" and s.background == "known":
        raise InputError("extraction='quick' estimates the background: use background='auto'")
    if sensor is None and (s.background == "known" or sigma == "snr"):
        raise InputError("background='known' and centroid_sigma_px='snr' need a sensor")
    max_patterns = s.max_patterns
    if max_patterns is not None:
        max_patterns = check_int(max_patterns, "max_patterns", 1)
    velocity = s.observer_velocity_m_s
    if velocity is not None:
        velocity = finite_array(velocity, "observer_velocity_m_s")
        if velocity.shape != (3,):
            raise InputError(
                f"observer_velocity_m_s must have 3 components, got shape {velocity.shape}"
            )
        speed = float(np.linalg.norm(velocity))
        if speed >= C_M_S:
            raise InputError(
                f"observer_velocity_m_s = {velocity.tolist()} is {speed:.4g} m/s, not below the "
                f"speed of light ({C_M_S:.9g} m/s); give the velocity in m/s (km/s on the CLI)"
            )
    return SolverSettings(
        **{
            **options,
            "fov_rad": fov_rad,
            "apparent": bool(s.apparent),
            "centroid_sigma_px": sigma,
            "refine": refine,
            "observer_velocity_m_s": velocity,
            "max_patterns": max_patterns,
        }
    )
