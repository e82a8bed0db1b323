"""The options and edge checks of ``starsense availability`` and ``availability mission``.

Options are declared once as :data:`typing.Annotated` aliases; the checks name the option and
its value, and convert degrees to radians before the library is called. Shared by
:mod:`starsense.cli.availability` (static, dynamic, track, fidelity) and
:mod:`starsense.cli.mission`.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense._io import check_outputs_in, read_text
from starsense._validate import check_count as _check_count
from starsense._validate import finite_float
from starsense.analysis.availability import (
    AvailabilityAnalysis,
    ThresholdCurve,
    field_of_view,
)
from starsense.analysis.availability.pointings import MAX_ORIENTATIONS, ORIENTATION_COST
from starsense.analysis.sensor_detection import sensor_detection
from starsense.analysis.slew import MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST
from starsense.catalog import load_catalog
from starsense.cli.common import (
    BRIGHTEST_MAG,
    option_float,
    output_dir,
    output_file,
)
from starsense.errors import InputError
from starsense.sensor import load_sensor
from starsense.units import DEG

# -- the options every command shares ---------------------------------------------------------

FovOpt = Annotated[
    str,
    typer.Option(
        "--fov",
        help="circular: a cone of the detector's minor half-axis (or --half-fov-deg); "
        "rectangular: the detector's real field, with roll.",
    ),
]
HalfFovOpt = Annotated[
    float | None,
    typer.Option(
        "--half-fov-deg",
        help="Half-angle of the circular field, deg (the ST-16 paper: 7.5; default: the "
        "sensor's minor half-axis).",
    ),
]
MaxMagOpt = Annotated[
    float | None,
    typer.Option(
        "--max-mag",
        help="Catalogue cut and static detection threshold m_t, V magnitude (default: the "
        "sensor's own, min(m_t(0), limiting magnitude) of its slew Monte Carlo, as in its "
        "datasheet).",
    ),
]
NMinOpt = Annotated[
    int,
    typer.Option("--n-min", help="Stars needed: 2 tracking, 3 lost-in-space, 4 conservative."),
]
NOrientOpt = Annotated[
    int, typer.Option("--n-orientations", help="Quasi-uniform boresights over the sky.")
]
RollOpt = Annotated[
    float | None,
    typer.Option(
        "--roll-deg",
        help="Roll of every spatial attitude, deg (rectangular field; default: uniform "
        "random from --seed).",
    ),
]
PlotOpt = Annotated[
    Path | None, typer.Option("--plot", help="Write the curve (PNG) here.", callback=output_file)
]
MapsOpt = Annotated[
    Path | None, typer.Option("--maps", help="Mollweide sky maps (PNG) here.", callback=output_dir)
]
ModelOpt = Annotated[str, typer.Option("--model", help="Sensitivity model: reed or liebe.")]
TrialsOpt = Annotated[
    int, typer.Option("--trials", help="Slew Monte Carlo trials per (magnitude, rate).")
]
ToleranceOpt = Annotated[
    Path | None,
    typer.Option(
        "--tolerance-json",
        help="Use a tolerable-slew curve saved by `starsense slew tolerance --json` instead of "
        "running the slew Monte Carlo.",
    ),
]

DEFAULT_DYNAMIC_RATES = "0,0.25,0.5,0.75,1,1.25,1.5,1.75,2,2.25,2.5,2.75,3,3.5,4,4.5,5"


# -- the options, checked at the edge (messages name the option) -------------------------------


#: the most stars a pointing may be asked to hold: far beyond any field of a star tracker (a few
#: thousand stars), well within the integers the field's counts are kept in
MAX_N_MIN = 1_000_000


def check_n_min(n_min: int) -> int:
    """Return ``--n-min`` (stars needed), checked: an integer >= 1.

    Raises
    ------
    InputError
        Naming ``--n-min`` and its value.
    """
    if not 1 <= n_min <= MAX_N_MIN:  # 10**23 overflowed the field's star counts (a traceback)
        raise InputError(
            f"N_min (--n-min) = {n_min} is out of range; must be an integer in 1-{MAX_N_MIN:,} "
            "(2 tracking, 3 lost-in-space, 4 conservative)"
        )
    return n_min


def check_count(n: int, label: str, option: str, cap: int | None = None, cost: str = "") -> int:
    """Return a count given to ``option``, checked: an integer >= 1, and <= ``cap`` if given.

    Parameters
    ----------
    n : int
        The option's value.
    label : str
        What is counted ("number of orientations"), for the message.
    option : str
        The option ("--n-orientations"), for the message.
    cap : int, optional
        The largest count allowed (derived from memory or time).
    cost : str
        What one unit costs, for the message.

    Raises
    ------
    InputError
        Naming the option and its value.
    """
    if n < 1:
        raise InputError(f"{label} ({option}) = {n} is out of range; must be an integer >= 1")
    if cap is not None:
        _check_count(n, f"{label} ({option})", cap, cost)
    return n


def check_slew_trials(n: int, option: str = "--trials") -> int:
    """Return the slew Monte Carlo's trials per (magnitude, rate), checked against their cap."""
    return _check_count(n, option, MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)


