"""Physical sanity of a datasheet: what is suspicious about the sensor or its numbers, in words.

What cannot exist is refused when the sensor is built (:mod:`starsense.sensor`: an f-number
below 0.5, a detection threshold the ADC cannot meet or finer than one count). What is only
suspicious is said here, in the datasheet's ``warnings``:

* a lit-pixel threshold at less than 3 or more than 20 sigma of the noise of an empty pixel
  (read noise, dark current over the exposure and quantisation, in counts);
* a bias below 3 sigma of that noise: the ADC clips the noise below zero, and the background
  is a rectified Gaussian (its mean above the bias, its smaller rms, the share of pixels at 0);
* fewer than half the frames solved at rest while an NEA is quoted, and too few to check it
  (:data:`starsense.analysis.datasheet.verify.MIN_CHECKED_FRAMES`), at rest or at the rate;
* a limiting magnitude past the catalogue's completeness (the stars in the field, the
  availability and the NEA then count too few stars).
"""

from __future__ import annotations

import math

from starsense.analysis.datasheet.noise import empty_pixel_sigma_counts
from starsense.analysis.datasheet.verify import MIN_CHECKED_FRAMES
from starsense.render.noise import empty_pixel_moments

__all__ = [
    "COMPLETENESS_V",
    "empty_pixel_sigma_counts",
    "no_star_reason",
    "sanity_warnings",
    "solving_warnings",
]

#: V to which each catalogue is complete, and the source of the figure
COMPLETENESS_V = {
    # ESA 1997, The Hipparcos and Tycho Catalogues, Vol. 1, sec. 1.1: the survey is complete
    # to V = 7.3 - 9.0 depending on galactic latitude and spectral type; 7.3 everywhere
    "hip2": (7.3, "Hipparcos, ESA 1997"),
    "hip_main": (7.3, "Hipparcos, ESA 1997"),
    # Hoffleit & Warren 1991 (Yale Bright Star Catalogue, 5th ed.): essentially complete to
    # V = 6.5
    "bsc5": (6.5, "Hoffleit & Warren 1991"),
    # Hog et al. 2000, A&A 355, L27: Tycho-2 is 99 % complete to V = 11.0
    "tycho2": (11.0, "Hog et al. 2000"),
    # the bundled Gaia DR3 file holds G <= 10 (V ~ G + 0.2 for BP-RP ~ 1)
    "gaia_dr3": (10.0, "the bundled Gaia DR3 file's cut, G <= 10"),
}
#: the detection logic's threshold, in sigma of an empty pixel, outside which it is suspicious
SIGMA_RANGE = (3.0, 20.0)
#: a bias below this many sigma of an empty pixel's noise lets the ADC clip the noise at 0
#: (at 3 sigma 0.13 % of the pixels are clipped, their mean moves by 0.0004 sigma)
BIAS_SIGMAS = 3.0


def sanity_warnings(sensor, *, catalog_name: str, limit_mag: float | None, runs) -> list[str]:
    """Return the datasheet's warnings on the detection logic, the solving and the catalogue.

    Parameters
    ----------
    sensor : Sensor
    catalog_name : str
        The catalogue's name (``hip2``, ``gaia_dr3``, ...).
    limit_mag : float or None
        The limiting magnitude, V.
    runs : dict of str -> MonteCarloCheck
        The Monte Carlo runs (``monte_carlo`` at rest).

    Returns
    -------
    list of str
    """
    out = []
    logic = sensor.detection
    sigma = empty_pixel_sigma_counts(sensor)
    k = logic.lit_pixel_counts / sigma
    lo, hi = SIGMA_RANGE
    if k < lo:
        out.append(
            f"the lit-pixel threshold ({logic.lit_pixel_counts:g} counts) is {k:.1f} sigma of "
            f"an empty pixel's noise ({sigma:.3g} counts): noise lights pixels in every frame "
            f"(a detection logic usually sits at ~5 sigma, {5 * sigma:.3g} counts)"
        )
    elif k > hi:
        out.append(
            f"the lit-pixel threshold ({logic.lit_pixel_counts:g} counts) is {k:.0f} sigma of "
            f"an empty pixel's noise ({sigma:.3g} counts): stars the noise would let through "
            f"are lost (a detection logic usually sits at ~5 sigma, {5 * sigma:.3g} counts)"
        )
    if sensor.detector.bias_counts < BIAS_SIGMAS * sigma:
        out.append(_clipped_bias(sensor, sigma))
    mc = runs.get("monte_carlo")
    if mc is not None and mc.frames and mc.solved < 0.5 * mc.frames:
        out.append(
            f"only {mc.solved} of {mc.frames} frames solved at rest: the NEA quoted is that of "
            "the frames that solve, not what the sensor delivers"
        )
    if mc is not None and mc.frames and mc.solved and mc.cross_ratio is None:
        out.append(
            f"the NEA is not checked against the rendered frames: {mc.solved} right "
            f"solution(s) at rest measure an rms to no better than "
            f"{100 / math.sqrt(2 * mc.solved):.0f} %, too coarse for the 0.8-1.25 acceptance"
        )
    at_rate = runs.get("monte_carlo_at_rate")
    few = at_rate is not None and at_rate.frames and at_rate.solved < MIN_CHECKED_FRAMES
    if few and (at_rate.solved or (mc is not None and mc.solved)):  # else nothing solves
        out.append(_few_at_rate(at_rate))
    if at_rate is not None and at_rate.solved and at_rate.cross_rms_arcsec is not None:
        if at_rate.cross_predicted_arcsec is None and at_rate.solved >= 10:
            out.append(
                f"at {at_rate.rate_deg_s:g} deg/s {at_rate.solved} frames solved, but the "
                "prediction at the rate holds no star bright enough to be detected there: the "
                "NEA under slew is measured, not predicted"
            )
    known = COMPLETENESS_V.get(catalog_name)
    if known is not None and limit_mag is not None and limit_mag > known[0]:
        out.append(
            f"the limiting magnitude V = {limit_mag:.2f} is past {catalog_name}'s completeness "
            f"(V = {known[0]:g}, {known[1]}): stars in the field, availability and NEA count too "
            "few stars; use a deeper catalogue (--catalog gaia, or tycho2)"
        )
    return out


