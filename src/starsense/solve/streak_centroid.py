"""Centre of gravity of a streaked star over the whole predicted streak (tracking).

A star smeared by the body rate over the exposure draws a segment; its centroid is taken over
the pixels within a radius (a few PSF sigmas) of that segment, centred on the current estimate,
and the segment moved there until it stays. :func:`streak_centroid` does one region;
:func:`streak_centroids` all regions of the tracking windows at once (the same masks, iteration
and stop rule, vectorised over the regions).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["streak_centroid", "streak_centroids"]


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


def streak_centroid(sub: np.ndarray, x: float, y: float, streak, radius: float):
    """Centre of gravity of a streak of known shape, started from a point on it.

    The CoG is taken over the pixels within ``radius`` of a segment of the predicted streak
    (start to end) centred on the current estimate, and the segment moved there, until it
    stays (at most 6 times). A faint streak breaks into pieces above the threshold, and a piece's
    own centroid is off the star's mid-exposure position by up to half the streak; this
    window, which spans the whole streak, is not.

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
    for _ in range(6):
        got = _segment_mask(sub.shape, x, y, streak, radius)
        if got is None:
            return out
        inside, (r0, r1, c0, c1) = got
        w = np.where(inside, sub[r0:r1, c0:c1], 0.0)
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


def _boxes(x, y, sx, sy, radius, shape):
    """Bounding boxes (row0, row1, col0, col1) of the segments' capsules on the plane, (R, 4)."""
    rows, cols = shape
    r0 = np.maximum(np.floor(y - np.abs(sy) - radius), 0)
    r1 = np.minimum(np.ceil(y + np.abs(sy) + radius) + 1, rows)
    c0 = np.maximum(np.floor(x - np.abs(sx) - radius), 0)
    c1 = np.minimum(np.ceil(x + np.abs(sx) + radius) + 1, cols)
    return np.column_stack([r0, r1, c0, c1]).astype(int)


def _capsules(x, y, sx, sy, length2, radius, box, shape):
    """Pixels within ``radius`` of each segment centred on (x, y), on one crop holding each box.

    Returns the mask (L, h, w) and the crops' columns (L, w) and rows (L, h), px (int); a
    crop is the box grown to the largest box's size (outside its box no pixel is in reach).
    """
    rows, cols = shape
    h, w = int(np.max(box[:, 1] - box[:, 0])), int(np.max(box[:, 3] - box[:, 2]))
    py = np.minimum(box[:, 0], rows - h)[:, None] + np.arange(h)
    px = np.minimum(box[:, 2], cols - w)[:, None] + np.arange(w)
    ax = px[:, None, :] - (x - sx)[:, None, None]
    ay = py[:, :, None] - (y - sy)[:, None, None]
    a2x, a2y = (2 * sx)[:, None, None], (2 * sy)[:, None, None]
    # clamped to the segment (np.clip's result, without its overhead)
    t = np.minimum(np.maximum((ax * a2x + ay * a2y) / length2[:, None, None], 0.0), 1.0)
    return (ax - t * a2x) ** 2 + (ay - t * a2y) ** 2 <= radius * radius, px, py


def streak_centroids(planes: np.ndarray, x, y, streaks, radius: float):
    """:func:`streak_centroid` of many regions at once (each on its own plane).

    The capsule around the segment lies inside its bounding box, so the mask is taken over the
    whole plane; every region iterates until it stays (at most 6 times), as one would alone.

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
    out_x, out_y, total = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    boxes, spread = np.zeros((n, 4), dtype=int), np.full((n, 2, 2), np.nan)
    last_x, last_y = np.full(n, np.nan), np.full(n, np.nan)  # where the kept capsule was
    live = np.arange(n)
    for _ in range(6):
        box = _boxes(x[live], y[live], sx[live], sy[live], radius, (rows, cols))
        some = (box[:, 0] < box[:, 1]) & (box[:, 2] < box[:, 3])
        live, box = live[some], box[some]
        if len(live) == 0:
            break
        inside, px, py = _capsules(x[live], y[live], sx[live], sy[live], length2[live], radius,
                                   box, (rows, cols))  # fmt: skip
        wt = np.where(inside, planes[live[:, None, None], py[:, :, None], px[:, None, :]], 0.0)
        tot = wt.sum(axis=(1, 2)).astype(float)
        good = tot > 0
        live, box, wt, tot = live[good], box[good], wt[good], tot[good]
        nx = np.einsum("kj,kj->k", wt.sum(axis=1), px[good].astype(float)) / tot
        ny = np.einsum("ki,ki->k", wt.sum(axis=2), py[good].astype(float)) / tot
        out_x[live], out_y[live], total[live], boxes[live] = nx, ny, tot, box
        last_x[live], last_y[live] = x[live], y[live]
        moving = np.hypot(nx - x[live], ny - y[live]) >= 0.01
        x[live], y[live] = nx, ny
        live = live[moving]
        if len(live) == 0:
            break
    done = np.flatnonzero(np.isfinite(out_x))
    if len(done):  # the spread about the centroid over the capsule it was taken from
        inside, px, py = _capsules(last_x[done], last_y[done], sx[done], sy[done],
                                   length2[done], radius, boxes[done], (rows, cols))  # fmt: skip
        dx = np.where(inside, px[:, None, :] - out_x[done, None, None], 0.0)
        dy = np.where(inside, py[:, :, None] - out_y[done, None, None], 0.0)
        sxy = np.einsum("kij,kij->k", dx, dy)
        sxx, syy = np.einsum("kij,kij->k", dx, dx), np.einsum("kij,kij->k", dy, dy)
        spread[done] = np.stack([sxx, sxy, sxy, syy], axis=1).reshape(-1, 2, 2)
    return out_x, out_y, total, boxes, spread
