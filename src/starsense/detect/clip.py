"""Sigma-clipped medians and MADs of many boxes at once (the mesh of :mod:`.background`).

The samples of every box are sorted once; the samples kept by clipping are then a contiguous
run of the sorted row, whose median is a rank lookup and whose median absolute deviation (MAD)
is found by bisection over the run's two halves, below and above the median (no second sort).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAD_TO_SIGMA"]

#: 1 / Phi^-1(3/4): the standard deviation of a Gaussian over its median absolute deviation.
MAD_TO_SIGMA = 1.482602218505602

_MAX_CLIP_ITERATIONS = 10


def _ranked(sorted_rows: np.ndarray, start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Median of ``sorted_rows[..., start:start + count]`` per row (NaN where count is 0)."""
    last = sorted_rows.shape[-1] - 1
    i0 = np.clip(start + (count - 1) // 2, 0, last)[..., None]
    i1 = np.clip(start + count // 2, 0, last)[..., None]
    a = np.take_along_axis(sorted_rows, i0, axis=-1)[..., 0]
    b = np.take_along_axis(sorted_rows, i1, axis=-1)[..., 0]
    return np.where(count > 0, 0.5 * (a.astype(np.float64) + b), np.nan)


def _kth_of_two(left, right, n_left, n_right, k):
    """k-th smallest (0-based) of two ascending sequences per row, by bisection (no sort).

    ``left(i)`` and ``right(j)`` return the i-th and j-th values of every row (index arrays of
    the rows' shape); ``n_left``, ``n_right`` are their lengths and ``0 <= k < n_left + n_right``.
    The search finds how many of the k + 1 smallest come from ``left``.
    """
    lo = np.maximum(0, k + 1 - n_right)
    hi = np.minimum(k + 1, n_left)
    top = hi.copy()
    while np.any(lo < hi):
        mid = (lo + hi) // 2
        active = lo < hi
        # taking mid from left: is its next value no smaller than the last one from right?
        done = active & (left(np.minimum(mid, top - 1)) >= right(np.maximum(k - mid, 0)))
        hi = np.where(done, mid, hi)
        lo = np.where(active & ~done, mid + 1, lo)
    a, b = lo, k + 1 - lo
    from_left = np.where(a > 0, left(np.maximum(a - 1, 0)), -np.inf)
    from_right = np.where(b > 0, right(np.maximum(b - 1, 0)), -np.inf)
    return np.maximum(from_left, from_right)


def _run_mad(s: np.ndarray, lo: np.ndarray, hi: np.ndarray, med: np.ndarray) -> np.ndarray:
    """Median of ``|s[..., lo:hi] - med|`` per row of the ascending rows ``s`` (NaN if empty).

    The deviations of a sorted run about its median are two ascending sequences (below and
    above the median); their median is found by :func:`_kth_of_two` instead of sorting them.
    Same float32 arithmetic as ``np.abs(s - med)``, so the same values.
    """
    m32 = med.astype(np.float32)
    last = s.shape[-1] - 1
    with np.errstate(invalid="ignore"):
        split = np.clip((s < m32[..., None]).sum(axis=-1), lo, hi)

    def at(i):
        return np.take_along_axis(s, np.clip(i, 0, last)[..., None], axis=-1)[..., 0]

    def below(i):
        return m32 - at(split - 1 - i)

    def above(j):
        return at(split + j) - m32

    count = hi - lo
    n_below, n_above = split - lo, hi - split
    k0 = np.maximum((count - 1) // 2, 0)
    a = _kth_of_two(below, above, n_below, n_above, k0)
    b = _kth_of_two(below, above, n_below, n_above, count // 2)
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, 0.5 * (a.astype(np.float64) + b), np.nan)


def _sigma_clip_boxes(cells: np.ndarray, sigma_clip: float):
    """Sigma-clipped median of every box at once.

    ``cells`` (..., samples) holds NaN for missing samples. The samples are sorted once; the kept
    samples of a box are then a contiguous run ``[lo, hi)`` of its sorted row, so the median is a
    rank lookup and the MAD a bisection over the run's two halves (:func:`_run_mad`).

    Returns the median, the lowest and highest kept values and the number kept, per box.
    """
    s = np.sort(cells, axis=-1)  # NaN last
    lo = np.zeros(cells.shape[:-1], dtype=np.intp)
    hi = np.isfinite(s).sum(axis=-1)
    med = _ranked(s, lo, hi - lo)
    for _ in range(_MAX_CLIP_ITERATIONS):
        scale = MAD_TO_SIGMA * _run_mad(s, lo, hi, med)
        # a zero scale (noiseless box) would clip everything off the median: do not clip
        half = np.where(scale > 0, sigma_clip * scale, np.inf)
        with np.errstate(invalid="ignore"):
            new_lo = np.maximum(lo, (s < (med - half)[..., None]).sum(axis=-1))
            new_hi = np.minimum(hi, (s <= (med + half)[..., None]).sum(axis=-1))
        new_hi = np.maximum(new_hi, new_lo)
        if np.array_equal(new_lo, lo) and np.array_equal(new_hi, hi):
            break
        lo, hi = new_lo, new_hi
        med = _ranked(s, lo, hi - lo)
    last = s.shape[-1] - 1
    low = np.take_along_axis(s, np.clip(lo, 0, last)[..., None], axis=-1)[..., 0]
    high = np.take_along_axis(s, np.clip(hi - 1, 0, last)[..., None], axis=-1)[..., 0]
    return med, low, high, hi - lo


def _robust_sigma(cells: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """1.4826 MAD over the samples ``keep`` of every box (NaN where none)."""
    n = keep.sum(axis=-1)
    zero = np.zeros(n.shape, dtype=np.intp)
    v = np.sort(np.where(keep, cells, np.inf), axis=-1)
    med = _ranked(v, zero, n)
    dev = np.sort(np.where(keep, np.abs(cells - med[..., None].astype(np.float32)), np.inf), -1)
    return MAD_TO_SIGMA * _ranked(dev, zero, n)