def check_rates_deg_s(values: list[float], option: str) -> np.ndarray:
    """Return slew rates given in deg/s, checked (finite, >= 0), in rad/s.

    Parameters
    ----------
    values : list of float
        The rates, deg/s.
    option : str
        The option that gave them, for the messages.

    Returns
    -------
    ndarray, shape (n,)
        The rates, rad/s.
    """
    rates = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(rates)):
        raise InputError(f"slew rates ({option}) must be finite, got {rates.tolist()}")
    if np.any(rates < 0):
        bad = float(rates[rates < 0][0])
        raise InputError(
            f"slew rate ({option}) = {bad:g} deg/s is negative; rates are magnitudes |w| >= 0"
        )
    if np.any(rates > MAX_RATE_DEG_S):  # 1e308 deg/s ran, every star smeared out, exit 0
        bad = float(rates[rates > MAX_RATE_DEG_S][0])
        raise InputError(
            f"slew rate ({option}) = {bad:g} deg/s is above {MAX_RATE_DEG_S:g} deg/s "
            "(one turn a second, the renderer's cap)"
        )
    return rates * DEG


#: the fastest slew rate an option takes, deg/s: one turn a second, as `render --rate-deg-s`
MAX_RATE_DEG_S = 360.0


def check_max_mag(max_mag: float | None) -> float | None:
    """Return ``--max-mag`` (magnitude), checked: not NaN, not -inf (None: the sensor's own).

    Raises
    ------
    InputError
        Naming ``--max-mag`` and its value.
    """
    if max_mag is not None and (math.isnan(max_mag) or max_mag == -math.inf):
        raise InputError(f"magnitude limit (--max-mag) must be finite, got {max_mag!r}")
    if max_mag is not None and max_mag < BRIGHTEST_MAG:  # +inf stays: every star
        raise InputError(
            f"magnitude limit (--max-mag) = {max_mag:g} is brighter than any star "
            f"(must be >= {BRIGHTEST_MAG:g})"
        )
    return max_mag


def field_of_view_option(sens, fov: str, half_fov_deg: float | None):
    """Return the field of view of ``--fov`` and ``--half-fov-deg``.

    Parameters
    ----------
    sens : Sensor
        The sensor (its detector gives the rectangular field and the default cone).
    fov : str
        ``"circular"`` or ``"rectangular"``.
    half_fov_deg : float or None
        Half-angle of the circular field, deg (converted to rad); None for the sensor's.

    Returns
    -------
    The field, as :func:`starsense.analysis.availability.field_of_view` returns it.

    Raises
    ------
    InputError
        Naming the option: an unknown shape, a half-angle outside (0, 90] deg, or a
        half-angle with the rectangular field.
    """
    if fov == "rectangular" and half_fov_deg is not None:
        raise InputError(
            "--half-fov-deg sets the circular field only; the rectangular field is the "
            "detector's (drop --half-fov-deg or use --fov circular)"
        )
    if fov not in ("circular", "rectangular"):
        raise InputError(f"field of view (--fov) must be 'circular' or 'rectangular', got {fov!r}")
    if half_fov_deg is None:
        return field_of_view(sens, fov)
    a = finite_float(half_fov_deg, "--half-fov-deg")
    if not 0.0 < a <= 90.0:
        raise InputError(
            f"half field (--half-fov-deg) = {a:g} deg is out of range; allowed (0, 90]"
        )
    return field_of_view(sens, fov, a * DEG)


def roll_option(roll_deg: float | None) -> float | None:
    """Return ``--roll-deg`` (deg) in radians, None when not given (a random roll per attitude).

    Raises
    ------
    InputError
        Naming ``--roll-deg`` when the value is not finite or outside -360 ... 360.
    """
    return None if roll_deg is None else option_float(roll_deg, "--roll-deg", -360.0, 360.0) * DEG


#: parameter names of the library -> the options that set them, for messages that depend on the
#: data (a magnitude cut that leaves no star of the catalogue)
_OPTIONS = {"max_mag": "--max-mag"}


@contextlib.contextmanager
def as_options() -> Iterator[None]:
    """Re-raise the library's user errors with its parameter names replaced by option names."""
    try:
        yield
    except InputError as exc:
        text = str(exc)
        for name, option in _OPTIONS.items():
            text = re.sub(rf"(?<![.\w]){name}\b", option, text)
        raise InputError(text) from None


