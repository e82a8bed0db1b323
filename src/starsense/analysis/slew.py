"""Slew tolerance: integrated intensity against slew rate, and the tolerable rate per magnitude.

Dzamba & Enright 2014, sec. 3.1: render a star smeared by a cross-axis slew (eqs. 12-22), add
shot and read noise, quantise like the detector, apply the detection logic, and record whether
the star is detected and its integrated intensity (Fig. 9). The tolerable slew rate of a
magnitude is the fastest rate at which it is still detected (Fig. 10).

Method, as implemented:

* The slew is a pure cross-axis rotation about the camera y axis: the streak runs along +x (rows
  of the detector), of length f tan(|w| t_e) / pitch (eq. 1), starting at a random sub-pixel
  position in each trial (the pixel phase changes which pixels light up). Rates are rad/s;
  :class:`SlewResult` gives deg/s for output.
* For each (rate, trial) one noiseless streak of unit flux is rendered (exactly integrated over
  pixel areas and time, :func:`starsense.render.smear.row_streaks_expected`) and scaled by
  each magnitude's photoelectrons: the expected image is linear in the flux, so all
  magnitudes share the rendering. Each rate has its own random stream (the pixel
  phases), and each (magnitude, rate) cell a child of it (the noise), so a cell's outcome does
  not depend on which other cells are simulated: the tolerance can stop each magnitude at the
  first rate where it is lost (``full_grid=False``) and still equal the whole grid's.
* Noise, gain and quantisation come from the sensor (:func:`starsense.render.noise.apply_noise`);
  detection applies the sensor's thresholds (:func:`starsense.detect.threshold.detect_stack`)
  with the known background (bias) subtracted, as the flight software subtracts the dark
  response (sec. 1.3). The star's integrated intensity is that of the brightest detection in
  the stamp.
* Detection criterion: a magnitude counts as detected at a rate when at least ``criterion``
  (default one half) of the trials detect it. The tolerable rate is the last rate of the grid,
  from rest upwards, before the detection fraction first falls below the criterion, refined by
  linear interpolation of the fraction between that grid point and the next. It is None when
  the star is not detected even at rest, and flagged ``capped`` when it is detected at every
  rate of the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from starsense._validate import as_generator, check_count
from starsense.analysis.inputs import as_sensor
from starsense.detect.stack import detect_stack
from starsense.errors import InputError
from starsense.photometry.sensitivity import Sensitivity
from starsense.render.noise import apply_noise
from starsense.render.smear import row_streaks_expected
from starsense.units import DEG, to_edge

__all__ = [
    "DEFAULT_MAX_RATE_RAD_S",
    "MAX_SLEW_SAMPLES",
    "MAX_TRIALS_PER_POINT",
    "SlewResult",
    "default_magnitudes",
    "default_rates_rad_s",
    "last_above",
    "magnitude_threshold",
    "simulate_slew",
    "slew_tolerance",
    "tolerable_rate",
]

#: the paper's rate range (Figs. 9-10): 0 to 10 deg/s, in deg/s as the paper gives it
_PAPER_MAX_RATE_DEG_S = 10.0
#: the paper's top rate, rad/s
DEFAULT_MAX_RATE_RAD_S = _PAPER_MAX_RATE_DEG_S * DEG
#: most float64 stamp bytes one batch of the slew Monte Carlo holds (noise and detection take
#: a few copies of it): 256 MiB keeps a run under ~1.5 GiB on a shared machine
STACK_BUDGET_BYTES = 2**28
#: most trials per (magnitude, rate): the detected fraction's binomial error at 100,000 is
#: under 0.16 %, and the default 20 x 40 grid then holds 0.7 GB of results
MAX_TRIALS_PER_POINT = 100_000
#: most simulated stars of one run (magnitudes x rates x trials): the result holds 9 bytes per
#: star (a flag and a float64 intensity), 0.9 GB at the cap
MAX_SLEW_SAMPLES = 100_000_000
SLEW_TRIAL_COST = "9 bytes of results and ~0.3 ms per simulated star"


def default_rates_rad_s(n: int = 40, max_rate_rad_s: float | None = None) -> np.ndarray:
    """Return `n` rates from 0 to `max_rate_rad_s` (inclusive), rad/s.

    The default top rate is the paper's 10 deg/s; its grid is spaced in deg/s and converted,
    so each rate is exactly ``k deg/s * DEG``.
    """
    if max_rate_rad_s is None:
        return np.linspace(0.0, _PAPER_MAX_RATE_DEG_S, n) * DEG
    return np.linspace(0.0, max_rate_rad_s, n)


def default_magnitudes(n: int = 20) -> np.ndarray:
    """Return `n` magnitudes in 0.25 mag steps ending at 6.0 (20: 1.25 ... 6.0)."""
    return 6.0 - 0.25 * np.arange(n)[::-1]


@dataclass(frozen=True)
class SlewResult:
    """Detection at rate, per magnitude and rate (Figs. 9-10).

    Attributes
    ----------
    magnitudes : array (M,)
        Simulated magnitudes.
    rates_rad_s : array (R,)
        Simulated slew rates, rad/s.
    electrons : array (M,)
        Expected photoelectrons of each magnitude (sensitivity model).
    detected_fraction : array (M, R)
        Fraction of trials in which the star was detected (NaN: cell not simulated, past the
        rate where the magnitude was lost, ``full_grid=False``).
    mean_intensity_counts : array (M, R)
        Mean integrated intensity of the detected trials (NaN where none), counts.
    ideal_intensity_counts : array (M,)
        Electrons x gain: the integrated intensity without saturation or detection logic.
    tolerable_rate_rad_s : list of float or None (M,)
        Fastest rate still detected, rad/s; None if not even at rest.
    capped : array (M,) bool
        Detected at every rate of the grid: the tolerable rate is at least the last rate.
    model, sensor_name : str
        Sensitivity model and sensor.
    n_trials : int
        Trials per (magnitude, rate).
    criterion : float
        Detection fraction that counts as detected.
    seed : int or None
        Root seed.
    threshold_counts : float
        The detection logic's integrated-intensity threshold, counts.
    """

    magnitudes: np.ndarray
    rates_rad_s: np.ndarray
    electrons: np.ndarray
    detected_fraction: np.ndarray
    mean_intensity_counts: np.ndarray
    ideal_intensity_counts: np.ndarray
    tolerable_rate_rad_s: list
    capped: np.ndarray
    model: str
    sensor_name: str
    n_trials: int
    criterion: float
    seed: int | None = None
    threshold_counts: float = field(default=0.0)

    @property
    def rates_deg_s(self) -> np.ndarray:
        """Simulated slew rates, deg/s (for output)."""
        return to_edge(self.rates_rad_s, DEG)

    @property
    def tolerable_rate_deg_s(self) -> list[float | None]:
        """Fastest rate still detected per magnitude, deg/s, None if never (for output)."""
        return [None if r is None else float(to_edge(r, DEG)) for r in self.tolerable_rate_rad_s]

    def tolerance_dict(self) -> dict:
        """Return the tolerable-rate curve as JSON-ready values (deg/s, Fig. 10)."""
        return {
            "sensor": self.sensor_name,
            "model": self.model,
            "magnitudes": [float(m) for m in self.magnitudes],
            "tolerable_rate_deg_s": [
                None if r is None else float(r) for r in self.tolerable_rate_deg_s
            ],
            "capped": [bool(c) for c in self.capped],
            "criterion": self.criterion,
            "n_trials": self.n_trials,
            "rates_deg_s": [float(r) for r in self.rates_deg_s],
            "seed": self.seed,
        }

    def intensity_dict(self) -> dict:
        """Return the integrated intensity against rate as JSON-ready values (Fig. 9)."""

        def clean(a):
            return [[None if not np.isfinite(v) else float(v) for v in row] for row in a]

        return {
            "sensor": self.sensor_name,
            "model": self.model,
            "magnitudes": [float(m) for m in self.magnitudes],
            "rates_deg_s": [float(r) for r in self.rates_deg_s],
            "mean_intensity_counts": clean(self.mean_intensity_counts),
            "detected_fraction": clean(self.detected_fraction),
            "ideal_intensity_counts": [float(v) for v in self.ideal_intensity_counts],
            "threshold_counts": self.threshold_counts,
            "n_trials": self.n_trials,
            "seed": self.seed,
        }


def _validate(magnitudes, rates_rad_s, n_trials, criterion):
    mags = np.atleast_1d(np.asarray(magnitudes, dtype=float))
    rates = np.atleast_1d(np.asarray(rates_rad_s, dtype=float))
    if mags.size == 0 or not np.all(np.isfinite(mags)):
        raise InputError("magnitudes must be a non-empty list of finite numbers")
    if rates.size == 0 or not np.all(np.isfinite(rates)):
        raise InputError("rates_rad_s must be a non-empty list of finite numbers")
    if np.any(rates < 0):
        raise InputError(f"rates_rad_s must be >= 0, got {rates[rates < 0][0]:g}")
    if np.any(np.diff(rates) <= 0):
        raise InputError("rates_rad_s must be strictly increasing")
    n_trials = check_count(n_trials, "n_trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)
    cells = mags.size * rates.size * n_trials
    if cells > MAX_SLEW_SAMPLES:
        raise InputError(
            f"n_trials = {n_trials:,} on {mags.size:,} magnitudes x {rates.size:,} rates is "
            f"{cells:,} simulated stars, above the cap of {MAX_SLEW_SAMPLES:,} "
            f"({SLEW_TRIAL_COST}); ask for fewer trials, magnitudes or rates"
        )
    if not 0 < criterion <= 1:
        raise InputError(f"criterion must be in (0, 1], got {criterion!r}")
    return mags, rates, n_trials


def last_above(x, y, level: float) -> float | None:
    """Return where ``y`` first falls below ``level``, walking ``x`` upwards (interpolated).

    The last ``x`` before ``y`` first drops under ``level``, moved linearly towards the first
    failing point; ``x[-1]`` when ``y`` never drops; None when ``y[0]`` is already below. Used
    for the tolerable rate (detection fraction against rate), the limiting magnitude (against
    magnitude) and the fastest rate that keeps an availability.

    Parameters
    ----------
    x : array (K,)
        Increasing abscissae.
    y : array (K,)
        Values at ``x``.
    level : float
        The threshold.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = y >= level
    if not ok[0]:
        return None
    fail = np.flatnonzero(~ok)
    if fail.size == 0:
        return float(x[-1])
    j = fail[0]  # first failing point; j - 1 passes
    t = (y[j - 1] - level) / (y[j - 1] - y[j]) if y[j - 1] != y[j] else 0.0
    return float(x[j - 1] + t * (x[j] - x[j - 1]))


