"""Window detection for tracking: look for stars only where the prior attitude puts them.

A tracker that knows where its stars are reads out small windows around them instead of the
whole frame; here the detector runs on a window around each of the brightest database stars
predicted on the detector. A window's half-width covers the search radius (the prior's
uncertainty), half the streak the body rate draws in one exposure, and the PSF with the
centroid margin. When the windows would cover more than a quarter of the frame the whole frame
is searched instead.

With a known background (simulated frames) each window uses the sensor's own detection logic
on its bias; otherwise each window's background is the median of its two-pixel border and its
noise the border's scaled median absolute deviation (sky around the star), with a sigma
threshold (:class:`WindowDetector`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from starsense.detect.clip import MAD_TO_SIGMA
from starsense.detect.streak import columns, kept_arange, streak_centroids, windows_view
from starsense.detect.threshold import Detections, StarDetector

if TYPE_CHECKING:
    from starsense.sensor import Detector

__all__ = ["WindowDetections", "WindowDetector", "streak_px", "union_area"]

#: Windows covering more than this fraction of the frame: search the whole frame.
MAX_WINDOW_FRACTION = 0.25
#: scipy's 2-D structuring elements, 8- and 4-connected (indexed by ``connectivity == 4``).
_STRUCTURES = (ndimage.generate_binary_structure(2, 2), ndimage.generate_binary_structure(2, 1))


@dataclass(frozen=True)
class WindowDetections:
    """Detections from the windows (or the whole frame), and where they were searched.

    Attributes
    ----------
    detections : Detections
        Merged, in frame pixel coordinates, brightest first.
    n_windows : int
        Windows searched (0: the whole frame).
    region_px : int
        Pixels searched (the union of the windows).
    boxes : ndarray of int, shape (K, 4) or None
        Row0, row1, col0, col1 (half-open) of each window (None: the whole frame).
    """

    detections: object
    n_windows: int
    region_px: int
    boxes: np.ndarray | None = None

    def count_inside(self, x, y) -> int:
        """Return how many of the positions (x, y), px, lie in a window (-1: whole frame)."""
        if self.boxes is None:
            return -1
        xi = np.rint(np.asarray(x, dtype=float))[:, None]
        yi = np.rint(np.asarray(y, dtype=float))[:, None]
        r0, r1, c0, c1 = self.boxes.T
        inside = (yi >= r0) & (yi < r1) & (xi >= c0) & (xi < c1)
        return int(np.count_nonzero(inside.any(axis=1)))


def union_area(boxes: np.ndarray) -> int:
    """Return the pixels covered by the union of boxes (row0, row1, col0, col1), exactly.

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


def streak_px(sensor, rate_rad_s, vectors_cam=None) -> np.ndarray | float:
    """Return the streak length a body rate draws in one exposure, px.

    The image of direction ``b`` moves at ``-w x b`` (camera frame); its length over the
    exposure is ``t_e f |(w x b)_xy|`` to first order (pinhole).

    Parameters
    ----------
    sensor : Sensor
    rate_rad_s : array_like, shape (3,)
        Body rate, camera frame, rad/s.
    vectors_cam : array_like, shape (N, 3), optional
        Star directions; default the farthest field corner (the longest streak).

    Returns
    -------
    float or ndarray, shape (N,)
    """
    w = np.zeros(3) if rate_rad_s is None else np.asarray(rate_rad_s, dtype=float)
    scale = sensor.exposure_s * sensor.focal_length_px
    if vectors_cam is None:
        hx, hy = sensor.half_fov_rad
        tx, ty = math.tan(hx), math.tan(hy)
        b = np.array([[-tx, -ty, 1.0], [-tx, ty, 1.0], [tx, -ty, 1.0], [tx, ty, 1.0]])
        b /= math.sqrt(tx * tx + ty * ty + 1.0)
        return float(np.max(scale * _cross_xy(w, b)))
    return scale * _cross_xy(w, np.asarray(vectors_cam, dtype=float))


