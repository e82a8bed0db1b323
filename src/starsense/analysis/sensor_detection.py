"""What the given sensor detects: its limiting magnitude and its threshold against slew rate.

One function, :func:`sensor_detection`, gives every analysis the same detection of the same
sensor (the datasheet, ``availability static|dynamic|mission``, ``slew tolerance``, the report),
so no analysis falls back on another sensor's numbers (a magnitude cut of 5.75, a slew grid
ending at V = 6):

1. the slew Monte Carlo (:func:`starsense.analysis.slew.simulate_slew`) at rest over a wide
   magnitude grid (V -2 ... 16 by 0.25) gives a first limit: the faintest magnitude detected in
   half the noisy renders;
2. the Monte Carlo again on the grid the sensor needs (:func:`slew_grids`: 0.25 mag steps ending
   just past that limit, 0.5 mag steps from there to the sky's brightest stars, rates up to
   what the detector can hold in one exposure) gives the limit (interpolated) and the threshold
   curve ``m_t(w)`` (Dzamba & Enright 2014, Fig. 10).

The static threshold an availability analysis uses is ``min(m_t(0), limit)``: the faintest
simulated magnitude detected at rest, never past the interpolated limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.analysis.inputs import as_sensor
from starsense.analysis.slew import SlewResult, default_rates_rad_s, last_above, simulate_slew
from starsense.units import DEG

__all__ = [
    "BRIGHTEST_V",
    "WIDE_MAGNITUDES",
    "SensorDetection",
    "limiting_magnitude",
    "sensor_detection",
    "slew_grids",
]

#: the sky's brightest stars (Sirius, V = -1.46): the slew grid's magnitudes reach them
BRIGHTEST_V = -1.5
#: the first, wide grid at rest: V -2 ... 16 by 0.25 (any sensor's limit lies inside)
WIDE_MAGNITUDES = np.arange(-2.0, 16.0001, 0.25)


def limiting_magnitude(magnitudes, fraction, criterion: float = 0.5) -> float | None:
    """Return the faintest magnitude detected in >= ``criterion`` of renders (interpolated).

    Parameters
    ----------
    magnitudes : array (M,)
        Increasing magnitudes.
    fraction : array (M,)
        Detection fraction of each at rest.
    criterion : float
        The fraction that counts as detected.

    Returns
    -------
    float or None
        The magnitude where the detection fraction crosses ``criterion`` on its way down
        (linear interpolation); None when not even the brightest is detected.
    """
    return last_above(magnitudes, fraction, criterion)


def slew_grids(sensor, static_limit: float, *, n_mag: int = 20, n_rate: int = 40):
    """Return the magnitudes and rates to simulate: from the sky's brightest stars to the limit.

    ``n_mag`` magnitudes in 0.25 mag steps end just past the limit (the paper's grid for the
    ST-16); brighter ones, in 0.5 mag steps, reach the sky's brightest stars
    (:data:`BRIGHTEST_V`): a long exposure or a fine pixel scale smears the stars of the fine
    part away at a fraction of the rates the detector can hold, and ``m_t(w)`` beyond that rate
    is the magnitude of the brighter stars that stay detected, not nothing. The rates run from
    rest to 10 deg/s (the paper's range), or less when a faster slew would sweep a star over
    more than half the detector's columns in one exposure.

    Parameters
    ----------
    sensor : Sensor
        The sensor.
    static_limit : float
        Its limiting magnitude at rest (V).
    n_mag, n_rate : int
        Sizes of the fine magnitude grid and of the rate grid.

    Returns
    -------
    magnitudes : ndarray, ascending
        V: the 0.5 mag steps down to BRIGHTEST_V or past it, then the ``n_mag`` fine ones.
    rates_rad_s : ndarray (n_rate,)
    """
    top = math.ceil(static_limit * 4.0) / 4.0 + 0.25
    fine = top - 0.25 * np.arange(n_mag)[::-1]
    bright = np.arange(fine[0] - 0.5, BRIGHTEST_V - 0.5, -0.5)[::-1]
    mags = np.concatenate([bright, fine])
    det = sensor.detector
    half_width = 0.5 * det.columns * det.pixel_pitch_m / sensor.optics.focal_length_m
    max_rate = math.atan(half_width) / sensor.exposure_s
    if max_rate >= 10.0 * DEG:  # the paper's grid, built as the slew analysis builds it
        return mags, default_rates_rad_s(n_rate)
    return mags, np.linspace(0.0, max_rate, n_rate)


@dataclass(frozen=True)
class SensorDetection:
    """A sensor's detection: limit at rest, the slew run on its own grid, and ``m_t(w)``.

    Attributes
    ----------
    limit_mag : float or None
        Faintest V detected in half the renders at rest (interpolated); None: nothing detected.
    slew : SlewResult or None
        The slew Monte Carlo on the sensor's grid (:func:`slew_grids`).
    curve : ThresholdCurve or None
        ``m_t(w)`` of that run.
    """

    limit_mag: float | None
    slew: SlewResult | None
    curve: ThresholdCurve | None

    @property
    def static_mag(self) -> float | None:
        """The threshold at rest an availability uses: ``min(m_t(0), limit)``, V (None: none)."""
        if self.curve is None or self.limit_mag is None:
            return None
        return float(min(float(self.curve(np.array([0.0]))[0]), self.limit_mag))


def sensor_detection(
    sensor,
    *,
    model: str = "reed",
    n_trials: int = 20,
    rng: int | np.random.Generator | None = 0,
    progress=None,
    full_grid: bool = True,
) -> SensorDetection:
    """Return what ``sensor`` detects: its limit, its slew run and ``m_t(w)`` (module docstring).

    Parameters
    ----------
    sensor : Sensor, str or Path
        The sensor (or a preset name, or a sensor TOML).
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model.
    n_trials : int
        Renders per (magnitude, rate).
    rng : None, int or numpy.random.Generator
        Seed of both Monte Carlo runs (the same seed gives the same numbers in every command).
    progress : callable(str label), optional
        Called after each of the two runs ("static limit", "slew tolerance").
    full_grid : bool
        Simulate every (magnitude, rate) cell of the slew run (its Fig. 9 intensities); False
        stops each magnitude at the first rate where it is lost: the same limit, tolerance and
        ``m_t(w)``, at a fraction of the renders (:func:`~starsense.analysis.slew.slew_tolerance`).

    Returns
    -------
    SensorDetection
    """
    sensor = as_sensor(sensor)
    rough = rest_limit(sensor, model=model, n_trials=n_trials, rng=rng)
    if progress is not None:
        progress("static limit")
    if rough is None:
        return SensorDetection(None, None, None)
    mags, rates = slew_grids(sensor, rough)
    slew = simulate_slew(
        sensor,
        model=model,
        magnitudes=mags,
        rates_rad_s=rates,
        n_trials=n_trials,
        rng=rng,
        full_grid=full_grid,
    )
    limit = limiting_magnitude(mags, slew.detected_fraction[:, 0])
    if progress is not None:
        progress("slew tolerance")
    return SensorDetection(rough if limit is None else limit, slew, ThresholdCurve.from_slew(slew))


def rest_limit(
    sensor,
    *,
    model: str = "reed",
    n_trials: int = 20,
    rng: int | np.random.Generator | None = 0,
    colour_index: float = 0.0,
) -> float | None:
    """Return the first limit at rest: the wide grid's faintest V detected in half the renders.

    Parameters
    ----------
    sensor : Sensor
        The sensor.
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model.
    n_trials : int
        Renders per magnitude.
    rng : None, int or numpy.random.Generator
        Seed.
    colour_index : float
        B-V of the stars ("blackbody" model).

    Returns
    -------
    float or None
        V (interpolated between the 0.25 mag steps); None when not even V = -2 is detected.
    """
    rest = simulate_slew(
        sensor,
        model=model,
        magnitudes=WIDE_MAGNITUDES,
        rates_rad_s=[0.0],
        n_trials=n_trials,
        rng=rng,
        colour_index=colour_index,
    )
    return limiting_magnitude(WIDE_MAGNITUDES, rest.detected_fraction[:, 0])


def sensor_grids(
    sensor,
    *,
    model: str = "reed",
    n_trials: int = 20,
    rng: int | np.random.Generator | None = 0,
    colour_index: float = 0.0,
):
    """Return the sensor's own slew grids: magnitudes ending past its limit, rates it can hold.

    :func:`slew_grids` around :func:`rest_limit` (the paper's 1.25 ... 6 when nothing is
    detected, so the run still says so).

    Parameters
    ----------
    sensor : Sensor
    model, n_trials, rng, colour_index
        As for :func:`rest_limit`.

    Returns
    -------
    magnitudes : ndarray, ascending
    rates_rad_s : ndarray (40,)
    """
    rough = rest_limit(sensor, model=model, n_trials=n_trials, rng=rng, colour_index=colour_index)
    return slew_grids(sensor, 5.75 if rough is None else rough)