def tolerable_rate(
    fraction_row: np.ndarray, rates: np.ndarray, criterion: float
) -> tuple[float | None, bool]:
    """Return the tolerable rate of one magnitude and whether it is capped by the grid.

    Parameters
    ----------
    fraction_row : array (R,)
        Detection fraction at each rate.
    rates : array (R,)
        Increasing rates (any unit; the result is in the same).
    criterion : float
        Detection fraction that counts as detected.

    Returns
    -------
    rate : float or None
        The fastest rate still detected (:func:`last_above`); None if not even at rest.
    capped : bool
        Detected at every rate of the grid.
    """
    rate = last_above(rates, fraction_row, criterion)
    return rate, bool(rate is not None and np.all(fraction_row >= criterion))


def slew_tolerance(
    sensor,
    *,
    model: str = "reed",
    magnitudes=None,
    rates_rad_s=None,
    n_trials: int = 20,
    criterion: float = 0.5,
    rng: int | np.random.Generator | None = 0,
    progress=None,
    colour_index: float = 0.0,
    full_grid: bool = True,
) -> SlewResult:
    """Simulate detection against slew rate, for every magnitude and rate (Figs. 9-10).

    Parameters
    ----------
    sensor : Sensor, str or Path
        The star tracker (or a preset name, or a sensor TOML file).
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model (magnitude -> electrons). "blackbody" fits each star's black body from
        its V magnitude and ``colour_index`` (B-V) and integrates it through the sensor's QE.
    magnitudes : array (M,), optional
        Magnitudes to simulate (default :func:`default_magnitudes`).
    rates_rad_s : array (R,), optional
        Slew rates, rad/s, increasing from rest (default :func:`default_rates_rad_s`).
    n_trials : int
        Monte Carlo repeats per (magnitude, rate), each with its own noise and pixel phase.
    criterion : float
        Detection fraction that counts as detected.
    rng : None, int or numpy.random.Generator
        Root seed; each rate derives its own child stream (``Generator.spawn``), so results are
        reproducible. None draws a fresh seed (recorded in the result).
    progress : callable(int done, int total) or None
        Called after each rate.
    colour_index : float
        B-V of the simulated stars for the "blackbody" model (default 0: an A0 star, the type of
        Reed's zero-magnitude reference).
    full_grid : bool
        Simulate every (magnitude, rate) cell (the intensities of Fig. 9). False stops each
        magnitude at the first rate where it is lost (detected in fewer than ``criterion`` of
        the trials): the cells past it hold NaN, and the tolerable rates, ``capped`` and the
        detection at rest are the same as the whole grid's, bit for bit (each cell draws its
        noise from its own stream).

    Returns
    -------
    SlewResult
    """
    sensor = as_sensor(sensor)
    if model not in ("reed", "liebe", "blackbody"):
        raise InputError(f"slew analysis model must be reed, liebe or blackbody, got {model!r}")
    if not np.isfinite(colour_index):
        raise InputError(f"colour_index must be finite, got {colour_index!r}")
    mags = default_magnitudes() if magnitudes is None else magnitudes
    rates = default_rates_rad_s() if rates_rad_s is None else rates_rad_s
    mags, rates, n_trials = _validate(mags, rates, n_trials, criterion)
    det = sensor.detector
    colours = np.full(len(mags), float(colour_index)) if model == "blackbody" else None
    electrons = np.asarray(
        Sensitivity.for_sensor(sensor, model).electrons(mags, colours), dtype=float
    )
    _check_streak_fits(sensor, rates[-1])
    n_m, n_r = len(mags), len(rates)
    detected = np.zeros((n_m, n_r, n_trials), dtype=bool)
    intensity = np.full((n_m, n_r, n_trials), np.nan)
    ran = np.zeros((n_m, n_r), dtype=bool)
    root, seed = as_generator(rng)
    streams = root.spawn(n_r)  # for an int seed: the children of SeedSequence(seed)
    for j, rate in enumerate(rates):
        todo = np.arange(n_m)
        if not full_grid and j > 0:  # magnitudes not yet lost at a slower rate
            todo = todo[np.all(detected[:, :j].mean(axis=2) >= criterion, axis=1)]
        if todo.size:
            _one_rate(sensor, rate, electrons, todo, streams[j], (detected, intensity, j))
            ran[todo, j] = True
        if progress is not None:
            progress(j + 1, n_r)
    fraction = np.where(ran, detected.mean(axis=2), np.nan)
    n_det = detected.sum(axis=2)
    total = np.where(detected, intensity, 0.0).sum(axis=2)
    mean_int = np.where(n_det > 0, total / np.maximum(n_det, 1), np.nan)
    tol, capped = zip(
        *(tolerable_rate(fraction[i], rates, criterion) for i in range(n_m)), strict=True
    )
    return SlewResult(
        magnitudes=mags,
        rates_rad_s=rates,
        electrons=electrons,
        detected_fraction=fraction,
        mean_intensity_counts=mean_int,
        ideal_intensity_counts=electrons * det.gain_counts_per_e,
        tolerable_rate_rad_s=list(tol),
        capped=np.array(capped),
        model=model,
        sensor_name=sensor.name,
        n_trials=int(n_trials),
        criterion=float(criterion),
        seed=seed,
        threshold_counts=float(sensor.detection.min_integrated_counts),
    )


