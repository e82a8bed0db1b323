"""starsense: from photons to attitude, how good a star sensor can be and how good it is.

The names a user needs, from ``import starsense as ss``::

    sensor = ss.load_sensor("st16")                       # a preset or your TOML
    rotation = ss.attitude_from_radec_roll(ra_rad, dec_rad, roll_rad)
    frame = ss.render_frame(sensor, rotation, rng=1)      # a frame and its truth
    solution = ss.Solver(sensor)(frame.image)             # lost in space
    sheet = ss.datasheet(sensor)                          # what the sensor will do

Sensors and sky
    load_sensor, Sensor
        A sensor preset or TOML file, as a frozen object (optics, detector, detection logic).
    load_catalog, Catalog
        A star catalogue (bundled Hipparcos, Gaia to G = 10, BSC5, Tycho-2, 2MASS, ...), as one
        object holding columns; filter it in Python and pass it anywhere a catalogue is taken.
    attitude_from_radec_roll
        The attitude (ICRS -> camera ``scipy.spatial.transform.Rotation``) from a boresight and
        a roll, all in radians.

Frames and attitude
    render_frame
        A detector frame of the catalogue at an attitude and body rate, with its truth.
    Solver, Solution
        Configure once, call on frames: lost in space, then the attitude and its covariance.
    Tracker
        Frame to frame from the last attitude (windows around the predicted stars), lost in
        space when that fails.
    calibrate
        Focal length, principal point and distortion fitted to the stars of solved frames.

What a sensor does
    datasheet, Datasheet, compare
        The sensor's datasheet (accuracy, lost in space, availability, slew, the physical
        limit), every predicted number checked on rendered frames in the same run; several
        designs side by side.
    predict
        What the datasheet predicts for a design without rendering frames (the same numbers,
        in about a second or a few): for trade studies.
    montecarlo
        Random attitudes through render -> detect -> identify -> estimate.
    availability
        Star-tracker availability: ``availability.static``, ``availability.dynamic`` (under
        slew) and ``availability.mission`` (an orbit and an attitude profile).
    slew_tolerance
        The slew-tolerance curve: the faintest star detected at each rate (Dzamba & Enright
        2014).
    sky_limit
        The physical limit of attitude accuracy over the sky (Fialho & Mortari 2019).

Angles are radians and rates rad/s throughout the Python interface; degrees and arcseconds
appear only in names that say so (``ra_deg``, ``nea_arcsec``). Randomness is an ``rng``: an int
seed or a ``numpy.random.Generator``. The names load on first use, so ``import starsense`` is
fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.2.0"

#: public name -> (module, attribute); attribute None: the module itself
_EXPORTS: dict[str, tuple[str, str | None]] = {
    "load_sensor": ("starsense.sensor", "load_sensor"),
    "Sensor": ("starsense.sensor", "Sensor"),
    "load_catalog": ("starsense.catalog", "load_catalog"),
    "Catalog": ("starsense.catalog", "Catalog"),
    "attitude_from_radec_roll": ("starsense.geometry.attitude", "attitude_from_radec_roll"),
    "render_frame": ("starsense.render.scene", "render_frame"),
    "Solver": ("starsense.solve", "Solver"),
    "Solution": ("starsense.solve", "Solution"),
    "Tracker": ("starsense.solve", "Tracker"),
    "calibrate": ("starsense.solve.calibration", "calibrate"),
    "datasheet": ("starsense.analysis.datasheet", "datasheet"),
    "Datasheet": ("starsense.analysis.datasheet", "Datasheet"),
    "compare": ("starsense.analysis.datasheet", "compare"),
    "predict": ("starsense.analysis.trade", "predict"),
    "montecarlo": ("starsense.analysis.montecarlo", "montecarlo"),
    "availability": ("starsense.analysis.availability", None),
    "slew_tolerance": ("starsense.analysis.slew", "slew_tolerance"),
    "sky_limit": ("starsense.analysis.limits", "sky_limit"),
}

__all__ = [
    "Catalog",
    "Datasheet",
    "Sensor",
    "Solution",
    "Solver",
    "Tracker",
    "__version__",
    "attitude_from_radec_roll",
    "availability",
    "calibrate",
    "compare",
    "datasheet",
    "load_catalog",
    "load_sensor",
    "montecarlo",
    "predict",
    "render_frame",
    "sky_limit",
    "slew_tolerance",
]

if TYPE_CHECKING:  # what the names are, for editors and type checkers
    from starsense.analysis import availability
    from starsense.analysis.datasheet import Datasheet, compare, datasheet
    from starsense.analysis.limits import sky_limit
    from starsense.analysis.montecarlo import montecarlo
    from starsense.analysis.slew import slew_tolerance
    from starsense.analysis.trade import predict
    from starsense.catalog import Catalog, load_catalog
    from starsense.geometry.attitude import attitude_from_radec_roll
    from starsense.render.scene import render_frame
    from starsense.sensor import Sensor, load_sensor
    from starsense.solve import Solution, Solver, Tracker
    from starsense.solve.calibration import calibrate


def __getattr__(name: str) -> Any:
    """Load a public name on first use (PEP 562): ``import starsense`` stays fast."""
    try:
        module, attribute = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'starsense' has no attribute {name!r}") from None
    value = importlib.import_module(module)
    if attribute is not None:
        value = getattr(value, attribute)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
