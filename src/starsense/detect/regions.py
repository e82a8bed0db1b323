"""Boxes, peaks and centres of gravity of many detected regions at once (no loop over stars).

The centroid of a detection (:mod:`starsense.detect.threshold`) is the CoG of the
background-subtracted window around it: its box (the bounding box of its pixels above the raw
threshold where it has any, else of all its lit pixels) grown by the margin and cut at the
frame's edges. A frame holds tens to hundreds of stars, and a Python loop that slices a window
and calls :func:`~starsense.detect.centroid.cog` per star costs more than finding them. Here
every window is laid out as one ragged list of pixels (region, row, column), and the sums of the
CoG are ``np.bincount`` over it: the same windows, weights and fallbacks as the per-star
:func:`~starsense.detect.centroid.cog`, equal to it to within float64 rounding of the sums.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

try:
    import starsense.detect._framec as _framec
except ImportError:  # built without a C compiler: the NumPy form below
    _framec = None

__all__ = ["label_pixels", "region_centroids"]


def label_pixels(idx: np.ndarray, shape: tuple[int, int], connectivity: int = 8):
    """Label the connected regions of a sparse set of pixels (``scipy.ndimage.label``'s labels).

    A frame's lit pixels are a small fraction of it (~0.1 % on the ESA frames): instead of
    scanning the whole frame, each lit pixel looks for its forward neighbours (right, below,
    and the two lower diagonals for 8-connectivity) among the lit pixels by binary search, and
    the regions are the connected components of that graph. They are numbered 1..n in the
    order of their first pixel in raster order, as ``scipy.ndimage.label`` numbers them.

    Parameters
    ----------
    idx : ndarray of int, shape (P,)
        Flat indices of the pixels, ascending (``np.flatnonzero`` of a mask).
    shape : (rows, columns)
        Frame shape.
    connectivity : {4, 8}

    Returns
    -------
    labels : ndarray of int32, shape (P,)
        Region of each pixel, 1..n.
    n : int
        Number of regions.
    """
    p = idx.size
    if p == 0:
        return np.zeros(0, np.int32), 0
    if _framec is not None:
        # union-find over each pixel's neighbours to the left and above (_framec.c): the
        # same regions, numbered the same way
        labels = np.empty(p, np.int32)
        n = _framec.label(
            np.ascontiguousarray(idx, dtype=np.int64), p, shape[1], connectivity, labels
        )
        return labels, int(n)
    return _label_pixels_numpy(idx, shape, connectivity)


def _label_pixels_numpy(idx: np.ndarray, shape: tuple[int, int], connectivity: int = 8):
    """:func:`label_pixels` by sparse-graph connected components, in NumPy/SciPy."""
    p = idx.size
    rows, cols = shape
    r, c = np.divmod(idx, cols)
    offsets = [(0, 1), (1, 0)] + ([(1, -1), (1, 1)] if connectivity == 8 else [])
    src, dst = [], []
    for dr, dc in offsets:
        inside = (r + dr < rows) & (c + dc >= 0) & (c + dc < cols)
        where = np.flatnonzero(inside)
        target = idx[where] + (dr * cols + dc)
        pos = np.searchsorted(idx, target)
        hit = pos < p
        hit[hit] = idx[pos[hit]] == target[hit]
        src.append(where[hit])
        dst.append(pos[hit])
    i, j = np.concatenate(src), np.concatenate(dst)
    graph = coo_array((np.ones(i.size, np.int8), (i, j)), shape=(p, p)).tocsr()
    n, comp = connected_components(graph, directed=False)
    # number the regions by their first pixel (the pixels are in raster order)
    _, first = np.unique(comp, return_index=True)
    rank = np.empty(n, np.int32)
    rank[np.argsort(first, kind="stable")] = np.arange(1, n + 1, dtype=np.int32)
    return rank[comp], int(n)


def _extent(key: np.ndarray, r: np.ndarray, c: np.ndarray, n: int):
    """Bounding boxes (row0, row1, col0, col1; half-open) of the pixels of each key 0..n-1."""
    big = np.iinfo(np.intp).max
    r0, c0 = np.full(n, big, np.intp), np.full(n, big, np.intp)
    r1, c1 = np.full(n, -1, np.intp), np.full(n, -1, np.intp)
    np.minimum.at(r0, key, r)
    np.minimum.at(c0, key, c)
    np.maximum.at(r1, key, r)
    np.maximum.at(c1, key, c)
    return r0, r1 + 1, c0, c1 + 1


def _ragged(r0, r1, c0, c1):
    """Every pixel of every box: (box index, row, column), boxes one after another."""
    h, w = r1 - r0, c1 - c0
    sizes = h * w
    box = np.repeat(np.arange(sizes.size), sizes)
    local = np.arange(box.size) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    dr, dc = np.divmod(local, w[box])
    return box, r0[box] + dr, c0[box] + dc


def _cog(box, rows, cols, weights, n):
    """(x, y) CoG of the pixels of each box 0..n-1; NaN where the weights do not sum above 0."""
    total = np.bincount(box, weights=weights, minlength=n)
    sx = np.bincount(box, weights=weights * cols, minlength=n)
    sy = np.bincount(box, weights=weights * rows, minlength=n)
    ok = total > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        x = np.where(ok, sx / total, np.nan)
        y = np.where(ok, sy / total, np.nan)
    return x, y


#: the most window pixels whose CoG is taken at once: the windows of a frame's regions can
#: cover it many times over (hundreds of long, crossing streaks), and the pixel lists of all
#: of them at once would take gigabytes; chunks of this many pixels take ~40 MB
_CHUNK_PIXELS = 1 << 20


def _window_cogs(sub, windows, power: int):
    """(x, y) CoG of ``sub`` over each window (row0, row1, col0, col1 arrays), in chunks."""
    wr0, wr1, wc0, wc1 = windows
    n = wr0.size
    x, y = np.full(n, np.nan), np.full(n, np.nan)
    ends = np.cumsum((wr1 - wr0) * (wc1 - wc0))
    start = 0
    while start < n:
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + _CHUNK_PIXELS, side="right")))
        part = slice(start, stop)
        box, rows, cols = _ragged(wr0[part], wr1[part], wc0[part], wc1[part])
        w = sub[rows, cols].astype(np.float64)
        if power != 1:
            w = np.maximum(w, 0.0) ** power
        x[part], y[part] = _cog(box, rows, cols, w, stop - start)
        start = stop
    return x, y


def region_centroids(sub, a, *, idx, lab, keep, core, margin: int, power: int = 1):
    """Box, peak and CoG of each kept region, in the order of ``keep``.

    Parameters
    ----------
    sub : ndarray, shape (rows, columns), float32
        Background-subtracted frame, counts.
    a : ndarray, shape (rows, columns)
        The raw frame (for the peaks), counts.
    idx : ndarray of int, shape (P,)
        Flat indices of the lit pixels.
    lab : ndarray of int, shape (P,)
        Their region labels (1..n).
    keep : ndarray of int, shape (N,)
        Labels of the regions to measure, in output order.
    core : ndarray of bool, shape (P,), or None
        Which lit pixels are above the raw threshold: the box is the bounding box of a region's
        lit pixels that are also core pixels, where it has any (matched filter); None for the
        lit pixels.
    margin : int
        Pixels added to each side of the box for the CoG window (cut at the frame's edges).
    power : {1, 2}
        1: CoG of the window's counts; 2: of their squares, negative counts set to 0 (iwcog).

    Returns
    -------
    x, y : ndarray (N,)
        Centroids, pixels (pixel-centre convention). A window whose counts do not sum above 0,
        or whose CoG lies outside the window, falls back to the CoG of the region's lit pixels
        inside its box; NaN if that fails too.
    peaks : ndarray (N,)
        Largest raw count of the region's lit pixels inside its box.
    boxes : ndarray of int, shape (N, 4)
        row0, row1, col0, col1 (half-open).
    ok : ndarray of bool (N,)
        The window CoG succeeded (False where the fallback was used).
    """
    n_rows, n_cols = sub.shape
    n = keep.size
    slot = np.full(int(lab.max(initial=0)) + 1, -1, np.intp)
    slot[keep] = np.arange(n)
    pos = slot[lab]
    mine = pos >= 0
    idx, pos = idx[mine], pos[mine]
    r, c = np.divmod(idx, n_cols)
    r0, r1, c0, c1 = _extent(pos, r, c, n)
    if core is not None:
        in_core = core[mine]
        k0, k1, j0, j1 = _extent(pos[in_core], r[in_core], c[in_core], n)
        has = k1 > 0
        r0, r1 = np.where(has, k0, r0), np.where(has, k1, r1)
        c0, c1 = np.where(has, j0, c0), np.where(has, j1, c1)
    inside = (r >= r0[pos]) & (r < r1[pos]) & (c >= c0[pos]) & (c < c1[pos])
    peaks = np.full(n, -np.inf)
    np.maximum.at(peaks, pos[inside], a.ravel()[idx[inside]].astype(np.float64))
    wr0, wr1 = np.maximum(r0 - margin, 0), np.minimum(r1 + margin, n_rows)
    wc0, wc1 = np.maximum(c0 - margin, 0), np.minimum(c1 + margin, n_cols)
    x, y = _window_cogs(sub, (wr0, wr1, wc0, wc1), power)
    # a window CoG outside its window is no centroid: a faint window summing to barely above 0
    # (noise of both signs) divides by almost nothing
    with np.errstate(invalid="ignore"):
        ok = (x >= wc0 - 0.5) & (x < wc1 - 0.5) & (y >= wr0 - 0.5) & (y < wr1 - 0.5)
    if not ok.all():
        # a faint region whose window sums to <= 0 (noise), or whose CoG left its window: the
        # CoG of its lit pixels in its box
        fx, fy = _cog(pos[inside], r[inside], c[inside], sub.ravel()[idx[inside]].astype(float), n)
        x, y = np.where(ok, x, fx), np.where(ok, y, fy)
    boxes = np.stack([r0, r1, c0, c1], axis=1).astype(int)
    return x, y, peaks, boxes, ok