def _one_rate(sensor, rate, electrons, todo, gen, out) -> None:
    """Simulate the magnitudes ``todo`` at one rate; write ``out = (detected, intensity, j)``.

    ``gen`` gives the trials' pixel phases (the unit stamps all magnitudes share), then one
    child stream per magnitude of the grid (``gen.spawn``) draws that cell's noise, so a cell's
    result does not depend on which other cells are simulated.
    """
    detected, intensity, j = out
    n_m, n_trials = detected.shape[0], detected.shape[2]
    phases = gen.random((n_trials, 2))  # x0, y0 of each trial
    unit, _, _ = row_streaks_expected(
        phases[:, 0],
        phases[:, 1],
        sensor.streak_length_px(rate),
        sigma_px=float(sensor.detector.psf_sigma_px),
    )
    cells = gen.spawn(n_m)
    det = sensor.detector
    for chunk in _magnitude_chunks(len(todo), unit, rate):
        rows = todo[chunk]
        counts = np.concatenate(
            [apply_noise(electrons[i] * unit, sensor, rng=cells[i]) for i in rows]
        )
        found, integ = detect_stack(counts, sensor.detection, background_counts=det.bias_counts)
        detected[rows, j, :] = found.reshape(-1, n_trials)
        intensity[rows, j, :] = integ.reshape(-1, n_trials)