def _cross_xy(w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Length of the x, y part of the cross product w x b of each row of b, shape (N,)."""
    cx = w[1] * b[:, 2] - w[2] * b[:, 1]
    cy = w[2] * b[:, 0] - w[0] * b[:, 2]
    return np.hypot(cx, cy)


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


def _label(lit: np.ndarray, connectivity: int):
    """Label the lit pixels of each window of the stack (K, h, w), never across windows.

    The labels of :func:`_lit_labels` put back on the stack (0 where unlit).
    """
    idx, lab, n = _lit_labels(lit, connectivity)
    labels = np.zeros(lit.shape, dtype=np.int32)
    labels.reshape(-1)[idx] = lab
    return labels, n


def _stack(image: np.ndarray, centres_px: np.ndarray, half: int):
    """Square windows (K, h, w) around the centres, moved inside the frame; their corners.

    The windows keep the frame's type (counts as read).
    """
    rows, cols = image.shape
    h, w = min(2 * half + 1, rows), min(2 * half + 1, cols)
    cx = np.rint(centres_px[:, 0]).astype(int)
    cy = np.rint(centres_px[:, 1]).astype(int)
    r0 = np.minimum(np.maximum(cy - half, 0), rows - h)  # np.clip, without its overhead
    c0 = np.minimum(np.maximum(cx - half, 0), cols - w)
    # one gather from a strided view of every h x w window of the frame (no copy until here)
    windows = windows_view(image[None], (h, w))[0, r0, c0]
    return windows, r0, c0


def _levels(cfg: WindowDetector, stack: np.ndarray):
    """Background level, noise and lit threshold of each window, counts, shape (K,) each."""
    logic = cfg.detector.logic
    k = len(stack)
    if cfg.known_background:
        det = cfg.camera
        level = np.full(k, float(det.bias_counts))
        noise = np.full(k, det.read_noise_e * det.gain_counts_per_e)
        return level, noise, np.full(k, float(logic.lit_pixel_counts))
    # the window's border (two pixels wide): sky around the star, a fraction of the pixels
    border = np.concatenate(
        [
            stack[:, :2].reshape(k, -1),
            stack[:, -2:].reshape(k, -1),
            stack[:, 2:-2, :2].reshape(k, -1),
            stack[:, 2:-2, -2:].reshape(k, -1),
        ],
        axis=1,
    )
    level = np.median(border, axis=1)
    noise = MAD_TO_SIGMA * np.median(np.abs(border - level[:, None]), axis=1)
    threshold = np.maximum(float(logic.lit_pixel_counts), cfg.threshold_sigma * noise)
    return level, noise, threshold


def _below(threshold: np.ndarray) -> np.ndarray:
    """Return the largest float32 at most each threshold (float64), shape (K,).

    For float32 ``x``, ``x > t`` equals ``x > _below(t)``: comparing float32 counts with
    float32 thresholds, not float64 ones, halves the work.
    """
    t32 = threshold.astype(np.float32)
    up = t32 > threshold
    if up.any():
        t32[up] = np.nextafter(t32[up], np.float32(-np.inf))
    return t32


def _median_noise(cfg: WindowDetector, noise: np.ndarray) -> float:
    """Median noise of the windows, counts (with a known background, the detector's own)."""
    if cfg.known_background:  # every window has the same noise: that is the median
        return float(noise[0])
    return float(np.median(noise))


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


def _detect_stack(cfg: WindowDetector, stack, r0, c0, shape, streaks):
    """Apply the detection logic to every window at once; return frame-pixel detection rows.

    With a streak of at least 2 PSF sigmas the centroid is taken over the whole predicted
    streak (:func:`streak_centroids`), started from the region's CoG; else the CoG over the
    region's box plus a 2 px margin, as the full-frame detector does.
    """
    logic = cfg.detector.logic
    if not cfg.known_background:  # the border statistics in float32, as the frame's
        stack = stack.astype(np.float32)
    level, noise, threshold = _levels(cfg, stack)
    # counts less the level in float32 (the frame's integer counts are exact in it)
    if cfg.known_background:  # one level and threshold for all: scalars, no broadcast
        sub = stack.astype(np.float32)
        sub -= np.float32(level[0])
        lit = sub > _below(threshold[:1])[0]
    else:
        sub = np.subtract(stack, level[:, None, None].astype(np.float32), dtype=np.float32)
        lit = sub > _below(threshold)[:, None, None]
    idx, lab, n = _lit_labels(lit, logic.connectivity)
    if n == 0:
        return _NO_ROWS, _median_noise(cfg, noise), 0
    sizes = np.bincount(lab, minlength=n + 1)
    sums = np.bincount(lab, weights=sub.ravel()[idx], minlength=n + 1)
    values = stack.ravel()[idx].astype(np.float32)
    plane, extent, peak = _label_extents(idx, lab, sizes, values, stack.shape)
    peaks = np.concatenate([[-np.inf], peak])
    ok = (sizes >= logic.min_pixels) & (sums >= logic.min_integrated_counts)
    k, p, box = _regions(plane, extent, ok, r0, c0, shape, stack.shape[1:])
    sigma = float(cfg.camera.psf_sigma_px)
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
    return rows, _median_noise(cfg, noise), n


#: No detection rows: x, y, counts, pixels, peak, box (row0, row1, col0, col1), spread.
_NO_ROWS = (
    np.zeros(0),
    np.zeros(0),
    np.zeros(0),
    np.zeros(0, int),
    np.zeros(0),
    np.zeros((0, 4), int),
    np.zeros((0, 2, 2)),
)


def _detections(rows, noise: float, n_candidates: int, saturation):
    """Build Detections from :func:`_detect_stack` rows: brightest first, one per 2 px."""
    x, y, counts, n_pixels, peak, box, spread = rows
    order = np.argsort(-counts, kind="stable")
    xs, ys = x[order].tolist(), y[order].tolist()
    keep: list[int] = []
    for i in range(len(xs)):  # overlapping windows and pieces of one streak: the same centre
        xi, yi = xs[i], ys[i]
        for j in keep:
            if not math.hypot(xi - xs[j], yi - ys[j]) >= 2.0:
                break
        else:
            keep.append(i)
    sel = order[keep]
    peak = peak[sel].astype(float)
    return Detections(
        x=x[sel].astype(float),
        y=y[sel].astype(float),
        integrated_counts=counts[sel].astype(float),
        n_pixels=n_pixels[sel].astype(int),
        peak_counts=peak,
        saturated=peak >= saturation if saturation is not None else np.zeros(len(sel), bool),
        bbox=box[sel].astype(int).reshape(-1, 4),
        fit_ok=np.ones(len(sel), bool),
        n_candidates=int(n_candidates),
        noise_counts=noise,
        method="cog",
        extra={"spread_px2": spread[sel].astype(float).reshape(-1, 2, 2)},
    )


@dataclass(frozen=True)
class WindowDetector:
    """Configure, then call: detect stars in windows around predicted positions.

    ``WindowDetector(detector, camera, known_background=..., threshold_sigma=...)(image,
    centres_px, half_px=...)`` (module docstring).

    Attributes
    ----------
    detector : StarDetector
        The full-frame detector: its detection logic applies in each window, and it searches
        the whole frame when the windows would cover too much of it.
    camera : Detector
        The sensor's detector (bias, read noise, gain, PSF sigma, saturation).
    known_background : bool
        True: each window's level is the bias and its threshold the logic's lit-pixel counts
        (simulated frames); False: the border's median and scaled MAD, with
        ``threshold_sigma``.
    threshold_sigma : float
        Lit threshold over the window's noise, sigmas (with ``known_background`` False).
    """

    detector: StarDetector
    camera: Detector
    known_background: bool
    threshold_sigma: float

    def __call__(
        self, image: np.ndarray, centres_px: np.ndarray, *, half_px: int, streaks_px=None
    ) -> WindowDetections:
        """Detect stars in square windows around predicted positions (or in the whole frame).

        Parameters
        ----------
        image : ndarray, shape (rows, columns)
            The frame, counts.
        centres_px : ndarray, shape (K, 2)
            Predicted star positions (x = column, y = row), px, on the detector.
        half_px : int
            Half-width of each window, px.
        streaks_px : ndarray, shape (K, 2), optional
            Predicted streak (start to end) of each window's star, px: each detection is
            centroided over the whole streak
            (:func:`~starsense.detect.streak.streak_centroid`).

        Returns
        -------
        WindowDetections
        """
        rows, cols = image.shape
        n = len(centres_px)
        if n == 0 or n * (2 * half_px + 1) ** 2 > MAX_WINDOW_FRACTION * rows * cols:
            det = self.detector(image)
            return WindowDetections(det, 0, rows * cols, None)
        stack, r0, c0 = _stack(image, np.asarray(centres_px, dtype=float), half_px)
        found, noise, n_cand = _detect_stack(self, stack, r0, c0, image.shape, streaks_px)
        det = _detections(found, noise, n_cand, self.camera.saturation_counts)
        _, h, w = stack.shape
        boxes = columns(r0, r0 + h, c0, c0 + w)
        return WindowDetections(det, n, union_area(boxes), boxes)
