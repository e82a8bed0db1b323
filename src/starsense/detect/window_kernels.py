"""The per-window work of tracking's window detection, in two forms that give the same rows.

:func:`detect_stack_numpy` is the reference: NumPy over every window at once (labels through
``scipy.ndimage.label``, centroids vectorised over the regions). :func:`detect_stack_compiled`
runs the same algorithm in the compiled kernel ``_windowc`` (``_windowc.c``, built by setup.py
as an optional extension), which cuts the windows from the frame itself: the same float32
thresholds, labels in the same raster order, region sums in the same order, so the results are
equal bit for bit for whole-number counts (a camera's) and to rounding otherwise (the centroid
sums, over a box or a streak's capsule, are summed in another order).
:class:`~starsense.detect.windows.WindowDetector` uses the compiled form where it is built and
reads the frame's pixel type, else the NumPy form.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from starsense._workspace import scratch
from starsense.detect.streak import columns, kept_arange, streak_centroids, windows_view

try:  # the compiled kernel (setup.py builds it where a C compiler exists)
    import starsense.detect._windowc as _windowc
except ImportError:  # pragma: no cover - exercised on machines without a compiler
    _windowc = None

__all__ = [
    "NO_ROWS",
    "apart_compiled",
    "apart_numpy",
    "count_inside_compiled",
    "count_inside_numpy",
    "detect_stack_compiled",
    "detect_stack_numpy",
    "float32_below",
    "label_windows",
    "union_area_compiled",
    "union_area_numpy",
]

#: scipy's 2-D structuring elements, 8- and 4-connected (indexed by ``connectivity == 4``).
_STRUCTURES = (ndimage.generate_binary_structure(2, 2), ndimage.generate_binary_structure(2, 1))
#: Pixel types the kernel reads (native byte order), by dtype string: the buffer format code.
_KERNEL_TYPES = {
    np.dtype(t).str: np.dtype(t).char
    for t in (np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32, np.float32, np.float64)
}
_NCOL = 13  # x, y, counts, pixels, peak, box (4), spread (4): one row of the kernel's output
_NO_STREAKS = np.zeros(0)


def _lit_labels(lit: np.ndarray, connectivity: int):
    """Label the lit pixels of the stack (K, h, w), never across windows; labels of lit pixels.

    The windows are labelled as one 2-D image of their rows that hold a lit pixel, in order,
    with an empty row wherever two kept rows are not neighbours in one window (a row without
    a lit pixel joins nothing, so the regions, their labels and scipy's raster order of them
    are those of the windows stacked with an empty row between them, at a fraction of the
    pixels).

    Returns
    -------
    idx : ndarray of int, shape (M,)
        Flat indices of the lit pixels in the stack, ascending.
    lab : ndarray of int, shape (M,)
        Their labels, 1..n.
    n : int
        Number of regions.
    """
    k, h, w = lit.shape
    flat = lit.reshape(k * h, w)
    idx = np.flatnonzero(lit)
    if len(idx) == 0:
        return idx, np.zeros(0, np.int32), 0
    lit_rows = idx // w  # ascending
    new = np.empty(len(idx), bool)  # the first lit pixel of its row
    new[0] = True
    np.not_equal(lit_rows[1:], lit_rows[:-1], out=new[1:])
    rows = lit_rows[new]
    # a break before each kept row that does not continue the row above it in its window
    gap = np.ones(len(rows), np.intp)
    gap[0] = 0
    gap[1:] = (rows[1:] != rows[:-1] + 1) | (rows[1:] % h == 0)
    pos = np.arange(len(rows)) + np.cumsum(gap)
    compact = np.zeros((pos[-1] + 1, w), dtype=bool)
    compact[pos] = flat[rows]
    labels, n = ndimage.label(compact, structure=_STRUCTURES[connectivity == 4])
    j = np.cumsum(new) - 1  # each lit pixel's kept row
    return idx, labels[pos[j], idx - lit_rows * w], n


def label_windows(lit: np.ndarray, connectivity: int):
    """Label the lit pixels of each window of the stack (K, h, w), never across windows.

    The labels of :func:`_lit_labels` put back on the stack (0 where unlit).
    """
    idx, lab, n = _lit_labels(lit, connectivity)
    labels = np.zeros(lit.shape, dtype=np.int32)
    labels.reshape(-1)[idx] = lab
    return labels, n


def float32_below(threshold: np.ndarray) -> np.ndarray:
    """Return the largest float32 at most each threshold (float64), shape (K,).

    For float32 ``x``, ``x > t`` equals ``x > _below(t)``: comparing float32 counts with
    float32 thresholds, not float64 ones, halves the work.
    """
    t32 = threshold.astype(np.float32)
    up = t32 > threshold
    if up.any():
        t32[up] = np.nextafter(t32[up], np.float32(-np.inf))
    return t32


def _cogs(sub, p, boxes, margin):
    """CoG of each region over its box plus the margin on its plane, px; NaN where empty.

    Each region is read from a crop of its plane that holds the grown box (one crop size for
    all: the largest grown box); pixels outside the grown box weigh nothing.
    """
    _, rows, cols = sub.shape
    if len(p) == 0:
        return np.zeros(0), np.zeros(0)
    a = np.maximum(boxes[:, 0] - margin, 0)[:, None]
    b = np.minimum(boxes[:, 1] + margin, rows)[:, None]
    c = np.maximum(boxes[:, 2] - margin, 0)[:, None]
    d = np.minimum(boxes[:, 3] + margin, cols)[:, None]
    h, w = int((b - a).max()), int((d - c).max())
    r0, c0 = np.minimum(a, rows - h), np.minimum(c, cols - w)  # (L, 1) first row, column
    rr = r0 + kept_arange(h)  # (L, h) rows of each crop
    cc = c0 + kept_arange(w)  # (L, w) columns
    keep = ((rr >= a) & (rr < b))[:, :, None] & ((cc >= c) & (cc < d))[:, None, :]
    crop = windows_view(sub, (h, w))[p, r0[:, 0], c0[:, 0]].astype(float)
    wt = np.where(keep, crop, 0.0)
    total = np.add.reduce(wt, axis=(1, 2))  # wt.sum, without its wrapper
    good = total > 0  # else NaN (an empty or negative region)
    x = np.divide(
        np.einsum("kj,kj->k", np.add.reduce(wt, axis=1), cc.astype(float)),
        total,
        out=np.full(len(p), np.nan),
        where=good,
    )
    y = np.divide(
        np.einsum("ki,ki->k", np.add.reduce(wt, axis=2), rr.astype(float)),
        total,
        out=np.full(len(p), np.nan),
        where=good,
    )
    return x, y


def _inside(x, y, streaks, sigma: float, shape) -> np.ndarray:
    """Whether each whole streak centred on (x, y), with its PSF radius, lies on the frame."""
    reach = 2.5 * sigma + 1.0
    hx = 0.5 * np.abs(streaks[:, 0]) + reach
    hy = 0.5 * np.abs(streaks[:, 1]) + reach
    rows, cols = shape
    return (hx <= x) & (x <= cols - 1 - hx) & (hy <= y) & (y <= rows - 1 - hy)


def _label_extents(idx, lab, sizes, values, shape):
    """Plane, box (a, b, c, d) and peak value of every label 1..n from its lit pixels.

    ``idx`` are the flat indices of the lit pixels in the (K, h, w) stack, ``lab`` their
    labels and ``values`` their counts; every label has ``sizes`` pixels (at least one).
    """
    _, h, w = shape
    order = np.argsort(lab, kind="stable")
    starts = np.concatenate([[0], np.cumsum(sizes[1:])[:-1]])
    plane, rest = np.divmod(idx[order], h * w)
    row, col = np.divmod(rest, w)
    low, high = np.minimum.reduceat, np.maximum.reduceat
    box = np.column_stack(
        [low(row, starts), high(row, starts) + 1, low(col, starts), high(col, starts) + 1]
    )
    return plane[starts], box, np.maximum.reduceat(values[order], starts)


def _regions(p, box, ok, r0, c0, shape, window):
    """Labels, planes and boxes of the kept regions, dropping those cut by a window edge."""
    keep = np.flatnonzero(ok[1:])
    p, box = p[keep], box[keep]
    h, w = window
    rows, cols = shape
    a, b, c, d = box.T
    # a star cut by the window's edge (not the frame's) has a biased centroid: drop it
    cut = ((a == 0) & (0 < r0[p])) | ((b == h) & (r0[p] + h < rows))
    cut |= ((c == 0) & (0 < c0[p])) | ((d == w) & (c0[p] + w < cols))
    return keep[~cut] + 1, p[~cut], box[~cut]


def detect_stack_numpy(stack, shape, *, corners, level, threshold, logic, sigma_px, streaks):
    """Apply the detection logic to every window at once, in NumPy (the reference form).

    With a streak of at least 2 PSF sigmas the centroid is taken over the whole predicted
    streak (:func:`streak_centroids`), started from the region's CoG; else the CoG over the
    region's box plus a 2 px margin, as the full-frame detector does.

    Parameters
    ----------
    stack : ndarray, shape (K, h, w)
        The windows, counts as read.
    shape : (int, int)
        The frame's rows and columns.
    corners : (ndarray of int, ndarray of int), shape (K,) each
        Each window's first row and column in the frame, px.
    level : ndarray of float32, shape (K,) or (1,)
        Each window's background level, counts ((1,): one for all).
    threshold : ndarray of float32, shape (K,) or (1,)
        Lit when the counts less the level exceed it (:func:`float32_below` of the threshold).
    logic : DetectionLogic
        ``connectivity``, ``min_pixels``, ``min_integrated_counts``.
    sigma_px : float
        PSF sigma, px.
    streaks : ndarray, shape (K, 2) or None
        Each window's predicted streak (start to end), px.

    Returns
    -------
    rows : tuple of ndarray
        x, y (N,), px; counts (N,); pixels (N,) int; peak (N,) counts; box (N, 4) int
        (row0, row1, col0, col1, frame px); spread (N, 2, 2), px^2 (NaN without a streak).
    n : int
        Regions labelled (candidates).
    """
    r0, c0 = corners
    # counts less the level in float32 (the frame's integer counts are exact in it)
    if len(level) == 1:  # one level and threshold for all: scalars, no broadcast
        sub = stack.astype(np.float32)
        sub -= level[0]
        lit = sub > threshold[0]
    else:
        sub = np.subtract(stack, level[:, None, None], dtype=np.float32)
        lit = sub > threshold[:, None, None]
    idx, lab, n = _lit_labels(lit, logic.connectivity)
    if n == 0:
        return NO_ROWS, 0
    sizes = np.bincount(lab, minlength=n + 1)
    sums = np.bincount(lab, weights=sub.ravel()[idx], minlength=n + 1)
    values = stack.ravel()[idx].astype(np.float32)
    plane, extent, peak = _label_extents(idx, lab, sizes, values, stack.shape)
    peaks = np.concatenate([[-np.inf], peak])
    ok = (sizes >= logic.min_pixels) & (sums >= logic.min_integrated_counts)
    k, p, box = _regions(plane, extent, ok, r0, c0, shape, stack.shape[1:])
    sigma = float(sigma_px)
    x, y = _cogs(sub, p, box, 2)
    counts, spread = sums[k].astype(float), np.full((len(k), 2, 2), np.nan)
    if streaks is not None and len(k):
        st = np.asarray(streaks, dtype=float)[p]
        use = ((np.hypot(st[:, 0], st[:, 1]) >= 2.0 * sigma) & np.isfinite(x)).nonzero()[0]
        gx, gy, gc, gb, gs = streak_centroids(
            sub[p[use]], x[use], y[use], streaks=st[use], radius=2.5 * sigma + 1.0
        )
        fin = np.isfinite(gx)
        got = use[fin]
        x[got], y[got], counts[got] = gx[fin], gy[fin], gc[fin]
        box[got], spread[got] = gb[fin], gs[fin]
        # a streak running off the frame: its centroid is pulled inwards
        off = np.zeros(len(k), bool)
        off[got] = ~_inside(x[got] + c0[p[got]], y[got] + r0[p[got]], st[got], sigma, shape)
    else:
        off = np.zeros(len(k), bool)
    fine = (np.isfinite(x) & ~off).nonzero()[0]
    pf, kf = p[fine], k[fine]
    offset = columns(r0[pf], r0[pf], c0[pf], c0[pf])  # window -> frame
    rows = (
        x[fine] + c0[pf],
        y[fine] + r0[pf],
        counts[fine],
        sizes[kf],
        peaks[kf],
        box[fine] + offset,
        spread[fine],
    )
    return rows, n


def union_area_numpy(boxes: np.ndarray) -> int:
    """Return the pixels covered by the union of boxes (row0, row1, col0, col1), in NumPy.

    The box edges cut the plane into cells (at most 2K x 2K for K boxes); each box marks the
    cells it spans, and the areas of the marked cells are summed.
    """
    boxes = np.asarray(boxes, dtype=int)
    if len(boxes) == 0:
        return 0
    rows, cols = _edges(boxes[:, :2]), _edges(boxes[:, 2:])
    i, j = rows.searchsorted(boxes[:, :2]), cols.searchsorted(boxes[:, 2:])
    covered = np.zeros((len(rows) - 1, len(cols) - 1), bool)
    for (i0, i1), (j0, j1) in zip(i.tolist(), j.tolist(), strict=True):
        covered[i0:i1, j0:j1] = True
    area = (rows[1:] - rows[:-1])[:, None] * (cols[1:] - cols[:-1])
    return int(area[covered].sum())


def _edges(values: np.ndarray) -> np.ndarray:
    """Return the distinct values, ascending (``np.unique`` without its overheads)."""
    v = values.flatten()  # a copy, sorted in place
    v.sort()
    first = np.empty(len(v), bool)
    first[0] = True
    np.not_equal(v[1:], v[:-1], out=first[1:])
    return v[first]


def union_area_compiled(boxes: np.ndarray) -> int | None:
    """:func:`union_area_numpy` in the compiled kernel (the same integer arithmetic).

    Returns None where the kernel is not built.
    """
    if _windowc is None:
        return None
    boxes = np.ascontiguousarray(boxes, dtype=np.int64).reshape(-1, 4)
    return _windowc.union_area(boxes, len(boxes))


def count_inside_numpy(boxes: np.ndarray, x, y) -> int:
    """Return how many positions (x, y), px, rounded (``np.rint``), lie in one of the boxes.

    Parameters
    ----------
    boxes : ndarray of int, shape (K, 4)
        Row0, row1, col0, col1 (half-open) of each box.
    x, y : array_like, shape (N,)
        Positions, px (x = column, y = row); NaN lies in none.

    Returns
    -------
    int
    """
    xi = np.rint(np.asarray(x, dtype=float))[:, None]
    yi = np.rint(np.asarray(y, dtype=float))[:, None]
    r0, r1, c0, c1 = np.asarray(boxes).T
    inside = (yi >= r0) & (yi < r1) & (xi >= c0) & (xi < c1)
    return int(np.count_nonzero(inside.any(axis=1)))


def count_inside_compiled(boxes: np.ndarray, x, y) -> int | None:
    """:func:`count_inside_numpy` in the compiled kernel (the same comparisons); None if unbuilt."""
    if _windowc is None:
        return None
    x = np.ascontiguousarray(x, dtype=float)
    return _windowc.count_inside(
        np.ascontiguousarray(boxes, dtype=np.int64),
        x,
        np.ascontiguousarray(y, dtype=float),
        len(boxes),
        len(x),
    )


def apart_numpy(x: np.ndarray, y: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Return the positions in ``order`` of the rows kept at least 2 px from those kept before.

    The rows are taken in ``order`` (e.g. brightest first); one is kept when it lies at least
    2 px (``math.hypot``) from every row kept before it.

    Parameters
    ----------
    x, y : ndarray, shape (N,)
        Positions, px.
    order : ndarray of int, shape (N,)
        The order in which the rows are taken.

    Returns
    -------
    ndarray of int, shape (M,)
        Positions in ``order`` (ascending).
    """
    xs, ys = x[order].tolist(), y[order].tolist()
    keep: list[int] = []
    for i in range(len(xs)):
        xi, yi = xs[i], ys[i]
        for j in keep:
            if not math.hypot(xi - xs[j], yi - ys[j]) >= 2.0:
                break
        else:
            keep.append(i)
    return np.array(keep, dtype=np.intp)


