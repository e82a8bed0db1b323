"""Per-row statistics of small 2-D arrays that hold NaN (windows cut at a frame's edge)."""

from __future__ import annotations

import numpy as np

__all__ = ["row_nanmedian"]


def row_nanmedian(a) -> np.ndarray:
    """Return ``np.nanmedian(a, axis=1)`` of a 2-D array, without its cost on small rows.

    One sort per row (NaN sorts last), then the middle of each row's finite values: the same
    values as NumPy's (the mean of the middle two of an even count; NaN for a row of NaN,
    without its warning). NumPy's takes ~0.1 ms on the few 100-value rows of a star's window
    borders (it masks them), this ~10 us.
    """
    a = np.asarray(a, dtype=float)
    s = np.sort(a, axis=1)
    n = np.count_nonzero(~np.isnan(a), axis=1)
    rows = np.arange(len(a))
    lo, hi = np.maximum((n - 1) // 2, 0), np.maximum(n // 2, 0)
    out = 0.5 * (s[rows, lo] + s[rows, hi]) if a.shape[1] else np.full(len(a), np.nan)
    out[n == 0] = np.nan
    return out