def _check_streak_fits(sensor, top_rate_rad_s: float) -> None:
    """Refuse a slew whose star image (streak + 10 PSF sigma) is wider than the detector."""
    det = sensor.detector
    max_len = sensor.streak_length_px(top_rate_rad_s)
    width = max_len + 10 * det.psf_sigma_px
    if width < det.columns:
        return
    star = f"a star image {width:.0f} px wide (10 x detector.psf_sigma_px = {det.psf_sigma_px:g})"
    if max_len >= 0.5:
        top_deg_s = float(to_edge(top_rate_rad_s, DEG))
        star = (
            f"a {top_deg_s:g} deg/s slew sweeps a star {max_len:.0f} px in "
            f"{sensor.exposure_s:g} s ({width:.0f} px with 10 x detector.psf_sigma_px)"
        )
    raise InputError(
        f"{star}: wider than the detector (detector.columns = {det.columns}); the star "
        "does not fit the frame"
    )


def _magnitude_chunks(n_mags: int, unit: np.ndarray, rate_rad_s: float) -> list[slice]:
    """Split the magnitudes so that one batch of noisy stamps stays within the memory budget.

    Every magnitude at once when it fits (the usual case); else batches of magnitudes, each
    holding at most :data:`STACK_BUDGET_BYTES` of float64 counts. One magnitude's stamps
    beyond the budget raise :class:`InputError` naming the stamp size and the budget.
    """
    per_mag = unit.nbytes  # float64 (T, H, W) per magnitude; the noise and detection copy it
    if per_mag > STACK_BUDGET_BYTES:
        h, w = unit.shape[1:]
        raise InputError(
            f"slew at {float(to_edge(rate_rad_s, DEG)):g} deg/s: {unit.shape[0]} trial stamps "
            f"of {h} x {w} px need {per_mag / 2**30:.2f} GiB, more than the "
            f"{STACK_BUDGET_BYTES / 2**30:.2f} GiB one batch may use (memory of a shared "
            "machine); lower the trials, the rates or detector.psf_sigma_px"
        )
    per_batch = max(1, STACK_BUDGET_BYTES // max(per_mag, 1))
    return [slice(i, min(i + per_batch, n_mags)) for i in range(0, n_mags, per_batch)]


def magnitude_threshold(result: SlewResult, rates_rad_s) -> np.ndarray:
    """Return m_t(w), the faintest magnitude still detected at each rate (rad/s; Fig. 10).

    Reads the tolerable-rate curve sideways, magnitude by magnitude (the availability analysis
    interpolates it: :class:`~starsense.analysis.availability.ThresholdCurve`). Magnitudes
    whose tolerable rate is None are never detected; the curve is made monotonic (a brighter
    star tolerates at least the rate of a fainter one) before inverting.
    """
    rates = np.atleast_1d(np.asarray(rates_rad_s, dtype=float))
    mags = np.asarray(result.magnitudes, dtype=float)
    tol = np.array([-np.inf if r is None else r for r in result.tolerable_rate_rad_s])
    tol[np.asarray(result.capped)] = np.inf
    order = np.argsort(mags)
    mags, tol = mags[order], tol[order]
    tol = np.minimum.accumulate(tol)  # non-increasing with magnitude
    out = np.empty_like(rates)
    for i, w in enumerate(rates):
        ok = tol >= w
        out[i] = mags[ok].max() if ok.any() else -np.inf
    return out


simulate_slew = slew_tolerance
"""The name the analyses use for :func:`slew_tolerance` (the same function)."""
