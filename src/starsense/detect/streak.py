"""Centre of gravity of a streaked star over the whole predicted streak (tracking).

A star smeared by the body rate over the exposure draws a segment; its centroid is taken over
the pixels within a radius (a few PSF sigmas) of that segment, centred on the current estimate,
and the segment moved there until it stays. :func:`streak_centroid` does one region;
:func:`streak_centroids` all regions of the tracking windows at once (the same masks, iteration
and stop rule, vectorised over the regions). :func:`streak_axes` measures a streak's length and
direction from the second moments of its lit pixels (a smeared frame's rate, and whether a frame
is smeared at all).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from starsense.detect.clip import MAD_TO_SIGMA
from starsense.detect.row_stats import row_nanmedian

__all__ = [
    "SYSTEMATIC",
    "WINDOW_PIXELS",
    "columns",
    "kept_arange",
    "streak_axes",
    "streak_centroid",
    "streak_centroids",
    "windows_view",
]

#: Float64 zero: ``np.where(mask, float32 counts, _ZERO)`` is float64, so the sums over a
#: capsule are float64 sums (a Python 0.0 would leave them float32, rounding past 2^24 counts)
_ZERO = np.float64(0.0)
#: 0, 1, 2, ...: the rows and columns of a crop (larger crops make their own)
_ARANGE = {int: np.arange(4096), float: np.arange(4096.0)}


#: the most times a capsule is moved to its centre of gravity (streak_centroids)
ITERATIONS = 6


def columns(*arrays: np.ndarray) -> np.ndarray:
    """Return the 1-D arrays (N,) as the columns of one (N, K) array (``np.stack(axis=1)``).

    Without ``np.stack``'s argument handling: these are called once or more per tracked frame.
    """
    out = np.empty((len(arrays[0]), len(arrays)), dtype=np.result_type(*arrays))
    for j, a in enumerate(arrays):
        out[:, j] = a
    return out


def kept_arange(n: int, dtype=int) -> np.ndarray:
    """Return ``np.arange(n)`` of int or float (a slice of a kept one up to 4096).

    Parameters
    ----------
    n : int
        Length.
    dtype : {int, float}
        Element type.

    Returns
    -------
    ndarray, shape (n,)
        Read-only when sliced from the kept array: do not write into it.
    """
    kept = _ARANGE[dtype]
    return kept[:n] if n <= len(kept) else np.arange(n, dtype=dtype)


def _segment_mask(shape, x, y, streak, radius):
    """Pixels of ``shape`` within ``radius`` px of the segment centred on (x, y), its box."""
    sx, sy = 0.5 * float(streak[0]), 0.5 * float(streak[1])
    rows, cols = shape
    r0 = max(math.floor(y - abs(sy) - radius), 0)
    r1 = min(math.ceil(y + abs(sy) + radius) + 1, rows)
    c0 = max(math.floor(x - abs(sx) - radius), 0)
    c1 = min(math.ceil(x + abs(sx) + radius) + 1, cols)
    if r0 >= r1 or c0 >= c1:
        return None
    ax = np.arange(c0, c1, dtype=float)[None, :] - (x - sx)
    ay = np.arange(r0, r1, dtype=float)[:, None] - (y - sy)
    length2 = 4.0 * (sx * sx + sy * sy)
    t = np.clip((ax * 2 * sx + ay * 2 * sy) / max(length2, 1e-12), 0.0, 1.0)
    inside = (ax - t * 2 * sx) ** 2 + (ay - t * 2 * sy) ** 2 <= radius * radius
    return inside, (r0, r1, c0, c1)


def streak_centroid(sub: np.ndarray, x: float, y: float, *, streak, radius: float):
    """Centre of gravity of a streak of known shape, started from a point on it.

    The CoG is taken over the pixels within ``radius`` of a segment of the predicted streak
    (start to end) centred on the current estimate, and the segment moved there, until it
    stays (at most ``ITERATIONS`` times). A faint streak breaks into pieces above the
    threshold, and a piece's own centroid is off the star's mid-exposure position by up to
    half the streak; this window, which spans the whole streak, is not.

    Parameters
    ----------
    sub : ndarray, shape (rows, columns)
        Background-subtracted counts of the window.
    x, y : float
        Starting point (a piece's centroid), px in the window.
    streak : (float, float)
        Predicted streak, start to end, px.
    radius : float
        Half-width of the window across the streak, px (a few PSF sigmas).

    Returns
    -------
    (x, y, counts, (r0, r1, c0, c1), spread) or None
        The centroid, px, the counts summed over the window, the window's bounding box, and
        the 2 x 2 sum over the window of (pixel - centroid)(pixel - centroid)^T, px^2 (a read
        noise sigma_r adds sigma_r^2 spread / counts^2 to the centroid's covariance).
    """
    out = None
    for _ in range(ITERATIONS):
        got = _segment_mask(sub.shape, x, y, streak, radius)
        if got is None:
            return out
        inside, (r0, r1, c0, c1) = got
        w = np.where(inside, sub[r0:r1, c0:c1], _ZERO)
        total = float(w.sum())
        if not total > 0:
            return out
        px = np.arange(c0, c1, dtype=float)
        py = np.arange(r0, r1, dtype=float)
        nx, ny = float(w.sum(axis=0) @ px / total), float(w.sum(axis=1) @ py / total)
        rr, cc = np.nonzero(inside)
        dx, dy = px[cc] - nx, py[rr] - ny
        spread = np.array([[dx @ dx, dx @ dy], [dx @ dy, dy @ dy]])
        out = (nx, ny, total, (r0, r1, c0, c1), spread)
        if math.hypot(nx - x, ny - y) < 0.01:
            break
        x, y = nx, ny
    return out


def windows_view(planes: np.ndarray, size) -> np.ndarray:
    """Read-only view (K, rows - h + 1, columns - w + 1, h, w) of every h x w window of planes.

    ``numpy.lib.stride_tricks.sliding_window_view`` over the last two axes, without its
    argument handling (a gather ``view[k, r0, c0]`` then copies only the windows wanted).
    """
    k, rows, cols = planes.shape
    h, w = size
    s0, s1, s2 = planes.strides
    shape, strides = (k, rows - h + 1, cols - w + 1, h, w), (s0, s1, s2, s1, s2)
    if not planes.flags.c_contiguous:
        return np.lib.stride_tricks.as_strided(planes, shape, strides, writeable=False)
    # a contiguous array's own buffer, viewed directly (as_strided's array-interface detour
    # costs more than the view)
    view = np.ndarray(shape, planes.dtype, buffer=planes, strides=strides)
    view.flags.writeable = False
    return view


def _boxes(x, y, sx, sy, radius, shape):
    """Bounding boxes (row0, row1, col0, col1) of the segments' capsules on the plane, (R, 4)."""
    rows, cols = shape
    r0 = np.maximum(np.floor(y - np.abs(sy) - radius), 0)
    r1 = np.minimum(np.ceil(y + np.abs(sy) + radius) + 1, rows)
    c0 = np.maximum(np.floor(x - np.abs(sx) - radius), 0)
    c1 = np.minimum(np.ceil(x + np.abs(sx) + radius) + 1, cols)
    return np.column_stack([r0, r1, c0, c1]).astype(int)


def _capsules(x, y, sx, sy, length2, radius, r0, c0, size):
    """Pixels within ``radius`` of each segment centred on (x, y), on a crop of each plane.

    The crops are ``size`` (h, w) px from rows ``r0`` and columns ``c0`` (L,), each holding
    the capsule's bounding box. Returns the mask (L, h, w) and the crops' columns (L, w) and
    rows (L, h), px (whole numbers, as floats). ``sx``, ``sy`` and ``length2`` are shaped
    (L, 1, 1).
    """
    py = r0[:, None] + kept_arange(size[0], float)  # float: exact pixel indices
    px = c0[:, None] + kept_arange(size[1], float)
    ax = px[:, None, :] - (x[:, None, None] - sx)
    ay = py[:, :, None] - (y[:, None, None] - sy)
    a2x, a2y = 2 * sx, 2 * sy
    # t = (a . a2) / |a2|^2 clamped to the segment; then |a - t a2|^2 (in place: no temporaries)
    t = ax * a2x + ay * a2y
    t /= length2
    np.maximum(t, 0.0, out=t)
    np.minimum(t, 1.0, out=t)
    ex = t * a2x
    np.subtract(ax, ex, out=ex)
    ex *= ex
    np.multiply(t, a2y, out=t)
    np.subtract(ay, t, out=t)
    t *= t
    t += ex
    return t <= radius * radius, px, py


def _origins(y_x, reach, limit):
    """First row and column of the crop of a given size holding each capsule's box, (L,) each.

    ``y_x`` (2, L) are the centres (rows, columns), ``reach`` (2, L) the capsules' half-spans
    and ``limit`` (2, 1) the plane's size less the crop's. A box (:func:`_boxes`) starts at
    ``floor(c - reach)`` (cut at 0) and spans at most ``ceil(2 reach) + 2`` px, which the crop
    covers: the crop starts with the box, or ends with the plane when the box reaches its far
    edge.
    """
    return np.minimum(np.maximum(np.floor(y_x - reach), 0), limit).astype(np.intp)


def streak_centroids(planes: np.ndarray, x, y, *, streaks, radius: float):
    """:func:`streak_centroid` of many regions at once (each on its own plane).

    The capsule around the segment lies inside its bounding box, so the mask is taken over a
    crop of the plane holding that box (one crop size for all regions and iterations); every
    region iterates until it stays (at most ``ITERATIONS`` times), as one would alone.

    Parameters
    ----------
    planes : ndarray, shape (R, rows, columns)
        Background-subtracted counts of each region's window.
    x, y : array_like, shape (R,)
        Starting points, px in the windows.
    streaks : array_like, shape (R, 2)
        Predicted streaks, start to end, px.
    radius : float
        Half-width across the streak, px.

    Returns
    -------
    x, y, counts : ndarray, shape (R,)
        Centroids, px, and counts summed over the capsule (NaN where no centroid was found).
    boxes : ndarray of int, shape (R, 4)
        Row0, row1, col0, col1 of each capsule's bounding box.
    spread : ndarray, shape (R, 2, 2)
        Sum over the capsule of (pixel - centroid)(pixel - centroid)^T, px^2.
    """
    planes = np.asarray(planes)
    n, rows, cols = planes.shape
    x, y = np.array(x, dtype=float), np.array(y, dtype=float)
    sx, sy = 0.5 * np.asarray(streaks, dtype=float).T
    length2 = np.maximum(4.0 * (sx * sx + sy * sy), 1e-12)
    # centroids, counts, and where the kept capsule was (NaN until found): rows of one array
    out_x, out_y, total, last_x, last_y = np.full((5, n), np.nan)
    boxes, spread = np.zeros((n, 4), dtype=int), np.full((n, 2, 2), np.nan)
    if n == 0:
        return out_x, out_y, total, boxes, spread
    reach_x, reach_y = np.abs(sx) + radius, np.abs(sy) + radius
    size = (
        min(math.ceil(2 * float(reach_y.max())) + 2, rows),
        min(math.ceil(2 * float(reach_x.max())) + 2, cols),
    )
    crops = windows_view(planes, size)
    # the capsule each centroid was taken over: its mask, columns and rows
    masks = np.zeros((n, *size), dtype=bool)
    cols_px, rows_px = np.zeros((n, size[1])), np.zeros((n, size[0]))
    reach = np.array([reach_y, reach_x])
    limit = np.array([[rows - size[0]], [cols - size[1]]])
    sx3, sy3, l3 = sx[:, None, None], sy[:, None, None], length2[:, None, None]
    y_x = np.array([y, x])  # where each capsule is centred: rows, columns
    live = np.arange(n)
    for _ in range(ITERATIONS):
        if len(live) == n:  # every region still moves: no selection of the constants
            yx, sxl, syl, l2, rch = y_x.copy(), sx3, sy3, l3, reach
        else:
            yx, sxl, syl, l2, rch = y_x[:, live], sx3[live], sy3[live], l3[live], reach[:, live]
        yl, xl = yx
        r0, c0 = _origins(yx, rch, limit)
        inside, px, py = _capsules(xl, yl, sxl, syl, l2, radius, r0, c0, size)
        # a capsule off its plane holds no pixel: no total, the region stops (as alone)
        wt = np.where(inside, crops[live, r0, c0], _ZERO)
        tot = np.add.reduce(wt, axis=(1, 2)).astype(float)  # wt.sum, without its wrapper
        good = tot > 0
        cut = not good.all()
        if cut:
            live, xl, yl, wt, tot = live[good], xl[good], yl[good], wt[good], tot[good]
            px, py = px[good], py[good]
        if len(live) == 0:
            break
        nx = np.einsum("kj,kj->k", np.add.reduce(wt, axis=1), px) / tot
        ny = np.einsum("ki,ki->k", np.add.reduce(wt, axis=2), py) / tot
        at = slice(None) if len(live) == n else live  # every region: plain copies
        out_x[at], out_y[at], total[at] = nx, ny, tot
        last_x[at], last_y[at] = xl, yl
        masks[at], cols_px[at], rows_px[at] = inside[good] if cut else inside, px, py
        y_x[0, at], y_x[1, at] = ny, nx
        live = live[np.hypot(nx - xl, ny - yl) >= 0.01]
        if len(live) == 0:
            break
    done = np.isfinite(out_x).nonzero()[0]
    if len(done):  # the spread about the centroid over the capsule it was taken from
        boxes[done] = _boxes(last_x[done], last_y[done], sx[done], sy[done], radius, (rows, cols))
        inside, px, py = masks[done], cols_px[done], rows_px[done]
        dx = np.where(inside, px[:, None, :] - out_x[done, None, None], 0.0)
        dy = np.where(inside, py[:, :, None] - out_y[done, None, None], 0.0)
        sxy = np.einsum("kij,kij->k", dx, dy)
        sxx, syy = np.einsum("kij,kij->k", dx, dx), np.einsum("kij,kij->k", dy, dy)
        spread[done] = columns(sxx, sxy, sxy, syy).reshape(-1, 2, 2)
    return out_x, out_y, total, boxes, spread


#: Relative error of a streak rate from the lit pixels' shortened ends (see rate_from_streaks)
SYSTEMATIC = 0.2
#: the most window pixels held at once (~32 MB of float64): a frame of 600 px streaks holds
#: 2 M pixels per star window
WINDOW_PIXELS = 1 << 22


def streak_axes(
    image,
    x,
    y,
    *,
    half_px: int,
    threshold: float,
    level: float | None = 0.0,
    threshold_sigma: float | None = None,
    bridge_px: float = 0.0,
) -> np.ndarray:
    """Return ``l l^T`` of the streak through each centroid, from its lit pixels, px^2.

    The streak is the 8-connected lit region nearest the centroid. A faint streak breaks into
    pieces where the noise takes its ridge below the threshold (gaps of a pixel or two); with
    ``bridge_px`` the lit pixels on its line are added to it: within ``bridge_px`` of the line
    through the region's second moments and at most ``bridge_px`` beyond its ends, repeated
    with the line refitted until none is added. Collinear pieces then measure as the whole
    streak they are part of.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame, counts.
    x, y : array_like, shape (N,)
        Centroids, px.
    half_px : int
        Half-width of the square window searched around each centroid, px.
    threshold : float
        Lit-pixel threshold above ``level``, counts (the detection logic's).
    level : float or None
        Background level, counts; None: the median of each window's border.
    threshold_sigma : float, optional
        With ``level`` None, the threshold is at least this many times the border's noise
        (scaled median absolute deviation).
    bridge_px : float
        Half-width of the band along the region's line whose lit pixels join it, and the
        longest gap bridged, px (0: the connected region only).

    Returns
    -------
    ndarray, shape (N, 2, 2)
        ``12 (lambda_1 - lambda_2) e e^T`` of the lit region at the centroid (x = column,
        y = row); NaN where no lit region holds the centroid. A window is cut at the frame's
        edges (a streak that runs off the frame measures as its part on it).
    """
    a = np.asarray(image)  # each window is read as float, not the whole frame
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    w = 2 * half_px + 1
    step = max(1, WINDOW_PIXELS // (w * w))
    if len(x) > step:  # chunks of windows: a frame of long streaks holds millions per star
        kw = dict(half_px=half_px, threshold=threshold, level=level)
        kw.update(threshold_sigma=threshold_sigma, bridge_px=bridge_px)
        return np.concatenate(
            [streak_axes(a, x[i : i + step], y[i : i + step], **kw) for i in range(0, len(x), step)]
        )
    out = np.full((len(x), 2, 2), np.nan)
    r0 = np.array([round(v) for v in y], dtype=np.int64) - half_px
    c0 = np.array([round(v) for v in x], dtype=np.int64) - half_px
    k = np.arange(len(x))
    if len(k) == 0:
        return out
    # every window at once: (K, w, w) float64, cut at the frame's edges (off it: NaN, unlit)
    ar = np.arange(w)
    rr, cc = r0[:, None] + ar[None, :], c0[:, None] + ar[None, :]
    on = ((rr >= 0) & (rr < a.shape[0]))[:, :, None] & ((cc >= 0) & (cc < a.shape[1]))[:, None, :]
    rr, cc = np.clip(rr, 0, a.shape[0] - 1), np.clip(cc, 0, a.shape[1] - 1)
    sub = a[rr[:, :, None], cc[:, None, :]].astype(float)
    sub[~on] = np.nan
    cut = np.full(len(k), float(threshold))
    if level is None:
        border = np.concatenate([sub[:, 0], sub[:, -1], sub[:, 1:-1, 0], sub[:, 1:-1, -1]], axis=1)
        base = row_nanmedian(border)  # NaN: a window with its whole border off the frame
        if threshold_sigma is not None:
            noise = MAD_TO_SIGMA * row_nanmedian(np.abs(border - base[:, None]))
            cut = np.maximum(cut, threshold_sigma * noise)
        sub -= base[:, None, None]
    else:
        sub -= level
    with np.errstate(invalid="ignore"):
        lit = sub > cut[:, None, None]
    # one labelling for all windows: 8-connected within a window, never across windows
    structure = np.zeros((3, 3, 3), bool)
    structure[1] = True
    labels, _ = ndimage.label(lit, structure=structure)
    # the lit pixel nearest the centroid (the first in row-major order among equals)
    dy = ar[None, :, None] - (y[k] - r0[k])[:, None, None]
    dx = ar[None, None, :] - (x[k] - c0[k])[:, None, None]
    dist = np.where(lit, np.hypot(dy, dx), np.inf).reshape(len(k), -1)
    near = np.argmin(dist, axis=1)
    ok = lit.reshape(len(k), -1).sum(axis=1) >= 3
    own = labels.reshape(len(k), -1)[np.arange(len(k)), near]
    mine = labels == own[:, None, None]
    total = np.where(mine, sub, 0.0).sum(axis=(1, 2))
    ok &= total != 0
    m = _moments(sub, mine, ar)
    if bridge_px > 0.0:
        m = _bridged(sub, lit, mine, m, ar, float(bridge_px))
    m = m[ok, :2]
    if len(m) == 0:
        return out
    lam, vec = np.linalg.eigh(m)
    e = vec[:, :, 1]
    out[k[ok]] = 12.0 * (lam[:, 1] - lam[:, 0])[:, None, None] * (e[:, :, None] * e[:, None, :])
    return out


def _moments(sub, mask, ar) -> np.ndarray:
    """Return the centroid (K, 2) and second moments (K, 2, 2) of ``sub`` over ``mask``.

    Packed as (K, 3, 2): rows 0-1 the moments (x = column, y = row), row 2 the centroid.
    """
    wgt = np.where(mask, sub, 0.0)
    total = wgt.sum(axis=(1, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (wgt * ar[None, None, :]).sum(axis=(1, 2)) / total
        cy = (wgt * ar[None, :, None]).sum(axis=(1, 2)) / total
        ddx = np.where(mask, ar[None, None, :] - cx[:, None, None], 0.0)
        ddy = np.where(mask, ar[None, :, None] - cy[:, None, None], 0.0)
        sxx = (wgt * ddx * ddx).sum(axis=(1, 2)) / total
        sxy = (wgt * ddx * ddy).sum(axis=(1, 2)) / total
        syy = (wgt * ddy * ddy).sum(axis=(1, 2)) / total
    return columns(sxx, sxy, sxy, syy, cx, cy).reshape(-1, 3, 2)


def _bridged(sub, lit, mine, m, ar, band: float) -> np.ndarray:
    """Return :func:`_moments` over ``mine`` and the lit pixels on its line (``bridge_px``).

    Only a region narrower than the band is a piece of a line: a faint streak's pieces are a
    PSF wide. A region that reaches the band's width across its own axis is a star's lit disc
    (a bright star at rest is lit several PSF sigmas out at a low threshold), the axis of its
    moments the noise's: bridged along it, it would take in a neighbour a band away in any
    direction and measure as a streak (a crowded field at rest read as smeared). A bright
    streak is whole: it needs no bridge.
    """
    for _ in range(64):  # each pass adds at least one pixel; a window holds few pieces
        good = np.isfinite(m).all(axis=(1, 2))
        vec = np.linalg.eigh(np.where(good[:, None, None], m[:, :2], np.eye(2)))[1][:, :, 1]
        ex, ey = vec[:, 0, None, None], vec[:, 1, None, None]
        dx = ar[None, None, :] - m[:, 2, 0, None, None]
        dy = ar[None, :, None] - m[:, 2, 1, None, None]
        along, across = dx * ex + dy * ey, dx * ey - dy * ex
        good &= np.where(mine, np.abs(across), 0.0).max(axis=(1, 2)) < band  # a line's piece
        lo = np.where(mine, along, np.inf).min(axis=(1, 2))[:, None, None]
        hi = np.where(mine, along, -np.inf).max(axis=(1, 2))[:, None, None]
        near = lit & (np.abs(across) <= band) & (along >= lo - band) & (along <= hi + band)
        grown = mine | (near & good[:, None, None])
        if not (grown != mine).any():
            return m
        mine = grown
        m = _moments(sub, mine, ar)
    return m
