"""Window detection for tracking: look for stars only where the prior attitude puts them.

A tracker that knows where its stars are reads out small windows around them instead of the
whole frame; here the detector runs on a window around each of the brightest database stars
predicted on the detector. A window's half-width covers the search radius (the prior's
uncertainty), half the streak the body rate draws in one exposure, and the PSF with the
centroid margin. When the windows would cover more than a quarter of the frame the whole frame
is searched instead.

With a known background (simulated frames) each window uses the sensor's own detection logic
on its bias; otherwise each window's background is its median and its noise the scaled median
absolute deviation (the window is mostly sky), with the Solver's sigma threshold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["WindowDetections", "detect_in_windows", "streak_px"]

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
        Pixels searched.
    mask : ndarray of bool, shape (rows, columns) or None
        The pixels searched (None: the whole frame).
    """

    detections: object
    n_windows: int
    region_px: int
    mask: np.ndarray | None = None

    def count_inside(self, x, y) -> int:
        """Return how many of the positions (x, y), px, lie in the searched pixels."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        if self.mask is None:
            return -1
        rows, cols = self.mask.shape
        ok = np.isfinite(x) & np.isfinite(y)
        xi = np.rint(x[ok]).astype(int)
        yi = np.rint(y[ok]).astype(int)
        on = (xi >= 0) & (xi < cols) & (yi >= 0) & (yi < rows)
        return int(self.mask[yi[on], xi[on]].sum())


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
        corner = np.array([math.tan(hx), math.tan(hy), 1.0])
        b = np.array([corner * [sx, sy, 1.0] for sx in (-1, 1) for sy in (-1, 1)])
        b /= np.linalg.norm(b, axis=1)[:, None]
        return float(np.max(scale * np.linalg.norm(np.cross(w, b)[:, :2], axis=1)))
    b = np.asarray(vectors_cam, dtype=float)
    return scale * np.linalg.norm(np.cross(w, b)[:, :2], axis=1)


def _window_detector(solver, window: np.ndarray):
    from starsense.detect import StarDetector

    if solver.background == "known":
        return StarDetector.for_sensor(solver.sensor)
    level = float(np.median(window))
    noise = 1.4826 * float(np.median(np.abs(window - level)))
    return StarDetector(
        solver.logic, "cog", background=level, noise_counts=max(noise, 1e-6),
        threshold_sigma=solver.threshold_sigma, remove_hot_pixels=False,
    )  # fmt: skip


def _merge(parts, empty):
    """Concatenate Detections of the windows; drop duplicates (< 1 px apart), brightest first."""
    import dataclasses

    if not parts:
        return empty
    names = ("x", "y", "integrated_counts", "n_pixels", "peak_counts", "saturated", "bbox",
             "fit_ok")  # fmt: skip
    cols = {n: np.concatenate([getattr(p, n) for p in parts]) for n in names}
    order = np.argsort(-cols["integrated_counts"], kind="stable")
    keep: list[int] = []
    for i in order.tolist():
        if all(math.hypot(cols["x"][i] - cols["x"][j], cols["y"][i] - cols["y"][j]) >= 1.0
               for j in keep):  # fmt: skip
            keep.append(i)
    k = np.asarray(keep, dtype=np.intp)
    return dataclasses.replace(empty, **{n: v[k] for n, v in cols.items()})


def detect_in_windows(
    solver, image: np.ndarray, centres_px: np.ndarray, half_px: int
) -> WindowDetections:
    """Detect stars in square windows around predicted positions (or in the whole frame).

    Parameters
    ----------
    solver : Solver
        Its sensor, detection logic, background mode and threshold are used.
    image : ndarray, shape (rows, columns)
        The frame, counts.
    centres_px : ndarray, shape (K, 2)
        Predicted star positions (x = column, y = row), px, on the detector.
    half_px : int
        Half-width of each window, px.

    Returns
    -------
    WindowDetections
    """
    import dataclasses

    rows, cols = image.shape
    n = len(centres_px)
    if n == 0 or n * (2 * half_px + 1) ** 2 > MAX_WINDOW_FRACTION * rows * cols:
        det = solver._detector()(image)
        return WindowDetections(det, 0, rows * cols, None)
    cx = np.rint(centres_px[:, 0]).astype(int)
    cy = np.rint(centres_px[:, 1]).astype(int)
    r0, r1 = np.maximum(cy - half_px, 0), np.minimum(cy + half_px + 1, rows)
    c0, c1 = np.maximum(cx - half_px, 0), np.minimum(cx + half_px + 1, cols)
    mask = np.zeros((rows, cols), dtype=bool)
    parts = []
    empty = None
    for a, b, c, d in zip(r0.tolist(), r1.tolist(), c0.tolist(), c1.tolist(), strict=True):
        mask[a:b, c:d] = True
        window = np.asarray(image[a:b, c:d])
        det = _window_detector(solver, window)(window)
        empty = det if empty is None else empty
        if len(det) == 0:
            continue
        box = det.bbox + np.array([a, a, c, c])
        # a star cut by the window's edge (not the frame's) has a biased centroid: drop it
        cut = (
            ((box[:, 0] == a) & (a > 0)) | ((box[:, 1] == b) & (b < rows))
            | ((box[:, 2] == c) & (c > 0)) | ((box[:, 3] == d) & (d < cols))
        )  # fmt: skip
        ok = ~cut
        parts.append(dataclasses.replace(
            det, x=det.x[ok] + c, y=det.y[ok] + a, integrated_counts=det.integrated_counts[ok],
            n_pixels=det.n_pixels[ok], peak_counts=det.peak_counts[ok],
            saturated=det.saturated[ok], bbox=box[ok], fit_ok=det.fit_ok[ok],
        ))  # fmt: skip
    return WindowDetections(_merge(parts, empty), n, int(mask.sum()), mask)
