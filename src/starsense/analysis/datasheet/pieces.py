"""A faint streak lit in pieces: where its detection lands, and whether it is detected at all.

A streak whose ridge is near the lit-pixel threshold is lit where the noise lifts its pixels
over it: in pieces, each a detection if it has ``min_pixels`` lit pixels summing to
``min_integrated_counts``. The solver identifies the piece nearest the star's mid-exposure
position (:mod:`starsense.identify.verify`), and matches it only when that piece's centre is
within the match radius (:func:`starsense.analysis.datasheet.merges.match_radius_px`): a
streak lit whole is matched, one lit in short pieces is matched as often as a piece lands near
its middle, one never lit is not detected.

Where the pieces fall is a question of the noise in each pixel along the ridge, and of where
the ridge crosses the pixel grid: with an undersampled PSF, a streak along a pixel row puts
most of its light in one row, one between two rows splits it, and a slanted streak goes from
one to the other along its length. :func:`piece_offsets_px` draws it, pixel by pixel, the way
the detector sees it:

* the streak's light per column of pixels along its major axis (its uniform smear convolved
  with the PSF along it), spread across the column by the PSF (sigma ``s / cos theta`` along
  the pixel axis, ``theta`` the streak's angle to it) at the phase the streak's line crosses
  the column, which moves by the streak's slope from one column to the next;
* each pixel lit where its counts, drawn with the star's shot noise and the empty pixel's noise
  (:func:`~starsense.analysis.datasheet.noise.empty_pixel_sigma_counts`), pass the threshold;
* lit columns next to each other are one piece (8-connectivity: the lit pixels of neighbouring
  columns of a streak whose slope is at most 1 touch); a piece is a detection when it passes
  the detection logic's pixel count and its lit pixels' summed counts;
* the offset of the nearest detection's centre of gravity (the lit pixels' counts) from the
  middle, along the streak; its own centroid sigma as the solver computes it (its box and summed
  counts), where no other piece lies within its own four sigma of the middle; its summed counts,
  and the streak's detections per bin of summed counts (the verification takes a frame's
  brightest detections only, and a frame of long faint streaks holds hundreds of pieces).

On rendered frames of two undersampled designs (PSF sigma 0.56-0.61 px, 11-21 px streaks) the
fraction of stars with a detection within 1.5, 3 and 6 px of their middle follows the
detector's within 0.1 across ridges of 0.5-4 times the threshold; on 24 rendered faint streaks
(PSF 0.55-1.5 px, 10-40 px, ridges 0.6-2 times the threshold) within 0.15, 0.02 on average.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from starsense.analysis.datasheet.noise import empty_pixel_sigma_counts
from starsense.solve.rematch import MATCH_SIGMAS

__all__ = [
    "FLUX_BINS",
    "WHOLE_RIDGE",
    "Pieces",
    "footprint_half_width_px",
    "piece_offsets_px",
    "ridge_counts",
]

#: a streak whose expected ridge is this many times the lit-pixel threshold is lit whole: its
#: brightest pixel across holds at least 0.69 of the ridge at any phase (an undersampled PSF,
#: sigma 0.6 px, on a pixel edge), 1.75 thresholds above the threshold, over 5 sigma of the
#: noise for a detection logic at 3 sigma of the read noise or more
WHOLE_RIDGE = 4.0
#: draws per star
SAMPLES = 64
#: bins of log10 summed counts in which a frame's detections are counted (to rank them)
FLUX_BINS = np.linspace(0.0, 10.0, 201)
#: sub-samples per column of the light along the streak
_SUB = 8


def ridge_counts(sensor, electrons, length_px) -> np.ndarray:
    """Return the expected counts above the bias along a streak's ridge.

    ``N / ((l + sqrt(2 pi) s) sqrt(2 pi) s)`` electrons per pixel (``N`` the star's electrons,
    ``l`` its streak, ``s`` the PSF sigma; ``N / 2 pi s^2`` at rest), times the gain.
    """
    s = sensor.detector.psf_sigma_px
    root = math.sqrt(2.0 * math.pi) * s
    e = np.asarray(electrons, dtype=float) / ((np.asarray(length_px, dtype=float) + root) * root)
    return e * sensor.detector.gain_counts_per_e


def footprint_half_width_px(sensor, electrons, length_px) -> np.ndarray:
    """Return how far either side of its line a streak's expected counts pass the threshold, px.

    0 where its ridge does not reach the detection logic's lit-pixel threshold.
    """
    over = ridge_counts(sensor, electrons, length_px) / float(sensor.detection.lit_pixel_counts)
    return sensor.detector.psf_sigma_px * np.sqrt(2.0 * np.log(np.maximum(over, 1.0)))


def _column_light(n_e: float, major: float, sigma_along: float, n: int) -> tuple:
    """Columns' offsets from the middle (n,) and each one's share of n_e electrons."""
    i = np.arange(n) - (n - 1) / 2.0
    sub = i[:, None] + (np.arange(_SUB) + 0.5)[None, :] / _SUB - 0.5
    half = 0.5 * major
    share = (ndtr((sub + half) / sigma_along) - ndtr((sub - half) / sigma_along)).mean(axis=1)
    return i, share / share.sum() * n_e


def _one(sensor, n_e: float, streak, rng, samples: int, margin_px: int) -> tuple:
    det, logic = sensor.detector, sensor.detection
    s, gain = det.psf_sigma_px, det.gain_counts_per_e
    dx, dy = abs(float(streak[0])), abs(float(streak[1]))
    major, minor = max(dx, dy), min(dx, dy)
    length = math.hypot(dx, dy)
    slope = minor / major if major > 0 else 0.0
    cos = major / length if length > 0 else 1.0
    across_s = s / cos
    n = math.ceil(major) + 1 + 2 * math.ceil(3.0 * s * cos)
    i, electrons = _column_light(n_e, major, max(s * cos, 1e-3), n)
    phase = (rng.uniform(0.0, 1.0, samples)[:, None] + i[None, :] * slope) % 1.0  # (K, n)
    j = np.arange(-math.ceil(3.0 * across_s) - 1, math.ceil(3.0 * across_s) + 2)
    frac = ndtr((j + 0.5 - phase[..., None]) / across_s) - ndtr(
        (j - 0.5 - phase[..., None]) / across_s
    )
    mean = electrons[None, :, None] * frac * gain  # counts (K, n, J)
    noise = np.sqrt(empty_pixel_sigma_counts(sensor) ** 2 + mean * gain)
    counts = mean + rng.standard_normal(mean.shape) * noise
    lit = counts > logic.lit_pixel_counts
    n_lit = lit.sum(axis=2)
    summed = np.where(lit, counts, 0.0).sum(axis=2)  # (K, n)
    on = n_lit > 0
    # pieces: runs of lit columns, numbered per draw
    starts = on & ~np.concatenate([np.zeros((samples, 1), bool), on[:, :-1]], axis=1)
    run = np.cumsum(starts, axis=1) + np.arange(samples)[:, None] * (n + 1)
    run = run[on]
    size = (samples * (n + 1),)
    pixels = np.bincount(run, weights=n_lit[on], minlength=size[0])
    total = np.bincount(run, weights=summed[on], minlength=size[0])
    moment = np.bincount(run, weights=(summed * i[None, :])[on], minlength=size[0])
    ok = (pixels >= logic.min_pixels) & (total >= logic.min_integrated_counts) & (total > 0)
    offset = np.full(size, np.inf)
    offset[ok] = np.abs(moment[ok] / total[ok]) * length / max(major, 1e-12)
    # the piece's own centroid sigma, as the solver's (starsense.detect.centroid.cog_sigma_px):
    # its box (columns along, the lit rows across and the line's drift) grown by the margin
    columns = np.bincount(run, minlength=size[0]).astype(float)
    across = np.zeros(size)
    np.maximum.at(across, run, n_lit[on].astype(float))
    w = columns + 2.0 * margin_px
    h = np.maximum(slope * (columns - 1.0), 0.0) + across + 2.0 * margin_px
    spread = 0.5 * (h * w * (w**2 - 1.0) + w * h * (h**2 - 1.0)) / 12.0
    n_piece = np.maximum(total / gain, 1.0)
    pixel_var = det.read_noise_e**2 + 1.0 / (12.0 * gain * gain)
    sigma = np.sqrt(s * s / n_piece + pixel_var * spread / n_piece**2)
    offset, sigma = offset.reshape(samples, n + 1), sigma.reshape(samples, n + 1)
    nearest = np.argmin(offset, axis=1)
    rows = np.arange(samples)
    # the solver pairs a detection at its own sigma only where no other is within its own
    # radius of the star (starsense.solve.rematch): two pieces of one streak refuse each other
    alone = (offset <= MATCH_SIGMAS * sigma).sum(axis=1) <= 1
    flux = total.reshape(samples, n + 1)
    per = np.histogram(np.log10(total[ok]), bins=FLUX_BINS)[0] / samples
    return (
        offset[rows, nearest],
        np.where(alone, sigma[rows, nearest], 0.0),
        flux[rows, nearest],
        per,
    )


@dataclass(frozen=True)
class Pieces:
    """Draws of each streak's nearest detection (:func:`piece_offsets_px`).

    Attributes
    ----------
    offsets_px : ndarray (N, samples)
        Its distance from the streak's middle, px; inf where no piece of the streak is a
        detection. 0 for a streak lit whole (its expected ridge ``WHOLE_RIDGE`` times the
        threshold or more) or a point.
    sigmas_px : ndarray (N, samples)
        Its centroid sigma per axis as the solver computes it (its pixels' count, box and summed
        counts), px, where the solver can pair it at that sigma: 0 where another piece lies
        within its own four sigma of the middle too (the pairing is ambiguous) and where the
        streak is lit whole (its own sigma applies).
    counts : ndarray (N, samples)
        Its lit pixels' summed counts (the detector's integrated counts).
    per_bin : ndarray (N, len(FLUX_BINS) - 1)
        The streak's mean number of detections per bin of log10 summed counts.
    """

    offsets_px: np.ndarray
    sigmas_px: np.ndarray
    counts: np.ndarray
    per_bin: np.ndarray


def piece_offsets_px(sensor, electrons, streaks_px, *, rng, samples: int = SAMPLES,
                     margin_px: int = 2) -> Pieces:  # fmt: skip
    """Draw where each streak's nearest detection is, its sigma and counts (module docstring).

    Parameters
    ----------
    sensor : Sensor
        The camera (PSF, gain, noise, detection logic).
    electrons : ndarray (N,)
        Each star's electrons over the exposure.
    streaks_px : ndarray (N, 2)
        Its streak, start to end, px.
    rng : numpy.random.Generator
    samples : int
        Draws per star.
    margin_px : int
        The detector's centroid window margin around a region's box, px.
    """
    n_e = np.asarray(electrons, dtype=float).reshape(-1)
    streak = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    length = np.hypot(streak[:, 0], streak[:, 1])
    offsets, sigmas = np.zeros((len(n_e), samples)), np.zeros((len(n_e), samples))
    # lit whole: one detection holding (nearly) all the light
    whole = np.maximum(n_e * sensor.detector.gain_counts_per_e, 1.0)
    counts = np.repeat(whole[:, None], samples, axis=1)
    per_bin = np.zeros((len(n_e), len(FLUX_BINS) - 1))
    at = np.clip(
        np.searchsorted(FLUX_BINS, np.log10(whole), side="right") - 1, 0, len(FLUX_BINS) - 2
    )
    per_bin[np.arange(len(n_e)), at] = 1.0
    ridge = ridge_counts(sensor, n_e, length) / float(sensor.detection.lit_pixel_counts)
    for k in np.flatnonzero((ridge < WHOLE_RIDGE) & (length > 0)):
        offsets[k], sigmas[k], counts[k], per_bin[k] = _one(
            sensor, float(n_e[k]), streak[k], rng, samples, margin_px
        )
    return Pieces(offsets, sigmas, counts, per_bin)
