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

The per-window work (cut-outs, threshold, labels, region sums, centroids) runs in the compiled
kernel where it is built, else in NumPy: the two forms give the same rows
(:mod:`starsense.detect.window_kernels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from starsense.detect.clip import MAD_TO_SIGMA
from starsense.detect.detections import Detections
from starsense.detect.streak import columns, windows_view
from starsense.detect.threshold import StarDetector
from starsense.detect.window_kernels import (
    apart_compiled,
    apart_numpy,
    count_inside_compiled,
    count_inside_numpy,
    detect_stack_compiled,
    detect_stack_numpy,
    float32_below,
    union_area_compiled,
    union_area_numpy,
)

if TYPE_CHECKING:
    from starsense.sensor import Detector

__all__ = ["WindowDetections", "WindowDetector", "streak_px", "union_area"]

#: Windows covering more than this fraction of the frame: search the whole frame.
MAX_WINDOW_FRACTION = 0.25


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
    compiled : bool
        Whether :meth:`count_inside` uses the compiled kernel where it is built.
    """

    detections: object
    n_windows: int
    region_px: int
    boxes: np.ndarray | None = None
    compiled: bool = True

    def count_inside(self, x, y) -> int:
        """Return how many of the positions (x, y), px, lie in a window (-1: whole frame).

        A position is rounded to its pixel (``np.rint``); in the compiled kernel where it is
        built and ``compiled``, else :func:`~starsense.detect.window_kernels.count_inside_numpy`.
        """
        if self.boxes is None:
            return -1
        got = count_inside_compiled(self.boxes, x, y) if self.compiled else None
        return count_inside_numpy(self.boxes, x, y) if got is None else got


def union_area(boxes: np.ndarray, *, compiled: bool = True) -> int:
    """Return the pixels covered by the union of boxes (row0, row1, col0, col1), exactly.

    The box edges cut the plane into cells (at most 2K x 2K for K boxes); each box marks the
    cells it spans, and the areas of the marked cells are summed (in the compiled kernel where
    it is built and ``compiled``, else :func:`~starsense.detect.window_kernels.union_area_numpy`).
    """
    got = union_area_compiled(boxes) if compiled else None
    return union_area_numpy(boxes) if got is None else got


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


def _corners(shape, centres_px: np.ndarray, half: int):
    """Return the corners of square windows around the centres, moved inside the frame.

    First rows and columns (K,) each, and the windows' size (h, w).
    """
    rows, cols = shape
    h, w = min(2 * half + 1, rows), min(2 * half + 1, cols)
    cx = np.rint(centres_px[:, 0]).astype(int)
    cy = np.rint(centres_px[:, 1]).astype(int)
    r0 = np.minimum(np.maximum(cy - half, 0), rows - h)  # np.clip, without its overhead
    c0 = np.minimum(np.maximum(cx - half, 0), cols - w)
    return r0, c0, (h, w)


def _stack(image: np.ndarray, r0, c0, size):
    """Return the windows (K, h, w) from their corners, in the frame's type (counts as read)."""
    # one gather from a strided view of every h x w window of the frame (no copy until here)
    return windows_view(image[None], size)[0, r0, c0]


def _levels(cfg: WindowDetector, image: np.ndarray, r0, c0, size):
    """Background level and noise of each window, counts, and its lit threshold.

    Returns level (float32, (K,), or (1,) for all alike), noise (float, (K,) or (1,)) and the
    threshold (float32, :func:`float32_below`, the shape of level).
    """
    logic = cfg.detector.logic
    if cfg.known_background:  # one level and threshold for every window
        det = cfg.camera
        level = np.array([det.bias_counts], np.float32)
        noise = np.array([det.read_noise_e * det.gain_counts_per_e])
        return level, noise, float32_below(np.array([float(logic.lit_pixel_counts)]))
    # the window's border (two pixels wide): sky around the star, a fraction of the pixels;
    # the statistics in float32, as the frame's
    stack = _stack(image, r0, c0, size).astype(np.float32)
    k = len(stack)
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
    return level.astype(np.float32), noise, float32_below(threshold)


def _median_noise(noise: np.ndarray) -> float:
    """Median noise of the windows, counts (one for all: that one)."""
    return float(noise[0]) if len(noise) == 1 else float(np.median(noise))


def _detections(rows, noise: float, n_candidates: int, saturation, compiled: bool):
    """Build Detections from the window rows: brightest first, one per 2 px.

    ``rows`` as :func:`~starsense.detect.window_kernels.detect_stack_numpy` returns them.
    """
    x, y, counts, n_pixels, peak, box, spread = rows
    order = np.argsort(-counts, kind="stable")
    # overlapping windows and pieces of one streak: the same centre
    keep = apart_compiled(x, y, order) if compiled else None
    keep = apart_numpy(x, y, order) if keep is None else keep
    sel = order[keep]
    # (the selections are copies already: no second copy to change a type it has)
    peak = peak[sel].astype(float, copy=False)
    return Detections(
        x=x[sel].astype(float, copy=False),
        y=y[sel].astype(float, copy=False),
        integrated_counts=counts[sel].astype(float, copy=False),
        n_pixels=n_pixels[sel].astype(int, copy=False),
        peak_counts=peak,
        saturated=peak >= saturation if saturation is not None else np.zeros(len(sel), bool),
        bbox=box[sel].astype(int, copy=False).reshape(-1, 4),
        fit_ok=np.ones(len(sel), bool),
        n_candidates=int(n_candidates),
        noise_counts=noise,
        method="cog",
        extra={"spread_px2": spread[sel].astype(float, copy=False).reshape(-1, 2, 2)},
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
    compiled : bool
        Use the compiled kernel where it is built (False: the NumPy form; the results are the
        same, :mod:`~starsense.detect.window_kernels`).
    """

    detector: StarDetector
    camera: Detector
    known_background: bool
    threshold_sigma: float
    compiled: bool = True

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
        r0, c0, (h, w) = _corners(image.shape, np.asarray(centres_px, dtype=float), half_px)
        level, noise, threshold = _levels(self, image, r0, c0, (h, w))
        kw = {
            "corners": (r0, c0),
            "level": level,
            "threshold": threshold,
            "logic": self.detector.logic,
            "sigma_px": self.camera.psf_sigma_px,
            "streaks": streaks_px,
        }
        got = None if not self.compiled else detect_stack_compiled(image, (h, w), **kw)
        if got is None:
            stack = _stack(image, r0, c0, (h, w))
            got = detect_stack_numpy(stack, image.shape, **kw)
        det = _detections(
            got[0], _median_noise(noise), got[1], self.camera.saturation_counts, self.compiled
        )
        boxes = columns(r0, r0 + h, c0, c0 + w)
        area = union_area(boxes, compiled=self.compiled)
        return WindowDetections(det, n, area, boxes, self.compiled)
