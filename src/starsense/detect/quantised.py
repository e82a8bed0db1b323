"""Background statistics of coarsely quantised frames (8-bit, low bias, noise clipped at zero).

The mesh background of :mod:`starsense.detect.background` measures the noise as 1.4826 MAD.
When the noise is comparable to one quantisation step that fails: a dark 8-bit frame whose
background sits at 0-2 counts has a median absolute deviation of 0 or 1 count, whatever the
noise, and the noise clipped at zero is not even symmetric (a MAD of 0 made every non-zero pixel
a "star": ~20,000 detections per frame). Such frames are treated here.

1. **Step.** The quantisation step ``q`` is the greatest common divisor of the sampled values
   (12-bit data stored as 16-bit: 16; 8-bit: 1); float frames that take few distinct values
   (8-bit counts scaled, summed over a Bayer cell or weighted into a colour frame's luminance)
   have the spacing of those values; continuous float frames have none.
2. **Underlying Gaussian.** A quantised, zero-clipped Gaussian N(mu, s) has, at every bin edge
   e = k + q/2 of a value k, the exact cumulative fraction F(e) = Phi((e - mu) / s): rounding
   and clipping at zero both keep the mass below an edge below it. So the probits
   z = Phi^-1(F) of the empirical fractions lie on the line e = mu + s z; a weighted least-squares
   line through the edges with 0.001 < F < 0.999 (weights n phi(z)^2 / (F (1 - F)), the inverse
   variance of z) gives mu and s per box. Stars add a fraction of ~1e-3 to the top of a box and
   barely move the fractions near the median.
3. **Pixel statistics.** What a detection threshold needs is the mean and standard deviation of
   the *pixel values* (a matched filter sums pixels; the sum of a clipped, skewed distribution
   centres on its mean, not its median). They are the mean and standard deviation of the
   samples within ``median +- (5 s + q/2)``: the star pixels above are left out, the noise is
   kept.
4. **Floor.** A noiseless box (all samples equal) has no spread to fit; the noise is then the
   quantisation noise q / sqrt(12), never zero.

Frames clipped at a floor but not coarsely quantised (the luminance of a colour camera's
frame, whose three channels were each clipped at zero: many distinct values, a MAD of a
fraction of a count where the noise is several) are recognised by their point mass at the
floor (:func:`clip_floor`): a continuous noise never puts a percent of the samples on one
value. Their boxes are fitted the same way on the sample quantiles above the floor
(:func:`clipped_box_stats`): the q-quantile of a Gaussian clipped at the floor is
mu + s Phi^-1(q) wherever it lies above the floor.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

from starsense.detect.clip import robust_sigma

__all__ = [
    "CLIPPED_FRACTION",
    "QUANTISED_BELOW_STEPS",
    "STEP_SAMPLES_EVERY",
    "clip_floor",
    "clipped_box_stats",
    "clipped_gaussian_sigma",
    "clipped_sigma",
    "frame_quantisation_step",
    "quantisation_step",
    "quantised_box_stats",
]

#: a frame is treated as quantised when its MAD noise is below this many steps
QUANTISED_BELOW_STEPS = 3.0
#: a frame whose samples put at least this fraction on their least value is clipped there
#: (a Gaussian's least of 10^5 samples lies ~4.4 sigma below its mean, where one value holds
#: ~1e-5 of them even in steps of a third of the noise)
CLIPPED_FRACTION = 0.01
#: sample quantiles of the probit fit of clipped continuous data (above the floor's fraction)
_QUANTILES = 16
#: the highest quantile used (stars and hot pixels lie in the top ~0.1-1 % of a box)
_TOP_QUANTILE = 0.95
#: bin edges used each side of the median by the probit fit
_EDGES_EACH_SIDE = 12
#: fractions kept for the probit fit
_F_RANGE = (1e-3, 1.0 - 1e-3)


def quantisation_step(values: np.ndarray) -> float | None:
    """Return the quantisation step of discrete data, or None when there is none.

    Parameters
    ----------
    values : ndarray
        Sampled pixel values, counts (NaN ignored).

    Returns
    -------
    float or None
        Integer data: the greatest common divisor of the values' differences from their
        minimum (1 for 8-bit data, 16 for 12-bit data stored as 16-bit). Float data taking
        few distinct values (at most one sample in ten distinct: counts scaled, a Bayer cell's
        sum, the luminance of 8-bit colour): the spacing of their lattice when they lie on one
        (x = a + k q), else the median spacing of the distinct values between the 1st and 99th
        percentiles. None for continuous data or a constant frame.
    """
    v = np.asarray(values)
    if v.dtype.kind in "iu":  # integers: finite, on the unit lattice
        v = v.ravel()
        if v.size == 0:
            return None
    else:
        v = np.asarray(v, dtype=np.float64).ravel()
        v = v[np.isfinite(v)]
        if v.size == 0:
            return None
        if not np.all(v == np.round(v)):
            return _float_step(v)
    d = v.astype(np.int64)
    d -= d.min()
    d = d[d > 0]  # the gcd of all the differences is that of the distinct ones
    if d.size == 0:
        return None
    # the gcd of a prefix divides the whole one: 1 is final, and a prefix gcd that divides
    # every difference is the whole one (a modulus per value, not a gcd per value)
    g = int(np.gcd.reduce(d[:_GCD_PREFIX]))
    if g == 1 or not np.any(d % g):
        return float(g)
    return float(np.gcd.reduce(d))


#: differences whose gcd is taken first (quantisation_step)
_GCD_PREFIX = 256


def _float_step(v: np.ndarray) -> float | None:
    """Return the step of float samples taking few distinct values (quantisation_step)."""
    u = np.unique(v)
    if u.size < 2 or u.size > v.size // 10:
        return None
    lo, hi = np.percentile(v, [1.0, 99.0])
    central = u[(u >= lo) & (u <= hi)]
    if central.size < 2:
        central = u
    q = float(np.diff(central).min())
    k = (central - central[0]) / q
    if np.all(np.abs(k - np.round(k)) < 1e-3):  # a lattice: rounding errors of float32 only
        return q
    return float(np.median(np.diff(central)))


def clipped_gaussian_sigma(cells: np.ndarray, median: np.ndarray, step: float) -> np.ndarray:
    """Fit the Gaussian behind quantised, clipped samples: its sigma per box (probit line).

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        Samples of every box, counts; NaN for missing samples.
    median : ndarray, shape (...)
        Median of every box, counts.
    step : float
        Quantisation step ``q``, counts.

    Returns
    -------
    ndarray, shape (...)
        Sigma of the underlying Gaussian, counts; NaN where fewer than two bin edges have
        fractions inside (0.001, 0.999) (a noiseless box).
    """
    n = np.isfinite(cells).sum(axis=-1).astype(np.float64)
    base = np.round(median / step) * step
    offsets = (np.arange(-_EDGES_EACH_SIDE, _EDGES_EACH_SIDE) + 0.5) * step
    edges = base[..., None] + offsets  # (..., E)
    s = np.sort(cells, axis=-1)  # NaN last
    count = np.empty(edges.shape)
    flat_s = s.reshape(-1, s.shape[-1])
    flat_e = edges.reshape(-1, edges.shape[-1])
    for i in range(flat_s.shape[0]):  # searchsorted is per row; boxes are few (hundreds)
        count.reshape(-1, edges.shape[-1])[i] = np.searchsorted(flat_s[i], flat_e[i], "right")
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = count / n[..., None]
        use = (frac > _F_RANGE[0]) & (frac < _F_RANGE[1])
        z = ndtri(np.where(use, frac, 0.5))
        phi = np.exp(-0.5 * z**2) / np.sqrt(2 * np.pi)
        w = np.where(use, n[..., None] * phi**2 / (frac * (1 - frac)), 0.0)
        sw = w.sum(-1)
        zm = (w * z).sum(-1) / sw
        em = (w * edges).sum(-1) / sw
        szz = (w * (z - zm[..., None]) ** 2).sum(-1)
        sze = (w * (z - zm[..., None]) * (edges - em[..., None])).sum(-1)
        sigma = sze / szz
    ok = (use.sum(-1) >= 2) & np.isfinite(sigma) & (sigma > 0)
    return np.where(ok, sigma, np.nan)


def quantised_box_stats(cells, median, step):
    """Mean and standard deviation of the background pixels of every box (module steps 2-4).

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        Samples of every box, counts; NaN for missing samples.
    median : ndarray, shape (...)
        Median of every box, counts.
    step : float
        Quantisation step, counts.

    Returns
    -------
    mean, std : ndarray, shape (...)
        Mean and standard deviation of the samples within median +- (5 s + q/2), counts; the
        standard deviation is at least q / sqrt(12).
    keep : ndarray of bool, shape (..., samples)
        The samples used.
    """
    sigma = clipped_gaussian_sigma(cells, median, step)
    floor = step / np.sqrt(12.0)
    half = 5.0 * np.where(np.isfinite(sigma), np.maximum(sigma, floor), floor) + 0.5 * step
    with np.errstate(invalid="ignore"):
        keep = np.abs(cells - median[..., None]) <= half[..., None]
    k = keep.sum(-1)
    safe = np.where(keep, cells, 0.0).astype(np.float64)
    mean = safe.sum(-1) / np.maximum(k, 1)
    var = (np.where(keep, (cells - mean[..., None]) ** 2, 0.0)).sum(-1) / np.maximum(k - 1, 1)
    std = np.maximum(np.sqrt(var), floor)
    mean = np.where(k > 0, mean, np.nan)
    return mean, np.where(k > 0, std, np.nan), keep


def clip_floor(values: np.ndarray) -> float | None:
    """Return the value a frame's noise is clipped at (its least), or None if it is not.

    Parameters
    ----------
    values : ndarray
        Sampled pixel values, counts (NaN ignored).

    Returns
    -------
    float or None
        The least value when at least :data:`CLIPPED_FRACTION` of the samples equal it.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    least = float(v.min())
    return least if np.count_nonzero(v == least) >= CLIPPED_FRACTION * v.size else None


