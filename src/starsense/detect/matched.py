"""Matched filtering of a background-subtracted frame: detect stars, not noise spikes.

A star spreads its light over a PSF; a noise spike, a hot pixel or a cosmic ray sits on one
pixel. Correlating the frame with the PSF (a Gaussian of the PSF's sigma, normalised to unit
sum) is the matched filter for a point source in white noise: it maximises the signal-to-noise
ratio of the peak, by sqrt(4 pi) sigma_psf over a single pixel (3.5 for sigma = 1 px), while a
one-pixel spike is spread to 1 / (2 pi sigma^2) of its height (16 % at 1 px). Thresholds are
then set in units of the noise of the *filtered* frame.

The noise of the filtered frame is measured, not assumed: for white noise it is the pixel noise
times sqrt(sum k^2) = 1 / (2 sqrt(pi) sigma), but JPEG compression, demosaicing and binning
correlate neighbouring pixels and make it larger. It is taken as 1.4826 MAD of the filtered
frame over the pixel noise map (on a subsample of pixels, where stars are a negligible
fraction), and never below the white-noise value.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

from starsense._workspace import scratch
from starsense.detect.clip import MAD_TO_SIGMA

try:
    import starsense.detect._framec as _framec
except ImportError:  # built without a C compiler: the NumPy forms below
    _framec = None

__all__ = [
    "LOCAL_BOX_PX",
    "NOISE_STEP",
    "box_mean_at_peaks",
    "filtered_noise_ratio",
    "gaussian_correlate",
    "local_noise_ratio",
    "matched_filter",
]

#: the kernel is cut at this many sigma
_TRUNCATE = 3.0
#: the filtered noise is measured on every this-many-th pixel each way (87,000 of 768 x 1024:
#: the MAD's relative scatter is ~0.4 %)
NOISE_STEP = 3


def gaussian_correlate(
    frame: np.ndarray,
    sigma_px: float,
    *,
    truncate: float = _TRUNCATE,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Correlate a frame with the unit-sum Gaussian of ``sigma_px``, in float32.

    The same sampled, truncated and normalised kernel as ``scipy.ndimage.gaussian_filter``
    (radius ``int(truncate sigma + 0.5)``, edge pixels repeated beyond the frame, "nearest"),
    applied separably by rows then columns as float32 array operations on bands of rows (each
    band's work arrays stay in the cache), pairing the symmetric taps. scipy filters the
    columns one at a time, which strides across the frame: on a 768 x 1024 frame this is ~4x
    faster, and equal to within float32 rounding.

    Parameters
    ----------
    frame : ndarray, shape (rows, columns)
        Image, any real dtype (computed in float32).
    sigma_px : float
        Gaussian sigma, pixels (> 0).
    truncate : float
        The kernel is cut at this many sigma.
    out : ndarray, shape (rows, columns), float32, optional
        Where to write the result (a new array by default).

    Returns
    -------
    ndarray, shape (rows, columns), float32
        ``out`` when given.
    """
    a = np.asarray(frame, dtype=np.float32)
    radius = int(truncate * float(sigma_px) + 0.5)
    taps = np.exp(-0.5 * (np.arange(radius + 1) / float(sigma_px)) ** 2)
    taps = (taps / (2.0 * taps.sum() - taps[0])).astype(np.float32)
    rows, cols = a.shape
    out = np.empty((rows, cols), np.float32) if out is None else out
    if radius == 0:
        out[...] = a
        return out
    if _framec is not None and out.dtype == np.float32 and out.flags.c_contiguous:
        # the compiled form of _band's passes, whole frame (_framec.c): the same float32
        # operations in the same order, so the same values
        _framec.correlate(np.ascontiguousarray(a), rows, cols, taps, radius, out)
        return out
    # bands of rows, so that a band's three work arrays stay in the cache between the passes
    band = max(16, _BAND_FLOATS // cols)
    r = radius
    padded = scratch("gauss_padded", (band + 2 * r, cols + 2 * r))
    across = scratch("gauss_across", (band + 2 * r, cols))
    pair = scratch("gauss_pair", (band + 2 * r, cols))
    for r0 in range(0, rows, band):
        r1 = min(r0 + band, rows)
        _band(a, r0, r1, r, taps, padded, across, pair, out)
    return out


#: floats per work array of one band of :func:`gaussian_correlate` (512 kB: 128 rows of 1024)
_BAND_FLOATS = 131072


def _band(a, r0, r1, r, taps, padded, across, pair, out) -> None:
    """Rows ``r0:r1`` of the separable correlation, edge pixels repeated ("nearest")."""
    rows, cols = a.shape
    n = r1 - r0
    m = n + 2 * r
    # the band's rows and r more each side (edge rows repeated), columns padded by r each side
    lo, hi = max(r0 - r, 0), min(r1 + r, rows)
    p = padded[:m]
    top = lo - (r0 - r)
    p[top : top + hi - lo, r : r + cols] = a[lo:hi]
    p[:top, r : r + cols] = a[0]
    p[top + hi - lo :, r : r + cols] = a[rows - 1]
    p[:, :r] = p[:, r : r + 1]
    p[:, r + cols :] = p[:, r + cols - 1 : r + cols]
    # along the rows, the taps in symmetric pairs
    acc, tmp = across[:m], pair[:m]
    np.multiply(p[:, r : r + cols], taps[0], out=acc)
    for j in range(1, r + 1):
        np.add(p[:, r - j : r - j + cols], p[:, r + j : r + j + cols], out=tmp)
        tmp *= taps[j]
        acc += tmp
    # then down the columns
    o, tmp = out[r0:r1], pair[:n]
    np.multiply(acc[r : r + n], taps[0], out=o)
    for j in range(1, r + 1):
        np.add(acc[r - j : r - j + n], acc[r + j : r + j + n], out=tmp)
        tmp *= taps[j]
        o += tmp


def matched_filter(sub: np.ndarray, noise, *, psf_sigma_px: float, out: np.ndarray | None = None):
    """Correlate a frame with its PSF and return it with the noise of the result.

    Parameters
    ----------
    sub : ndarray, shape (rows, columns)
        Background-subtracted frame, counts.
    noise : float or ndarray, shape (rows, columns)
        Pixel noise of the background, counts rms (a number or a map).
    psf_sigma_px : float
        Sigma of the (Gaussian) PSF, pixels.
    out : ndarray, shape (rows, columns), float32, optional
        Where to write the filtered frame (a new array by default).

    Returns
    -------
    filtered : ndarray, shape (rows, columns), float32
        The frame correlated with the unit-sum Gaussian of sigma ``psf_sigma_px``, counts.
    filtered_noise : float or ndarray
        Noise of ``filtered``, counts rms (same form as ``noise``).
    ratio : float
        ``filtered_noise / noise``.
    """
    filtered = gaussian_correlate(sub, psf_sigma_px, out=out)
    noise_arr = np.asarray(noise, dtype=np.float32)
    ratio = filtered_noise_ratio(filtered, noise_arr, psf_sigma_px=psf_sigma_px)
    return filtered, noise_arr * np.float32(ratio), ratio


def filtered_noise_ratio(
    filtered: np.ndarray, noise, *, psf_sigma_px: float, noise_grid: bool = False
) -> float:
    """Noise of a PSF-filtered frame over its pixel noise: measured, at least the white value.

    Parameters
    ----------
    filtered : ndarray, shape (rows, columns)
        Background-subtracted frame correlated with the PSF (:func:`gaussian_correlate`).
    noise : float or ndarray, shape (rows, columns)
        Pixel noise of the background, counts rms.
    psf_sigma_px : float
        Sigma of the PSF, pixels.
    noise_grid : bool
        ``noise`` is already the noise at the sampled pixels (``map[::NOISE_STEP,
        ::NOISE_STEP]``), not a whole-frame map.

    Returns
    -------
    float
        1.4826 MAD of ``filtered / noise`` over every third pixel each way, or
        ``1 / (2 sqrt(pi) sigma)`` (white noise) if that is larger.
    """
    white = 1.0 / (2.0 * np.sqrt(np.pi) * psf_sigma_px)
    noise_arr = np.asarray(noise, dtype=np.float32)
    step = NOISE_STEP
    n_s = noise_arr[::step, ::step] if noise_arr.ndim and not noise_grid else noise_arr
    f_s = filtered[::step, ::step]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.divide(f_s, np.maximum(n_s, np.float32(1e-12)), dtype=np.float32).ravel()
    if not np.isfinite(z).all():
        z = z[np.isfinite(z)]
    if z.size == 0:
        return white
    # np.median(np.abs(z - np.median(z))) with the two selections done in place (no copies)
    med = _median_in_place(z)
    np.subtract(z, med, out=z)
    np.abs(z, out=z)
    return max(MAD_TO_SIGMA * float(_median_in_place(z)), white)


#: side of the boxes over which the filtered noise is measured locally, px
LOCAL_BOX_PX = 96
#: the local filtered noise replaces the frame's only where it exceeds it by this factor (the
#: MAD of one box of ~1,000 samples scatters by ~2.5 %, ~1.5 % after the 3 x 3 median: the
#: factor is several times that, so a clean frame keeps its one threshold)
LOCAL_EXCESS = 1.15


def local_noise_ratio(filtered: np.ndarray, noise, *, ratio: float) -> np.ndarray:
    """Return the filtered frame's noise over its pixel noise, box by box, where above ``ratio``.

    A fixed pattern (row banding, blotches tens of pixels across) lies below the background
    mesh's scale and passes the PSF's filter almost whole: where it is, the filtered frame
    scatters several times more than its white noise, and a threshold set on the frame's
    median scatter lights the pattern as rows of "stars". Measured here as 1.4826 MAD of
    ``filtered / noise`` on the sampled grid in boxes of :data:`LOCAL_BOX_PX`, median-filtered
    over 3 x 3 boxes (a bright star spoils a box, not three).

    Parameters
    ----------
    filtered : ndarray, shape (rows, columns)
        Background-subtracted frame correlated with the PSF.
    noise : float or ndarray
        Pixel noise on the sampled grid (``noise_grid`` of the background), counts rms.
    ratio : float
        The frame's ratio (:func:`filtered_noise_ratio`).

    Returns
    -------
    ndarray, shape (box rows, box columns), float32
        Per box: the local ratio where it exceeds ``ratio`` by :data:`LOCAL_EXCESS`, else
        ``ratio``.
    """
    step = NOISE_STEP
    f_s = filtered[::step, ::step]
    n_s = np.broadcast_to(np.asarray(noise, dtype=np.float32), f_s.shape)
    z = f_s / np.maximum(n_s, np.float32(1e-12))
    b = max(1, LOCAL_BOX_PX // step)
    # a frame narrower than a box (a 92-row frame: 31 grid rows) is one box across that axis
    by, bx = min(b, z.shape[0]), min(b, z.shape[1])
    ny, nx = z.shape[0] // by, z.shape[1] // bx
    cells = z[: ny * by, : nx * bx].reshape(ny, by, nx, bx)
    cells = cells.transpose(0, 2, 1, 3).reshape(ny, nx, -1)
    med = np.median(cells, axis=-1, keepdims=True)
    mad = MAD_TO_SIGMA * np.median(np.abs(cells - med), axis=-1)
    mad = median_filter(mad, size=3, mode="nearest")
    out = np.where(mad > LOCAL_EXCESS * ratio, mad, ratio).astype(np.float32)
    return out


def ratio_at(mesh: np.ndarray, flat_idx: np.ndarray, columns: int) -> np.ndarray:
    """Return the box values of :func:`local_noise_ratio` at flat pixel indices (nearest box)."""
    b = max(1, LOCAL_BOX_PX // NOISE_STEP) * NOISE_STEP
    r, c = np.divmod(flat_idx, columns)
    return mesh[np.minimum(r // b, mesh.shape[0] - 1), np.minimum(c // b, mesh.shape[1] - 1)]


def _median_in_place(z: np.ndarray) -> np.float32:
    """``np.median`` of a 1-D float32 array, reordering it in place (same float32 value).

    One selection: for an even count the upper middle value is the least of those above the
    lower one (NumPy's two-index ``partition``, which ``np.median`` uses, takes ~10x longer).
    The compiled kernel (``_framec.median``: a radix selection, ~5x faster still) finds the
    same value without reordering.
    """
    n = z.size
    if _framec is not None and z.flags.c_contiguous:
        return np.float32(_framec.median(z, n, scratch("median_keys", (n,), np.uint32)))
    k = (n - 1) // 2
    z.partition(k)
    if n % 2:
        return z[k]
    return np.mean(np.array([z[k], z[k + 1 :].min()], dtype=z.dtype))


def box_mean_at_peaks(sub, filtered, *, idx, lab, half: int):
    """Return, per region, its label, its filtered peak and the box mean of ``sub`` there.

    The peak is the region's lit pixel where ``filtered`` is largest; the box is
    (2 half + 1)^2 pixels around it, edge pixels repeated beyond the frame (as
    ``ndimage.uniform_filter(mode="nearest")``), evaluated at the peaks only.
    """
    values = filtered.ravel()[idx]
    # each region's largest value, at its last pixel holding it (the last of a sort by region,
    # then by value, stable): two passes instead of the sort, which NaN needs
    top = np.full(int(lab.max()) + 1, -np.inf, values.dtype)
    np.maximum.at(top, lab, values)
    if np.isnan(top).any():
        order = np.lexsort((values, lab))
        last = order[np.r_[np.flatnonzero(np.diff(lab[order])), len(order) - 1]]
    else:
        at_top = np.flatnonzero(values == top[lab])
        last = np.full(top.size, -1, np.intp)
        np.maximum.at(last, lab[at_top], at_top)
        last = last[last >= 0]
    rows, cols = sub.shape
    r, c = np.divmod(idx[last], cols)
    off = np.arange(-half, half + 1)
    rr = np.clip(r[:, None, None] + off[None, :, None], 0, rows - 1)
    cc = np.clip(c[:, None, None] + off[None, None, :], 0, cols - 1)
    return lab[last], values[last], sub[rr, cc].mean(axis=(1, 2), dtype=np.float64)
