"""Row and column fixed pattern: offsets of whole lines that a background mesh cannot follow.

CMOS sensors read a row (or a column) through one amplifier: each line carries its own offset,
a banding of a fraction of the read noise that drifts from line to line. The background mesh
(boxes of tens of pixels) averages it away; the PSF's matched filter does not (it sums ~3
lines), and a band of a few tenths of the noise across a row lights the row as a string of
faint "stars". Each line's offset is measured here as the mean of its background pixels (below
5 noise sigma: stars left out; the mean, not the median, because the filter sums values and
a frame clipped at zero has a skewed noise) and removed where the lines' offsets scatter
significantly more than the noise alone makes them scatter (sigma / sqrt(pixels per line)).
"""

from __future__ import annotations

import numpy as np

try:
    import starsense.detect._framec as _framec
except ImportError:  # built without a C compiler: the NumPy form below
    _framec = None

__all__ = ["CUT_SIGMAS", "PATTERN_SIGNIFICANCE", "line_offsets", "remove_line_pattern"]

#: the lines' offsets are removed when their scatter exceeds the noise's by this factor (the
#: scatter of ~1,000 line means of white noise is known to ~2 %; demosaiced frames correlate
#: neighbouring pixels, which raises it by up to ~1.5: the factor is above both)
PATTERN_SIGNIFICANCE = 2.0


#: a pixel is a line's background pixel below this many noise sigmas
CUT_SIGMAS = 5.0


def line_offsets(sub: np.ndarray, noise: np.ndarray | float, axis: int) -> np.ndarray:
    """Return each line's mean of its pixels below :data:`CUT_SIGMAS` noise (0 where none).

    Parameters
    ----------
    sub : ndarray, shape (rows, columns), float32
        Background-subtracted frame.
    noise : float or ndarray (rows, columns)
        Background noise, counts rms.
    axis : {1, 0}
        1: one mean per row; 0: one per column.

    Returns
    -------
    ndarray of float64, shape (rows,) or (columns,)
    """
    noise32 = np.asarray(noise, dtype=np.float32)
    if _framec is not None and sub.dtype == np.float32 and sub.flags.c_contiguous:
        # the compiled form (_framec.c): one pass, the same float32 comparisons, the sums in
        # order along each line
        lines = sub.shape[0] if axis == 1 else sub.shape[1]
        total, n = np.empty(lines), np.empty(lines, dtype=np.int64)
        mapped = noise32.ndim == 2
        noise32 = np.ascontiguousarray(noise32 if mapped else noise32.reshape(1))
        _framec.line_sums(sub, *sub.shape, noise32, int(mapped), CUT_SIGMAS, axis, total, n)
    else:
        below = sub < np.float32(CUT_SIGMAS) * noise32
        n = below.sum(axis=axis)
        total = np.where(below, sub, np.float32(0.0)).sum(axis=axis, dtype=np.float64)
    return np.where(n > 0, total / np.maximum(n, 1), 0.0)


def remove_line_pattern(sub: np.ndarray, noise) -> dict:
    """Subtract significant row and column offsets from a background-subtracted frame, in place.

    Parameters
    ----------
    sub : ndarray, shape (rows, columns), float32
        Frame minus its background map, counts (modified in place).
    noise : float or ndarray (rows, columns)
        Background noise, counts rms (the map where there is one).

    Returns
    -------
    dict
        ``row_pattern_counts`` and ``column_pattern_counts``: the rms of the offsets removed
        (0 where the lines did not scatter significantly).
    """
    out = {}
    sigma = float(np.median(noise))
    for axis, name in ((1, "row_pattern_counts"), (0, "column_pattern_counts")):
        off = line_offsets(sub, noise, axis)
        expected = sigma / np.sqrt(sub.shape[axis])
        rms = float(np.std(off))
        if rms > PATTERN_SIGNIFICANCE * expected and off.size > 8:
            off = (off - np.median(off)).astype(np.float32)
            sub -= off[:, None] if axis == 1 else off[None, :]
            out[name] = rms
        else:
            out[name] = 0.0
    return out