def _clipped_probit(s: np.ndarray, n: np.ndarray, floor: float) -> np.ndarray:
    """Sigma of the Gaussian behind each box's sorted samples ``s``, clipped at ``floor``.

    The q-quantile of the samples is mu + sigma Phi^-1(q) for every q above the fraction at
    the floor: a weighted least-squares line through :data:`_QUANTILES` quantiles between that
    fraction (plus 2 %) and :data:`_TOP_QUANTILE`, weights phi(z)^2 / (q (1 - q)) (the inverse
    variance of a sample quantile, in sigma units). NaN where fewer than a fifth of the samples
    lie above the floor.
    """
    at_floor = (s <= floor).sum(-1) / np.maximum(n, 1)
    lo = np.minimum(at_floor + 0.02, _TOP_QUANTILE)
    t = np.linspace(0.0, 1.0, _QUANTILES)
    q = lo[..., None] + (_TOP_QUANTILE - lo[..., None]) * t  # (..., Q)
    rank = np.clip(np.floor(q * n[..., None]).astype(np.int64), 0, s.shape[-1] - 1)
    x = np.take_along_axis(s, rank, axis=-1)
    z = ndtri(q)
    phi = np.exp(-0.5 * z**2)
    w = phi**2 / (q * (1.0 - q))
    sw = w.sum(-1)
    zm = (w * z).sum(-1) / sw
    xm = (w * x).sum(-1) / sw
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = (w * (z - zm[..., None]) * (x - xm[..., None])).sum(-1) / (
            w * (z - zm[..., None]) ** 2
        ).sum(-1)
    ok = (at_floor <= _TOP_QUANTILE - 0.15) & np.isfinite(sigma) & (sigma > 0)
    return np.where(ok, sigma, np.nan)