def apart_compiled(x: np.ndarray, y: np.ndarray, order: np.ndarray) -> np.ndarray | None:
    """:func:`apart_numpy` in the compiled kernel (the same ``hypot``); None where not built."""
    if _windowc is None:
        return None
    keep = np.empty(len(order), np.int64)
    m = _windowc.apart(
        np.ascontiguousarray(x, dtype=float),
        np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(order, dtype=np.int64),
        len(order),
        keep,
    )
    return keep[:m]


def detect_stack_compiled(image, size, *, corners, level, threshold, logic, sigma_px, streaks):
    """:func:`detect_stack_numpy` in the compiled kernel, the windows cut from the frame there.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame, counts.
    size : (int, int)
        The windows' rows and columns (h, w).
    corners : (ndarray of int, ndarray of int), shape (K,) each
        Each window's first row and column, px (the window inside the frame).
    level, threshold, logic, sigma_px, streaks
        As :func:`detect_stack_numpy` (``level`` and ``threshold`` (K,) or (1,)).

    Returns
    -------
    (rows, n) as :func:`detect_stack_numpy`, or None where the kernel is not built or does not
    read the frame's pixel type.
    """
    fmt = _KERNEL_TYPES.get(image.dtype.str) if _windowc is not None else None
    if fmt is None:
        return None
    image = np.ascontiguousarray(image)
    r0, c0 = corners
    k, (h, w) = len(r0), size
    level, threshold = (
        np.full(k, v[0], np.float32) if len(v) == 1 else np.ascontiguousarray(v, np.float32)
        for v in (level, threshold)
    )
    eight = logic.connectivity != 4
    # at most one region per 2 x 2 pixels (8-connected) or per 2 pixels (4-connected)
    cap = k * (((h + 1) // 2) * ((w + 1) // 2) if eight else (h * w + 1) // 2)
    out = scratch("window_rows", (max(cap, 1), _NCOL), np.float64)
    st = _NO_STREAKS if streaks is None else np.ascontiguousarray(streaks, dtype=float)
    n, m = _windowc.detect_windows(
        image,
        fmt,
        image.shape[0],
        image.shape[1],
        np.ascontiguousarray(r0, dtype=np.int64),
        np.ascontiguousarray(c0, dtype=np.int64),
        k,
        h,
        w,
        level,
        threshold,
        4 if not eight else 8,
        int(logic.min_pixels),
        float(logic.min_integrated_counts),
        2,
        st,
        streaks is not None,
        float(sigma_px),
        out,
        len(out),
    )
    if n == 0:
        return NO_ROWS, 0
    o = out[:m].copy()  # nothing returned is the scratch buffer: views of one copy
    rows = (
        o[:, 0],
        o[:, 1],
        o[:, 2],
        o[:, 3].astype(np.intp),
        o[:, 4],
        o[:, 5:9].astype(np.intp),
        o[:, 9:13].reshape(m, 2, 2),
    )
    return rows, n


#: No detection rows: x, y, counts, pixels, peak, box (row0, row1, col0, col1), spread.
NO_ROWS = (
    np.zeros(0),
    np.zeros(0),
    np.zeros(0),
    np.zeros(0, int),
    np.zeros(0),
    np.zeros((0, 4), int),
    np.zeros((0, 2, 2)),
)
