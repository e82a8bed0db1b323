"""A fast read-out of a whole frame with the statistics of apply_noise, for Monte Carlo runs.

:func:`~starsense.render.noise.apply_noise` draws a float32 standard normal per pixel (the read
noise: ~45 ms of CPU for the 5 Mpixel of an ST-16 frame, most of the render) and a Poisson
count for every pixel a star touches (~300,000 of them, most with a mean far below one
electron). :func:`fast_read_out` draws the same distributions to within stated bounds, in one
compiled pass (``_renderc.c``):

* **Read noise.** A standard normal per pixel by inversion of 32 random bits ``u`` of the
  generator (``bit_generator.random_raw``: two pixels per 64-bit draw; :func:`normal_draws`):
  the top 12 bits pick one of 4096 equally likely bins, the low 20 a point
  ``(f + 1/2) / 2^20`` of the way across it on the line between the bin's edge quantiles (a
  64 KB table: the draw costs a cached load, where numpy's ziggurat costs as much as the rest
  of the read-out); the two outermost bins (beyond 3.49 sigma, where detection thresholds
  lie) take the exact quantile at ``(u + 1/2) / 2^32`` (Acklam's rational approximation,
  relative error < 1.15e-9: :func:`normal_quantiles`). The drawn distribution's CDF differs
  from the normal's by less than 2e-5 anywhere (the linear pieces inside the bins; the worst
  bin is the outermost linear one, at 3.3-3.5 sigma), by < 1e-9 beyond 3.49 sigma, and it
  reaches 6.34 sigma (a normal goes further with probability 1e-10 per pixel).
* **Shot noise.** A pixel whose mean charge ``lambda`` (star + dark, electrons) is at least
  ``cut = SKEW_LIMIT x sigma_r^3`` gets a Poisson draw, as in :func:`apply_noise`. Below it the
  charge is folded into the read noise: ``lambda + sqrt(sigma_r^2 + lambda) z``, a normal of
  the same mean and variance as Poisson(lambda) + N(0, sigma_r^2). The two differ only from the
  third cumulant on: the skewness of the true sum, ``lambda / (sigma_r^2 + lambda)^1.5``, is
  below ``SKEW_LIMIT`` = 0.02 there (0.86 e- for the ST-16's 3.5 e- read noise: the faint wings
  of stars, whose tails far beyond any detection threshold are the only thing changed). Pixels
  with no star light but dark charge are folded the same way (``dark < cut``).
* Gain, bias, rounding to the nearest count, clipping to the ADC range: as
  :func:`apply_noise` (which rounds a tie to even; a tie has probability 0 here).

It applies to detectors of at most 16 bits without PRNU, DSNU or hot pixels, dark charge below
``cut``, read noise > 0, and needs the compiled kernel: otherwise :func:`fast_read_out` returns
None (the caller uses :func:`apply_noise`). Random draws differ from :func:`apply_noise`'s (a
frame is not the same frame for the same seed), the statistics do not
(tests/render/test_readout.py).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.special import ndtri

from starsense._validate import as_generator

try:  # the compiled kernel (setup.py builds it where a C compiler exists)
    import starsense.render._renderc as _renderc
except ImportError:  # pragma: no cover - exercised on machines without a compiler
    _renderc = None

__all__ = ["SKEW_LIMIT", "add_stamps", "fast_read_out", "normal_draws", "normal_quantiles"]

#: Largest skewness of a pixel's read-out distribution that the normal fold may ignore.
SKEW_LIMIT = 0.02


@functools.cache
def _bins() -> np.ndarray:
    """Return the 4096 bins of the read noise: lower edge quantile and width / 2^20 (4096, 2)."""
    q = ndtri(np.arange(4097) / 4096.0)
    table = np.zeros((4096, 2))
    table[1:-1, 0] = q[1:-2]
    table[1:-1, 1] = np.diff(q[1:-1]) / 2.0**20
    return table


def normal_draws(u: np.ndarray) -> np.ndarray | None:
    """Return the read-out's standard normal draws from 32-bit integers ``u`` (float64).

    The module docstring's table inversion; None where the kernel is not built.

    Parameters
    ----------
    u : ndarray of uint32, shape (N,)
        Random bits.
    """
    if _renderc is None:
        return None
    u = np.ascontiguousarray(u, dtype=np.uint32)
    out = np.empty(len(u))
    _renderc.normal_draws(u, len(u), _bins(), out)
    return out


def normal_quantiles(u: np.ndarray) -> np.ndarray | None:
    """Return the normal quantiles the read-out draws from 32-bit integers ``u`` (float64).

    ``Phi^-1((u + 1/2) / 2^32)`` by Acklam's rational approximation (relative error
    < 1.15e-9), the upper half from the lower by symmetry; None where the kernel is not built.

    Parameters
    ----------
    u : ndarray of uint32, shape (N,)
        Random bits.
    """
    if _renderc is None:
        return None
    u = np.ascontiguousarray(u, dtype=np.uint32)
    out = np.empty(len(u))
    _renderc.normal_quantiles(u, len(u), out)
    return out


def add_stamps(image: np.ndarray, flat: np.ndarray, values: np.ndarray) -> bool:
    """Add ``values`` to the float32 ``image`` at flat indices ``flat``, in order.

    Each sum is formed in float64 and stored as float32, element by element: what
    ``np.add.at(image.reshape(-1), flat, values)`` does, bit for bit. Returns False (nothing
    done) where the compiled kernel is not built.

    Parameters
    ----------
    image : ndarray of float32, C-contiguous
    flat : ndarray of int64, shape (K,)
    values : ndarray of float64, shape (K,)
    """
    if _renderc is None or image.dtype != np.float32 or not image.flags.c_contiguous:
        return False
    _renderc.add_stamps(
        image,
        image.size,
        np.ascontiguousarray(flat, dtype=np.int64),
        np.ascontiguousarray(values, dtype=float),
        len(flat),
    )
    return True


def fast_read_out(expected_e, sensor, *, rng=None, exposure_s: float | None = None):
    """Noisy counts from expected electrons, the statistics of :func:`apply_noise` (docstring).

    Parameters
    ----------
    expected_e : ndarray of float32
        Expected photo-electrons per pixel (star light), finite and >= 0.
    sensor : Sensor
    rng : None, int or numpy.random.Generator
    exposure_s : float, optional
        Integration time for the dark charge, s (default ``sensor.exposure_s``).

    Returns
    -------
    ndarray of uint16, same shape, or None
        None where the fast read-out does not apply (module docstring).
    """
    det = sensor.detector
    e = np.asarray(expected_e)
    if (
        _renderc is None
        or e.dtype != np.float32
        or det.bit_depth > 16
        or det.read_noise_e <= 0
        or det.prnu_fraction > 0
        or det.dsnu_e > 0
        or det.hot_pixel_fraction > 0
    ):
        return None
    dark = det.dark_current_e_s * sensor.exposure_or(exposure_s)
    cut = min(SKEW_LIMIT * det.read_noise_e**3, det.full_well_e)
    if dark >= cut:
        return None
    e = np.ascontiguousarray(e)
    flat = e.reshape(-1)
    low = flat.min() if flat.size else 0.0
    pidx = np.flatnonzero(flat >= cut - dark).astype(np.int64)
    lam = flat[pidx].astype(float) + dark
    if not (np.isfinite(low) and low >= 0 and np.isfinite(lam).all()):
        return None  # NaN, inf or negative electrons: apply_noise names the bad value
    gen, _ = as_generator(rng)
    pois = gen.poisson(lam).astype(np.int64)
    raw = gen.bit_generator.random_raw((flat.size + 1) // 2)
    out = np.empty(e.shape, np.uint16)
    _renderc.read_out(
        flat,
        flat.size,
        raw,
        _bins(),
        pois,
        pidx,
        len(pidx),
        float(dark),
        float(det.read_noise_e),
        float(det.gain_counts_per_e),
        float(det.bias_counts),
        float(det.saturation_counts),
        float(det.full_well_e),
        out,
    )
    return out