def clipped_sigma(cells: np.ndarray, floor: float) -> np.ndarray:
    """Sigma of the Gaussian behind each box's samples clipped at ``floor``, counts.

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        Samples of every box, counts; NaN for missing samples.
    floor : float
        The clipping floor (:func:`clip_floor`), counts.

    Returns
    -------
    ndarray, shape (...)
        The probit line's sigma through the quantiles above the floor; NaN where fewer than a
        fifth of a box's samples lie above it.
    """
    n = np.isfinite(cells).sum(axis=-1)
    return _clipped_probit(np.sort(cells, axis=-1), n, floor)


def clipped_box_stats(cells, median, floor: float):
    """Mean and standard deviation of the background pixels of boxes clipped at ``floor``.

    The clipped counterpart of :func:`quantised_box_stats` for data that are not coarsely
    quantised: the underlying Gaussian's sigma from the quantiles above the floor
    (:func:`_clipped_probit`), then the mean and standard deviation of the samples below
    median + 5 sigma (what a matched filter sums: the clipped values, floor included). A box
    too clipped to fit takes the median sigma of the boxes that fit.

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        Samples of every box, counts; NaN for missing samples.
    median : ndarray, shape (...)
        Median of every box, counts.
    floor : float
        The clipping floor (:func:`clip_floor`), counts.

    Returns
    -------
    mean, std : ndarray, shape (...)
        Mean and standard deviation of the samples kept, counts (NaN where none).
    keep : ndarray of bool, shape (..., samples)
        The samples used.
    """
    sigma = clipped_sigma(cells, floor)
    fitted = np.isfinite(sigma)
    if not fitted.any():
        sigma = np.full(sigma.shape, float(np.nanmax(np.nanstd(cells, axis=-1))))
    else:
        sigma = np.where(fitted, sigma, np.median(sigma[fitted]))
    with np.errstate(invalid="ignore"):
        keep = cells <= (median + 5.0 * sigma)[..., None]
    k = keep.sum(-1)
    safe = np.where(keep, cells, 0.0).astype(np.float64)
    mean = safe.sum(-1) / np.maximum(k, 1)
    var = (np.where(keep, (cells - mean[..., None]) ** 2, 0.0)).sum(-1) / np.maximum(k - 1, 1)
    return np.where(k > 0, mean, np.nan), np.where(k > 1, np.sqrt(var), np.nan), keep


