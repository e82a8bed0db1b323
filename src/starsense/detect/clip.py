"""Sigma-clipped medians and MADs of many boxes at once (the mesh of :mod:`.background`).

The samples of every box are sorted once; the samples kept by clipping are then a contiguous
run of the sorted row, whose median is a rank lookup and whose median absolute deviation (MAD)
is found by bisection over the run's two halves, below and above the median (no second sort).

The compiled kernel ``_clipc`` (``_clipc.c``, built by setup.py), when it is installed, runs
the same algorithm box by box: it sorts each box's samples itself (a radix sort on the values'
bits, in the cache, in place of NumPy's sort of the whole mesh and its copies) and bisects
them; the NumPy form below sorts with NumPy and bisects every box at once in a few hundred
small array operations. Both give the same values, bit for bit
(tests/detect/test_detect_clip_kernel.py); without a C compiler at install time the package
runs the NumPy form.
"""

from __future__ import annotations

import numpy as np

from starsense._workspace import scratch

try:
    import starsense.detect._clipc as _clipc
except ImportError:  # built without a C compiler: the NumPy form below
    _clipc = None

__all__ = ["MAD_TO_SIGMA", "robust_sigma", "sigma_clip_boxes"]

#: 1 / Phi^-1(3/4): the standard deviation of a Gaussian over its median absolute deviation.
MAD_TO_SIGMA = 1.482602218505602

_MAX_CLIP_ITERATIONS = 10
#: rows of at most this many samples get their MAD by sorting the deviations (same values)
_SORT_DEVIATIONS_BELOW = 256


def _rows_at(sorted_rows: np.ndarray):
    """Return ``at(i)``: the ``i``-th value of every row of ``sorted_rows``.

    Flat indexing with precomputed row offsets: the searches below call this a few hundred
    times on arrays of a few hundred rows, where ``np.take_along_axis`` and ``np.clip`` cost
    more in building their index arrays than in the gather itself. An index outside its row
    reads a neighbouring row (or the array's first or last value): the searches only read
    such indices for rows whose result they then discard (empty runs, finished searches).
    """
    m = sorted_rows.shape[-1]
    flat = np.ascontiguousarray(sorted_rows).reshape(-1)
    base = np.arange(0, flat.size, m, dtype=np.intp).reshape(sorted_rows.shape[:-1])

    def at(i):
        return flat.take(base + i, mode="clip")

    at.flat, at.base = flat, base  # for callers that fold their own offsets into ``base``
    return at


def _steps(width: np.ndarray) -> int:
    """Halvings that take every interval of ``width`` (>= 0) down to nothing."""
    return int(np.max(width, initial=0)).bit_length()


def _rank_of(at, lo: np.ndarray, hi: np.ndarray, x: np.ndarray, inclusive: bool) -> np.ndarray:
    """Per row, ``lo`` plus how many of the ascending values ``[lo, hi)`` are < x (<= x).

    A vectorised binary search in every row at once (``np.searchsorted`` per row, side "left"
    or "right"), in place of comparing and counting all the row's samples: the same count,
    clamped to ``[lo, hi]``, for ~log2(samples) small gathers. A finished row stays put
    (``left == right``), so every row takes the same fixed number of steps, unmasked.
    """
    shape = np.broadcast_shapes(np.shape(lo), np.shape(x))  # x may stack several per row
    left, right = np.broadcast_to(lo, shape).copy(), np.broadcast_to(hi, shape).copy()
    less = np.less_equal if inclusive else np.less
    for _ in range(_steps(right - left)):
        mid = (left + right) >> 1
        go = less(at(mid), x)
        left = np.where(go, np.minimum(mid + 1, right), left)
        right = np.where(go, right, mid)
    return left


