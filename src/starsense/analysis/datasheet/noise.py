"""Centroid noise of one star on the detector: the windowed centre of gravity and its bound.

The tracker's centroider (:class:`starsense.detect.threshold.StarDetector`, ``centroid="cog"``)
takes the pixels lit above the detection threshold, widens their bounding box by a margin and
returns the centre of gravity of the bias-subtracted window. Its noise is modelled here from
the sensor alone (no rendering):

* the expected counts of each pixel: the PSF (a Gaussian of ``psf_sigma_px``, integrated over
  the pixel) times the star's photo-electrons, plus dark signal, times the gain, plus the bias;
* each pixel's variance: shot noise of star and dark signal, read noise, and the ADC's
  quantisation (1/12 count^2), with the clipping at 0 and at the ADC's top count applied
  exactly (the moments of a Gaussian clipped to [0, 2^bits - 1]);
* the lit window from the *expected* image (bounding box of the pixels above
  ``lit_pixel_counts``, widened by the margin), and the centre of gravity linearised in the
  pixel values: var(x_c) = sum_i (x_i - x_c)^2 var_i / S^2 (S: the window's expected sum).

Averaged over the star's sub-pixel position. Beside it, the Cramer-Rao bound of a pixelated
Gaussian PSF with the same pixel noise (unbiased estimators, no clipping): I_x = sum_i
(d mu_i / d x)^2 / var_i. Both are per axis, in pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from starsense._validate import as_generator
from starsense.detect.centroid import cog_sigma_px
from starsense.detect.threshold import StarDetector
from starsense.render.noise import apply_noise
from starsense.render.psf import pixel_profile

__all__ = ["CentroidNoise", "centroid_noise", "clipped_moments", "empty_pixel_sigma_counts"]

_SQRT2PI = math.sqrt(2.0 * math.pi)
#: noisy renders per sub-pixel phase (the scatter about the phase's mean is the noise)
_REPEATS = 4


def clipped_moments(mu, sigma, *, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the mean and variance of ``clip(X, lo, hi)`` for X ~ N(mu, sigma^2).

    Parameters
    ----------
    mu, sigma : array_like
        Mean and standard deviation of X (sigma > 0).
    lo, hi : float
        Clip limits, ``lo < hi`` (``hi`` may be inf).

    Returns
    -------
    mean, var : ndarray
        Same shape as the broadcast of ``mu`` and ``sigma``.
    """
    mu = np.asarray(mu, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    a = (lo - mu) / sigma
    b = (hi - mu) / sigma
    pa, pb = ndtr(a), ndtr(b)
    da = np.exp(-0.5 * a * a) / _SQRT2PI
    db = np.exp(-0.5 * np.where(np.isfinite(b), b, 0.0) ** 2) / _SQRT2PI
    db = np.where(np.isfinite(b), db, 0.0)
    mid = pb - pa
    hi_f = np.where(np.isfinite(b), hi, 0.0)
    top = hi_f * (1.0 - pb)
    top2 = hi_f * hi_f * (1.0 - pb)
    mean = lo * pa + top + mu * mid + sigma * (da - db)
    second = (
        lo * lo * pa
        + top2
        + (mu * mu + sigma * sigma) * mid
        + sigma * ((lo + mu) * da - (hi_f + mu) * db)
    )
    return mean, np.maximum(second - mean * mean, 0.0)


@dataclass(frozen=True)
class CentroidNoise:
    """Centroid noise and bias of a star against its photo-electrons (one axis, pixels).

    Attributes
    ----------
    electrons : ndarray (K,)
        Photo-electrons of the star (the lookup grid).
    sigma_px : ndarray (K,)
        1-sigma noise of the windowed centre of gravity about its mean at each sub-pixel
        position, rms over positions (measured on noisy single-star renders, see
        :func:`centroid_noise`).
    crb_px : ndarray (K,)
        Cramer-Rao bound of a pixelated Gaussian PSF with the same pixel noise.
    bias_rms_px, bias_max_px : ndarray (K,)
        The centroider's deterministic error against sub-pixel position (pixel spatial error of
        this model), rms and largest, from the expected image.
    window_px : ndarray (K,)
        Mean side of the centroid window, pixels.
    window_model_px : ndarray (K,)
        The CoG noise of the linearised model (the window of the expected image, clipped pixel
        moments), for comparison: it misses the window's own noise, which matters for faint
        stars.
    noisy_bias_px : ndarray (K,)
        The mean error against sub-pixel position on the noisy renders, rms over positions:
        the pixel spatial error as frames meet it (the lit window moves with the noise).
    solver_sigma_px : ndarray (K,)
        The noise the solver assumes for such a star (its Wahba weight ``1 / sigma^2``,
        :func:`starsense.detect.centroid.cog_sigma_px`), averaged as a weight.
    """

    electrons: np.ndarray
    sigma_px: np.ndarray
    crb_px: np.ndarray
    bias_rms_px: np.ndarray
    bias_max_px: np.ndarray
    window_px: np.ndarray
    window_model_px: np.ndarray
    noisy_bias_px: np.ndarray
    solver_sigma_px: np.ndarray

    def _interp(self, values: np.ndarray, electrons) -> np.ndarray:
        e = np.clip(np.asarray(electrons, dtype=float), self.electrons[0], self.electrons[-1])
        ok = np.isfinite(values)
        if not ok.any():
            return np.full(np.shape(e), np.nan)
        grid, vals = self.electrons[ok], values[ok]
        out = np.exp(np.interp(np.log(e), np.log(grid), np.log(vals)))
        # below the faintest star detected in half the renders: read-noise limited, ~ 1 / N_e
        return np.where(e < grid[0], vals[0] * grid[0] / e, out)

    def sigma(self, electrons) -> np.ndarray:
        """Return the centroid noise (px) of stars of ``electrons`` (log-log interpolation)."""
        return self._interp(self.sigma_px, electrons)

    def bias(self, electrons) -> np.ndarray:
        """Return the pixel spatial error (px rms) of stars of ``electrons`` on noisy frames.

        A table without any bias (the forward model's fit, whose model integrates the PSF over
        the pixels) gives exactly 0, not the 1e-6 px floor of the log interpolation.
        """
        if not np.any(self.noisy_bias_px > 0):
            return np.zeros(np.shape(electrons))
        return self._interp(np.maximum(self.noisy_bias_px, 1e-6), electrons)

    def solver_sigma(self, electrons) -> np.ndarray:
        """Return the noise (px) the solver assumes for stars of ``electrons`` (its weights)."""
        return self._interp(self.solver_sigma_px, electrons)

    def crb(self, electrons) -> np.ndarray:
        """Return the Cramer-Rao bound (px) of stars of ``electrons``."""
        return self._interp(self.crb_px, electrons)


def _profile(centres: np.ndarray, offset: float, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-integrated 1-d Gaussian (the renderer's) and its derivative in the star position.

    ``centres`` are consecutive integers; the profile is :func:`starsense.render.psf.
    pixel_profile`, the one the frames are rendered with.
    """
    c0 = int(centres[0])
    p = pixel_profile(c0, c0 + len(centres), offset, sigma_px=sigma)[0]
    lo = (centres - 0.5 - offset) / sigma
    hi = (centres + 0.5 - offset) / sigma
    dp = (np.exp(-0.5 * lo * lo) - np.exp(-0.5 * hi * hi)) / (_SQRT2PI * sigma)
    return p, dp


def _one(n_e: float, phase: tuple[float, float], sensor, margin_px: int) -> tuple:
    """Centroid variance, CRB information, bias (x, y) and window side of one star, one phase."""
    det, logic = sensor.detector, sensor.detection
    g = det.gain_counts_per_e
    sig = det.psf_sigma_px
    dark_e = det.dark_current_e_s * sensor.exposure_s
    peak = n_e * (math.erf(0.5 / (math.sqrt(2) * sig)) ** 2) * g
    reach = sig * math.sqrt(2.0 * math.log(max(peak / max(logic.lit_pixel_counts, 1e-9), 1.0)))
    half = math.ceil(reach + 4.0 * sig) + margin_px + 2
    c = np.arange(-half, half + 1, dtype=float)
    px, _ = _profile(c, phase[0], sig)
    py, dpy = _profile(c, phase[1], sig)
    p = py[:, None] * px[None, :]
    star_e = n_e * p
    var_e = star_e + dark_e + det.read_noise_e**2
    mu_c = g * (star_e + dark_e) + det.bias_counts
    sd_c = np.sqrt(g * g * var_e + 1.0 / 12.0)
    mean_c, var_c = clipped_moments(mu_c, sd_c, lo=0.0, hi=float(det.saturation_counts))
    sub = mean_c - det.bias_counts
    lit = sub > logic.lit_pixel_counts
    info = float(np.sum((n_e * dpy[:, None] * px[None, :]) ** 2 / (var_e + 1.0 / (12 * g * g))))
    if not lit.any():
        return math.nan, info, math.nan, math.nan, math.nan
    rows = np.flatnonzero(lit.any(axis=1))
    cols = np.flatnonzero(lit.any(axis=0))
    r0, r1 = max(rows[0] - margin_px, 0), min(rows[-1] + margin_px + 1, len(c))
    c0, c1 = max(cols[0] - margin_px, 0), min(cols[-1] + margin_px + 1, len(c))
    w = sub[r0:r1, c0:c1]
    v = var_c[r0:r1, c0:c1]
    xs, ys = c[c0:c1][None, :], c[r0:r1][:, None]
    s = w.sum()
    xc, yc = (w * xs).sum() / s, (w * ys).sum() / s
    var_x = (v * (xs - xc) ** 2).sum() / s**2
    var_y = (v * (ys - yc) ** 2).sum() / s**2
    side = 0.5 * ((r1 - r0) + (c1 - c0))
    return 0.5 * (var_x + var_y), info, xc - phase[0], yc - phase[1], side


def _measured(sensor, span: tuple[float, float], rng, n_stamps: int) -> tuple:
    """Centroid noise, bias and the solver's own sigma (px, per axis) on noisy single-star renders.

    The star is put at ``n_stamps / 4`` random sub-pixel phases (uniform over the pixel: the
    bias of an undersampled or saturated star changes sharply with the phase, which a coarse
    grid misses) and brightnesses (log-uniform over ``span``, the table point's cell: the bias
    of a saturated star changes as sharply with its brightness, and the catalogue's stars
    fill the cell), each rendered 4 times with fresh noise and detected by the tracker's
    detector. The noise is the scatter about each phase's mean centroid (the deterministic
    error of the phase removed, with the ``n / (n - 1)`` of an estimated mean): a frame meets
    every star at a random phase, so the phase's bias is a separate error (the pixel spatial
    error), not noise. The bias is the rms of the phases' mean errors (less the noise of the
    means). The solver's sigma is what the solver assumes for these detections
    (:func:`starsense.detect.centroid.cog_sigma_px`, its Wahba weights ``1 / sigma^2``):
    ``1 / sqrt(mean(1 / sigma^2))``.

    The stamps are laid side by side in one strip, separated by ``margin + 1`` columns at the
    known background (no signal, no noise), and detected in one call: with the detector's
    constant background no lit region or centroid window crosses a gap, so each stamp's
    detections are those of the stamp alone. NaNs when the star is detected in fewer than half
    the renders.
    """
    det = sensor.detector
    half = 6 + math.ceil(6.0 * det.psf_sigma_px)
    size = 2 * half + 1
    n_phases = max(n_stamps // _REPEATS, 2)
    phase = np.repeat(np.arange(n_phases), _REPEATS)
    xy = half + (rng.random((n_phases, 2)) - 0.5)[phase]
    # each phase's brightness drawn log-uniformly over the table point's cell
    n_e = np.exp(rng.uniform(math.log(span[0]), math.log(span[1]), n_phases))[phase]
    box = (0, size, 0, size)
    # gaussian_stamp's n_e * outer(P_y, P_x) for every stamp at once (the same numbers)
    p_x = pixel_profile(box[2], box[3], xy[:, 0], sigma_px=det.psf_sigma_px)
    p_y = pixel_profile(box[0], box[1], xy[:, 1], sigma_px=det.psf_sigma_px)
    stack = np.asarray(n_e, dtype=float)[:, None, None] * (p_y[:, :, None] * p_x[:, None, :])
    counts = apply_noise(stack, sensor, rng=rng)
    finder = StarDetector.for_sensor(sensor)
    n = len(xy)
    pitch = size + finder.margin_px + 1
    strip = np.full((size, pitch * n), det.bias_counts, dtype=np.float64)
    view = strip.reshape(size, n, pitch)
    view[:, :, :size] = np.moveaxis(counts, 0, 1)
    found = finder(strip)
    stamp = (found.x // pitch).astype(int) if len(found) else np.empty(0, int)
    # detections come brightest first: the first of each stamp is its brightest
    first = np.unique(stamp, return_index=True)[1] if len(stamp) else np.empty(0, int)
    if len(first) < n // 2:  # detected in fewer than half the renders
        return math.nan, math.nan, math.nan
    k = stamp[first]
    err = np.column_stack([found.x[first] - k * pitch - xy[k, 0], found.y[first] - xy[k, 1]])
    ph = phase[k]
    n_ph = np.bincount(ph, minlength=n_phases)
    seen = n_ph >= 2
    means = np.stack([np.bincount(ph, err[:, a], n_phases) for a in (0, 1)], 1)
    means = means / np.maximum(n_ph, 1)[:, None]
    dev = err - means[ph]
    use = seen[ph]
    dof = float(np.sum(n_ph[seen] - 1))
    noise2 = float(np.sum(dev[use] ** 2)) / (2.0 * dof)
    bias2 = float(np.mean(means[seen] ** 2 - noise2 / n_ph[seen][:, None]))
    solver = cog_sigma_px(found, first, detector=det, margin_px=finder.margin_px)
    return math.sqrt(noise2), math.sqrt(max(bias2, 0.0)), float(np.mean(solver**-2.0) ** -0.5)


#: table points past the onset of saturation, in units of the onset's electrons
_SATURATION_STEPS = (1.0, 1.15, 1.3, 1.5, 1.75, 2.0, 2.5, 3.0)


def _saturation_points(sensor, lo: float, hi: float) -> np.ndarray:
    """Electrons at which a star's brightest pixel reaches saturation, and a few steps past.

    Saturation is the full well or the ADC's top count, whichever comes first; a star centred
    on a pixel puts ``erf(1 / (2 sqrt2 sigma))^2`` of its light in it.
    """
    det = sensor.detector
    sat_e = det.clip_e
    peak = math.erf(0.5 / (math.sqrt(2.0) * det.psf_sigma_px)) ** 2
    points = sat_e / peak * np.asarray(_SATURATION_STEPS)
    return points[(points > lo) & (points < hi)]


def centroid_noise(
    sensor,
    electrons_min: float,
    electrons_max: float,
    *,
    margin_px: int = 2,
    n_grid: int = 16,
    n_phase: int = 4,
    n_stamps: int = 200,
    rng: int | np.random.Generator | None = 0,
) -> CentroidNoise:
    """Tabulate the centroid noise of the sensor's centroider against photo-electrons.

    The noise is measured on ``n_stamps`` noisy renders of a single star per table point
    (random sub-pixel phases, :func:`_measured`) through the tracker's own detector (the
    noise model of :mod:`starsense.render.noise`: shot, dark, read noise, gain, quantisation
    and clipping): the lit window then moves with the noise, which the linearised window
    model of :func:`_one` (kept for the bias and the window size) misses for faint stars.
    The Cramer-Rao bound is analytic.

    Parameters
    ----------
    sensor : Sensor
        Detector, PSF, exposure and detection logic.
    electrons_min, electrons_max : float
        Range of the table, photo-electrons (> 0).
    margin_px : int
        Window margin around the lit pixels (the detector's, default 2).
    n_grid : int
        Table points, log-spaced; beside them, points where the brightest pixel starts to
        saturate (the bias of a clipped star rises steeply there, :func:`_saturation_points`).
    n_phase : int
        Sub-pixel positions per axis of the analytic terms (``n_phase^2`` in all).
    n_stamps : int
        Noisy renders per table point.
    rng : None, int or numpy.random.Generator
        Randomness of the renders (an int: its seed).

    Returns
    -------
    CentroidNoise
        Stars detected in fewer than half of the renders get NaN noise.
    """
    lo = max(float(electrons_min), 1.0)
    hi = max(float(electrons_max), 2.0 * lo)
    grid = np.union1d(np.geomspace(lo, hi, int(n_grid)), _saturation_points(sensor, lo, hi))
    offsets = (np.arange(n_phase) + 0.5) / n_phase - 0.5
    phases = [(float(a), float(b)) for a in offsets for b in offsets]
    rng, _ = as_generator(rng)
    out = np.empty((len(grid), 8))
    # each point's cell, symmetric in log: half the step to its nearer neighbour either side
    step = np.diff(np.log(grid))
    half = 0.5 * np.minimum(np.r_[step, np.inf], np.r_[np.inf, step])
    half = np.where(np.isfinite(half), half, 0.0)
    cells = grid[:, None] * np.exp(np.column_stack([-half, half]))
    for k, n_e in enumerate(grid):
        res = np.array([_one(float(n_e), ph, sensor, margin_px) for ph in phases])
        var, info, bx, by, side = res.T
        bias = np.concatenate([bx, by])
        noise, noisy_bias, solver = _measured(sensor, tuple(cells[k]), rng, n_stamps)
        out[k] = (
            noise,
            math.sqrt(np.mean(1.0 / info)),
            math.sqrt(np.mean(bias**2)),
            np.max(np.abs(bias)),
            np.mean(side),
            math.sqrt(np.mean(var)),
            noisy_bias,
            solver,
        )
    return CentroidNoise(grid, *out.T)


def empty_pixel_sigma_counts(sensor) -> float:
    """Return the noise of a pixel without a star, counts rms.

    Read noise and the shot noise of the dark current over the exposure (electrons) times the
    gain, and the ADC's quantisation (1 / sqrt(12) counts), in quadrature.

    Parameters
    ----------
    sensor : Sensor

    Returns
    -------
    float
        counts rms.
    """
    det = sensor.detector
    electrons2 = det.read_noise_e**2 + det.dark_current_e_s * sensor.exposure_s
    return math.sqrt((det.gain_counts_per_e**2) * electrons2 + 1.0 / 12.0)