def _clipped_bias(sensor, sigma: float) -> str:
    """Say what a bias of less than ``BIAS_SIGMAS`` sigma does to an empty pixel, in counts."""
    det = sensor.detector
    dark_e = det.dark_current_e_s * sensor.exposure_s
    mean, var = empty_pixel_moments(det, dark_e=dark_e)
    g = det.gain_counts_per_e
    s = g * math.sqrt(det.read_noise_e**2 + dark_e)
    # the pixels that read 0: the Gaussian below half a count, rounded to 0 or clipped there
    zero = 0.5 * (1.0 + math.erf((0.5 - g * dark_e - det.bias_counts) / (math.sqrt(2) * s)))
    return (
        f"bias {det.bias_counts:g} counts is {det.bias_counts / sigma:.1f} sigma of the read "
        f"noise ({sigma:.3g} counts): the ADC clips the noise below zero; an empty pixel reads "
        f"{mean - det.bias_counts - g * dark_e:.3g} counts above the bias with "
        f"{math.sqrt(var):.3g} counts rms, {zero:.0%} of them 0. The frames, the model fit "
        "(a pixel read 0 is censored) and its bound see that clipped background, which tells "
        "less of a faint star than an unclipped one; the centroids' weights (--refine cog) "
        "assume the unclipped noise. A camera's bias "
        f"usually sits at >= {BIAS_SIGMAS:g} sigma ({BIAS_SIGMAS * sigma:.3g} counts), where "
        "the noise is Gaussian"
    )


def _few_at_rate(run) -> str:
    """Say why a run at a rate with too few right solutions quotes no prediction or ratio."""
    if not run.solved:
        return (
            f"no frame of {run.frames} solved at {run.rate_deg_s:g} deg/s: the NEA under slew "
            "is neither measured nor predicted"
        )
    return (
        f"only {run.solved} of {run.frames} frames solved at {run.rate_deg_s:g} deg/s: too few "
        f"to check the NEA under slew (their rms is known to no better than "
        f"{100 / math.sqrt(2 * run.solved):.0f} %, the acceptance is 0.8-1.25), so neither the "
        "prediction at the rate nor its ratio is quoted"
    )


def solving_warnings(stars, avail, runs, *, n_min: int) -> list[str]:
    """Say in words what the numbers cannot: too few stars, no attitude, wrong solutions.

    Parameters
    ----------
    stars : StarsInFov
        Detectable stars per field.
    avail : AvailabilitySummary
        The availability (lost in space, tracking).
    runs : dict of str -> MonteCarloCheck
        The Monte Carlo runs (``monte_carlo`` at rest, first).
    n_min : int
        The stars lost in space needs.

    Returns
    -------
    list of str
    """
    out = []
    if (stars.median or 0) < n_min:
        out.append(
            f"the median field holds {stars.median} detectable stars, fewer than the "
            f"{n_min} lost in space needs"
        )
    if avail.tracking == 0.0:
        out.append("no boresight of the sky holds the 2 stars an attitude needs")
    mc, lis = runs["monte_carlo"], avail.lost_in_space
    if mc.frames:
        solved = mc.solved / mc.frames
        margin = 2.0 * math.sqrt(max(solved * (1 - solved), 1e-4) / mc.frames)  # ~95 %
        if solved < lis - margin:
            out.append(
                f"lost in space solved {solved:.1%} of the rendered frames at rest, below the "
                f"{lis:.1%} of the sky with >= {n_min} detectable stars: identification "
                f"needs more than that (statuses {mc.statuses})"
            )
    for key, run in runs.items():
        if run.wrong:
            out.append(f"{key}: {run.wrong} wrong identifications in {run.frames} frames")
        if run.frames_beyond_fit:
            out.append(
                f"at {run.rate_deg_s:g} deg/s, {run.frames_beyond_fit} of {run.solved} right "
                "solutions had streaks whose windows pass what the model fit may hold: the "
                "solver kept their centroids' attitude, which the datasheet does not predict at "
                "a rate (the check compares the others)"
            )
    return out


def no_star_reason(sensor, sky=None) -> str:
    """Return why a sensor's datasheet holds no number: it detects no star at rest.

    ``sky``: (its limiting magnitude, the catalogue's brightest star), V, where the limit lies
    above every star of the sky; None where it detects none of magnitude -2.
    """
    needs = (
        f"(the detection logic needs {sensor.detection.min_pixels} pixels above "
        f"{sensor.detection.lit_pixel_counts:g} counts and "
        f"{sensor.detection.min_integrated_counts:g} counts in all)"
    )
    if sky is None:
        return f"{sensor.name} detects no star at rest, not even of magnitude -2 {needs}"
    return (
        f"{sensor.name} detects no star of the sky at rest: its limiting magnitude, V "
        f"{sky[0]:.2f}, is brighter than the catalogue's brightest star (V {sky[1]:.2f}) {needs}"
    )
