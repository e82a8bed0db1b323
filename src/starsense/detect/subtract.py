"""A frame minus its background level, and the pixels well above a threshold, in one pass.

The detector subtracts the background map from the frame (in float32) and then looks for the
few pixels above a threshold: hot-pixel candidates, lit pixels of the filtered frame. In NumPy
that is a subtraction, a comparison into a boolean frame and a search of it for its non-zero
entries, three passes over the frame. The compiled kernel (``_framec.subtract`` and
``_framec.above``, built by setup.py) makes one, block by block in the cache, with the same
float32 arithmetic and comparisons: the same frame and the same indices. Without a C compiler
the package runs the NumPy forms below.
"""

from __future__ import annotations

import numpy as np

from starsense._workspace import scratch

try:
    import starsense.detect._framec as _framec
except ImportError:  # built without a C compiler: the NumPy forms below
    _framec = None

__all__ = ["floor_threshold", "pixels_above", "subtract_level"]

#: indices the kernel collects at most (a frame with more above its threshold than this, or a
#: sixteenth of its pixels, is searched again by NumPy)
_MIN_CAPACITY = 1 << 16
#: sample types the kernel reads (NumPy's type characters): 8/16-bit integers, floats
_KINDS = frozenset("BHhfd")


def floor_threshold(background, sigma: float):
    """Return ``sigma`` times the frame's lowest background noise (at least 1e-12 counts).

    Parameters
    ----------
    background : Background
        The frame's background (:mod:`starsense.detect.background`).
    sigma : float
        Multiple of the noise.

    Returns
    -------
    numpy.float32
        The threshold, counts (a float32 for float32 noise floors).
    """
    return sigma * np.maximum(background.noise_floor(), np.float32(1e-12))


def _capacity(n: int) -> int:
    return max(_MIN_CAPACITY, n // 16)


def _collected(count: int, idx: np.ndarray, x: np.ndarray, threshold) -> np.ndarray:
    """Return the kernel's indices, or NumPy's search where more were above than it held."""
    if count <= idx.size:
        return idx[:count].copy()
    return np.flatnonzero(x > threshold)


def pixels_above(x: np.ndarray, threshold) -> np.ndarray:
    """Return ``np.flatnonzero(x > threshold)``: flat indices of the values above, ascending.

    Parameters
    ----------
    x : ndarray
        Values (a float32 frame takes the compiled path).
    threshold : scalar
        Threshold, in the units of ``x`` (a float32 threshold takes the compiled path).

    Returns
    -------
    ndarray of int64
    """
    if (
        _framec is not None
        and x.dtype == np.float32
        and x.flags.c_contiguous
        and isinstance(threshold, np.float32)
    ):
        idx = scratch("above_idx", (_capacity(x.size),), np.int64)
        count = _framec.above(x, x.size, float(threshold), idx, idx.size)
        return _collected(count, idx, x.ravel(), threshold)
    return np.flatnonzero(x > threshold)


def subtract_level(image, level, out: np.ndarray, *, above=None):
    """Subtract a background level from a frame in float32, and find the pixels above a threshold.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        Frame, counts (any real dtype).
    level : float or ndarray, shape (rows, columns)
        Background level, counts (``Background.level``).
    out : ndarray of float32, shape (rows, columns)
        Where the difference goes (``np.subtract(image, level, dtype=float32)``).
    above : scalar, optional
        Threshold on the difference, counts.

    Returns
    -------
    out : ndarray of float32, shape (rows, columns)
    idx : ndarray of int64 or None
        ``np.flatnonzero(out > above)``; None without ``above``.
    """
    a = np.asarray(image)
    lev = np.asarray(level, dtype=np.float32)
    if (
        _framec is not None
        and lev.shape == a.shape == out.shape
        and a.dtype.char in _KINDS
        and a.dtype.isnative
        and out.dtype == np.float32
        and out.flags.c_contiguous
        and (above is None or isinstance(above, np.float32))
    ):
        idx = scratch("above_idx", (_capacity(a.size),), np.int64)
        thr, cap = (np.inf, 0) if above is None else (float(above), idx.size)
        args = (np.ascontiguousarray(a), a.dtype.char, np.ascontiguousarray(lev), a.size, out)
        count = _framec.subtract(*args, thr, idx, cap)
        return out, None if above is None else _collected(count, idx, out.ravel(), above)
    np.subtract(a, lev, out=out, dtype=np.float32)
    return out, None if above is None else np.flatnonzero(out > above)