#: the quantisation step is judged on every this-many-th sample of each box
STEP_SAMPLES_EVERY = 7


def frame_quantisation_step(sampled: np.ndarray, keep: np.ndarray, counts=None) -> float | None:
    """Return the quantisation step when the frame's noise is below a few steps, else None.

    The noise is the MAD's, or where the samples are clipped at a floor (:func:`clip_floor`)
    and the MAD reads below a few steps, the sigma of the Gaussian behind the clip: the
    luminance of clipped colour channels lies on a lattice of a thousandth of a count, with a
    MAD of 0 where half the pixels are 0, and a noise of counts. ``sampled`` is every
    :data:`STEP_SAMPLES_EVERY`-th sample of each box, ``keep`` which of
    them the clipping kept; ``counts`` the same samples of every box as integers, if any.
    """
    ints = None if counts is None else counts[:, :, ::STEP_SAMPLES_EVERY]
    step = quantisation_step(sampled if ints is None else ints)
    if step is None:
        return None
    noise = np.nanmedian(robust_sigma(sampled, keep))
    if not noise >= QUANTISED_BELOW_STEPS * step:
        floor = clip_floor(sampled)
        fitted = np.zeros(0) if floor is None else clipped_sigma(sampled, floor)
        fitted = fitted[np.isfinite(fitted)]
        if fitted.size:  # clipped: the MAD reads low, the Gaussian behind the clip does not
            noise = np.median(fitted)
    return step if not noise >= QUANTISED_BELOW_STEPS * step else None