def setup_analysis(
    sensor: str,
    catalog: str,
    *,
    fov: str,
    half_fov_deg: float | None,
    max_mag: float | None,
    n_orientations: int,
    roll_deg: float | None,
    seed: int,
    progress: Callable[[str, int, int], None] | None = None,
    band: str = "V",
):
    """Return (sensor, catalogue, analysis) of the options every command shares.

    Parameters
    ----------
    sensor, catalog : str
        ``--sensor`` and ``--catalog``.
    fov, half_fov_deg, max_mag, n_orientations, roll_deg, seed
        The options of the same names (degrees as given), checked here; ``max_mag`` None is
        the sensor's own static threshold (:func:`sensor_threshold`).
    progress : callable, optional
        ``progress(label, done, total)``.
    band : str
        Magnitude band of ``max_mag``.

    Returns
    -------
    tuple
        ``(Sensor, Catalog, AvailabilityAnalysis)``.
    """
    check_max_mag(max_mag)
    check_count(
        n_orientations,
        "number of orientations",
        "--n-orientations",
        MAX_ORIENTATIONS,
        ORIENTATION_COST,
    )
    roll = roll_option(roll_deg)
    sens = load_sensor(sensor)
    field = field_of_view_option(sens, fov, half_fov_deg)
    cat = load_catalog(catalog)
    if max_mag is None:  # the sensor's own threshold at rest, as its datasheet computes it
        max_mag = sensor_threshold(sens, seed=seed, progress=progress)[1]
    with as_options():
        analysis = AvailabilityAnalysis.from_catalog(
            cat,
            field,
            max_mag,
            band=band,
            n_orientations=n_orientations,
            roll_rad=roll,
            rng=seed,
            progress=progress,
        )
    return sens, cat, analysis


def sensor_threshold(
    sens,
    *,
    model: str = "reed",
    n_trials: int = 20,
    seed: int = 0,
    tolerance_json: Path | None = None,
    progress: Callable[[str, int, int], None] | None = None,
):
    """Return the sensor's m_t(w) and its static threshold, from a saved curve or the sensor.

    Without ``tolerance_json`` the slew Monte Carlo runs on the sensor's own grid
    (:func:`starsense.analysis.sensor_detection.sensor_detection`: magnitudes up to just past its
    limit, rates it can hold), the run its datasheet makes for the same model, trials and seed.

    Parameters
    ----------
    sens : Sensor
        The sensor.
    model : str
        ``--model``: ``"reed"`` or ``"liebe"``.
    n_trials : int
        ``--trials``: slew Monte Carlo trials per (magnitude, rate).
    seed : int
        ``--seed``.
    tolerance_json : Path or None
        ``--tolerance-json``: a curve saved by ``starsense slew tolerance --json``.
    progress : callable or None
        ``progress(label, done, total)``.

    Returns
    -------
    curve : ThresholdCurve
    static_mag : float
        The threshold at rest, V: ``min(m_t(0), limit)`` (a saved curve: its ``m_t(0)``).

    Raises
    ------
    InputError
        A bad option, or a sensor that detects no star even at rest.
    """
    if tolerance_json is not None:
        # a missing file, a folder, a FIFO (reading one waited for a writer for ever), not UTF-8
        text = read_text(tolerance_json, "--tolerance-json")
        try:
            data = json.loads(text.removeprefix("\ufeff"))
        except ValueError as exc:
            raise InputError(f"--tolerance-json {tolerance_json}: not valid JSON ({exc})") from None
        if not isinstance(data, dict):
            raise InputError(f"--tolerance-json {tolerance_json}: expected a JSON object")
        curve = ThresholdCurve.from_tolerance_dict(data, f"--tolerance-json {tolerance_json}")
        return curve, float(curve(np.array([0.0]))[0])
    if model not in ("reed", "liebe"):
        raise InputError(f"--model must be 'reed' or 'liebe', got {model!r}")
    if isinstance(n_trials, bool) or n_trials < 1:
        raise InputError(f"--trials = {n_trials} is out of range; must be an integer >= 1")
    det = sensor_detection(
        sens,
        model=model,
        n_trials=n_trials,
        rng=seed,
        progress=None
        if progress is None
        else (lambda label: progress(f"slew Monte Carlo ({model}): {label}", 1, 1)),
    )
    if det.curve is None:
        raise InputError(
            f"{sens.name} detects no star at rest, not even of magnitude -2: nothing is available"
        )
    return det.curve, det.static_mag


def threshold_curve_option(
    sens,
    *,
    model: str,
    n_trials: int,
    seed: int,
    tolerance_json: Path | None,
    progress: Callable[[str, int, int], None] | None,
):
    """Return m_t(w) from a saved tolerance JSON, or from the sensor's slew Monte Carlo.

    The curve of :func:`sensor_threshold` (same parameters).

    Returns
    -------
    ThresholdCurve
    """
    return sensor_threshold(
        sens,
        model=model,
        n_trials=n_trials,
        seed=seed,
        tolerance_json=tolerance_json,
        progress=progress,
    )[0]


def check_maps(maps: Path | None, names: list[str]) -> None:
    """Check the files ``--maps`` will get (new or regular files) before the work starts."""
    if maps is not None:
        check_outputs_in(maps, names, "--maps")


def maps_dir(maps: Path) -> Path:
    """Create the ``--maps`` directory (checked by the option's callback) and return it."""
    maps = Path(maps)  # checked by its option's callback (output_dir)
    maps.mkdir(parents=True, exist_ok=True)
    return maps