def _ranked(sorted_rows: np.ndarray, start: np.ndarray, count: np.ndarray, at=None) -> np.ndarray:
    """Median of ``sorted_rows[..., start:start + count]`` per row (NaN where count is 0)."""
    at = _rows_at(sorted_rows) if at is None else at
    a = at(start + (count - 1) // 2)
    b = at(start + count // 2)
    return np.where(count > 0, 0.5 * (a.astype(np.float64) + b), np.nan)


def _kth_of_two(left, right, n_left, n_right, k):
    """k-th smallest (0-based) of two ascending sequences per row, by bisection (no sort).

    ``left(i)`` and ``right(j)`` return the i-th and j-th values of every row (index arrays of
    the rows' shape); ``n_left``, ``n_right`` are their lengths and ``0 <= k < n_left + n_right``.
    The search finds how many of the k + 1 smallest come from ``left``.
    """
    lo = np.maximum(0, k + 1 - n_right)
    hi = np.minimum(k + 1, n_left)
    top_1 = hi - 1
    # lo > hi only for an empty sequence pair (k = 0), whose result the caller discards
    for _ in range(_steps(hi - lo)):
        mid = (lo + hi) >> 1
        # taking mid from left: is its next value no smaller than the last one from right?
        done = left(np.minimum(mid, top_1)) >= right(np.maximum(k - mid, 0))
        lo = np.where(done, lo, np.minimum(mid + 1, hi))
        hi = np.where(done, mid, hi)
    a, b = lo, k + 1 - lo
    from_left = np.where(a > 0, left(np.maximum(a - 1, 0)), -np.inf)
    from_right = np.where(b > 0, right(np.maximum(b - 1, 0)), -np.inf)
    return np.maximum(from_left, from_right)


def _run_mad(s: np.ndarray, lo: np.ndarray, hi: np.ndarray, med: np.ndarray, at=None) -> np.ndarray:
    """Median of ``|s[..., lo:hi] - med|`` per row of the ascending rows ``s`` (NaN if empty).

    The deviations of a sorted run about its median are two ascending sequences (below and
    above the median); their median is found by :func:`_kth_of_two` instead of sorting them.
    Same float32 arithmetic as ``np.abs(s - med)``, so the same values.
    """
    at = _rows_at(s) if at is None else at
    m32 = med.astype(np.float32)
    with np.errstate(invalid="ignore"):
        split = _rank_of(at, lo, hi, m32, inclusive=False)
    flat = at.flat
    from_split_1, from_split = at.base + (split - 1), at.base + split

    def below(i):
        return m32 - flat.take(from_split_1 - i, mode="clip")

    def above(j):
        return flat.take(from_split + j, mode="clip") - m32

    count = hi - lo
    n_below, n_above = split - lo, hi - split
    # both middle ranks in one bisection (the index arrays broadcast over the leading 2)
    k = np.stack([np.maximum((count - 1) // 2, 0), count // 2])
    a, b = _kth_of_two(below, above, n_below, n_above, k)
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, 0.5 * (a.astype(np.float64) + b), np.nan)


def sigma_clip_boxes(cells: np.ndarray, sigma_clip: float, *, counts: np.ndarray | None = None):
    """Sigma-clipped median of every box at once.

    ``cells`` (..., samples) holds NaN for missing samples. The samples are sorted once; the kept
    samples of a box are then a contiguous run ``[lo, hi)`` of its sorted row, so the median is a
    rank lookup and the MAD a bisection over the run's two halves (:func:`_run_mad`).

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        The samples of each box, counts; NaN where missing.
    sigma_clip : float
        Clip at this many robust sigmas (MAD_TO_SIGMA x MAD) from the median.
    counts : ndarray of 8- or 16-bit integers, shape (..., samples), optional
        The same samples as the integers they were converted from (none missing): sorted as
        integers, ~1.5x faster than as floats, then converted (exactly, and in the same order).

    Returns
    -------
    median : ndarray, shape (...)
        The clipped median of each box.
    low, high : ndarray, shape (...)
        The lowest and highest kept values.
    kept : ndarray of int, shape (...)
        The number of samples kept.
    """
    ints = counts is not None and counts.dtype.itemsize <= 2 and counts.dtype.kind in "iu"
    if _clipc is not None and (ints or cells.dtype == np.float32):
        # each box sorted and clipped in the kernel (a radix sort, in the cache): the same
        # sorted rows as np.sort's, so the same values
        values = np.ascontiguousarray(counts if ints else cells)
        if not values.dtype.isnative:  # e.g. FITS's big-endian integers
            values = values.astype(values.dtype.newbyteorder("="))
        return _clip_in_kernel(values, float(sigma_clip))
    s = scratch("clip_sorted", cells.shape, cells.dtype)
    if ints:
        ints = scratch("clip_sorted_counts", counts.shape, counts.dtype)
        np.copyto(ints, counts)
        ints.sort(axis=-1)
        np.copyto(s, ints)
    else:
        np.copyto(s, cells)
        s.sort(axis=-1)  # NaN last
    return _clip_sorted_numpy(s, sigma_clip)


#: the kernel's name of each sample type it sorts (clip_rows in _clipc.c)
_KINDS = {"float32": "f", "uint8": "B", "int8": "b", "uint16": "H", "int16": "h"}


def _clip_in_kernel(values: np.ndarray, sigma_clip: float):
    """:func:`sigma_clip_boxes` by the kernel on the unsorted, C-contiguous samples."""
    lead, m = values.shape[:-1], values.shape[-1]
    rows = int(np.prod(lead))
    med, kept = np.empty(lead, np.float64), np.empty(lead, np.int64)
    low, high = np.empty(lead, np.float32), np.empty(lead, np.float32)
    kind = _KINDS[values.dtype.name]
    args = (values, kind, rows, m, sigma_clip, MAD_TO_SIGMA, _MAX_CLIP_ITERATIONS)
    _clipc.clip_rows(*args, med, low, high, kept)
    return med, low, high, kept.astype(np.intp, copy=False)


def _clip_sorted_numpy(s: np.ndarray, sigma_clip: float):
    """Clip the sorted rows of :func:`sigma_clip_boxes`, every box at once, in NumPy."""
    mask = scratch("clip_mask", s.shape, bool)
    at = _rows_at(s)
    lo = np.zeros(s.shape[:-1], dtype=np.intp)
    hi = np.count_nonzero(np.isfinite(s, out=mask), axis=-1)
    med = _ranked(s, lo, hi - lo, at)
    for _ in range(_MAX_CLIP_ITERATIONS):
        scale = MAD_TO_SIGMA * _run_mad(s, lo, hi, med, at)
        # a zero scale (noiseless box) would clip everything off the median: do not clip
        half = np.where(scale > 0, sigma_clip * scale, np.inf)
        # both bounds in one search: s <= x is s < the next float64 after x (s is float32,
        # exact in float64)
        bounds = np.stack([med - half, np.nextafter(med + half, np.inf)])
        with np.errstate(invalid="ignore"):
            new_lo, new_hi = _rank_of(at, lo, hi, bounds, inclusive=False)
        new_hi = np.maximum(new_hi, new_lo)
        if np.array_equal(new_lo, lo) and np.array_equal(new_hi, hi):
            break
        lo, hi = new_lo, new_hi
        med = _ranked(s, lo, hi - lo, at)
    last = s.shape[-1] - 1
    low, high = at(np.minimum(lo, last)), at(np.maximum(hi - 1, 0))
    return med, low, high, hi - lo


def robust_sigma(cells: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Return MAD_TO_SIGMA x MAD over the samples ``keep`` of every box (NaN where none).

    Parameters
    ----------
    cells : ndarray, shape (..., samples)
        The samples of each box, counts.
    keep : ndarray of bool, shape (..., samples)
        The samples to use.

    Returns
    -------
    ndarray, shape (...)
        The robust noise of each box, counts.
    """
    if _clipc is not None and cells.dtype == np.float32 and cells.shape[-1] > 0:
        # each box's kept samples sorted (a radix sort) and their MAD taken in the kernel:
        # the values of the NumPy form's sorted rows, so the same MAD
        values = np.ascontiguousarray(cells)
        kept = np.ascontiguousarray(np.broadcast_to(keep, cells.shape)).view(np.uint8)
        out = np.empty(cells.shape[:-1], np.float64)
        _clipc.mad_masked(values, kept, int(out.size), cells.shape[-1], out)
        return MAD_TO_SIGMA * out
    return _robust_sigma_numpy(cells, keep)


def _robust_sigma_numpy(cells: np.ndarray, keep: np.ndarray, n: np.ndarray | None = None):
    """:func:`robust_sigma` every box at once, in NumPy."""
    n = np.count_nonzero(keep, axis=-1) if n is None else n
    zero = np.zeros(n.shape, dtype=np.intp)
    if cells.shape[-1] <= _SORT_DEVIATIONS_BELOW:
        # short rows: sorting the deviations costs less than searching for their median
        v = np.sort(np.where(keep, cells, np.inf), axis=-1)
        med = _ranked(v, zero, n)
        dev = np.where(keep, np.abs(cells - med[..., None].astype(cells.dtype)), np.inf)
        return MAD_TO_SIGMA * _ranked(np.sort(dev, axis=-1), zero, n)
    v = scratch("robust_sorted", cells.shape, cells.dtype)
    np.copyto(v, cells)
    np.copyto(v, np.inf, where=np.logical_not(keep, out=scratch("robust_mask", keep.shape, bool)))
    v.sort(axis=-1)  # the kept samples first, ascending
    at = _rows_at(v)
    med = _ranked(v, zero, n, at)
    return MAD_TO_SIGMA * _run_mad(v, zero, n, med, at)
