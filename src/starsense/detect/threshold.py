"""Star detection: the lit-pixel / contiguous-pixels / integrated-intensity logic of the ST-16.

Dzamba & Enright 2014, sec. 1.2: a pixel is *lit* when its background-subtracted counts exceed a
threshold; lit pixels that touch (4- or 8-connected, as configured) form a candidate; a candidate
is a star when it has at least ``min_pixels`` lit pixels and their background-subtracted counts
sum to at least ``min_integrated_counts`` (its *integrated intensity*).

For real frames the threshold can follow the noise: with ``threshold_sigma`` set, a pixel is lit
when it exceeds ``max(lit_pixel_counts, threshold_sigma x noise)`` above the background map (with
``background="auto"`` the noise is a map, so the threshold follows the sky glow's shot noise
across the frame), and hot pixels (:func:`~starsense.detect.hot_pixels.hot_pixel_mask`) are
replaced by the background before labelling.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from starsense._validate import check_int, finite_float, positive_float, show
from starsense._workspace import scratch
from starsense.detect.background import Background, constant_background, estimate_background
from starsense.detect.centroid import METHODS, gauss_fit
from starsense.detect.detections import Detections
from starsense.detect.hot_pixels import HOT_PIXEL_SIGMA, hot_pixel_mask
from starsense.detect.matched import (
    NOISE_STEP,
    box_mean_at_peaks,
    filtered_noise_ratio,
    gaussian_correlate,
    local_noise_ratio,
    ratio_at,
)
from starsense.detect.mesh import mesh_box_px
from starsense.detect.pattern import remove_line_pattern
from starsense.detect.quick import quick_background, quick_subtract
from starsense.detect.regions import label_pixels, region_centroids
from starsense.detect.subtract import floor_threshold, pixels_above, subtract_level
from starsense.errors import InputError
from starsense.sensor import DetectionThresholds

#: on quantised data (Background.step), a star's peak must be this many steps above background
MIN_PEAK_STEPS = 1.5
#: matched filter: least ratio of a star's PSF-filtered peak to its box-filtered peak
MIN_SHARPNESS = 1.6
#: the detection logic is the sensor's configuration
DetectionLogic = DetectionThresholds


def _check_image(image) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim != 2:
        raise InputError(f"image must be 2-D (rows, columns), got shape {a.shape}")
    if a.size == 0:
        raise InputError("image is empty")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InputError(f"image must be real numbers, got dtype {a.dtype}")
    if np.issubdtype(a.dtype, np.floating):
        bad = int(np.count_nonzero(~np.isfinite(a)))
        if bad:
            raise InputError(f"image has {bad} non-finite (NaN or inf) pixel(s)")
    return a


class StarDetector:
    """Configure, then call: ``StarDetector(logic)(image) -> Detections``.

    Parameters
    ----------
    logic : DetectionThresholds
    centroid : {"cog", "iwcog", "gauss"}
    background : "auto", "quick", float, Background or None
        "auto" estimates a background map and noise (real frames); "quick" a coarse one, with a
        plain threshold in one pass (:mod:`starsense.detect.quick`: no hot-pixel removal, no
        matched filter; ``threshold_sigma`` default 5); a number is a flat known level
        (simulated frames: the bias); None means zero.
    noise_counts : float
        Noise of a known background (used with a numeric background), counts.
    threshold_sigma : float or None
        Lit threshold as a multiple of the noise (real frames); the larger of this and
        ``logic.lit_pixel_counts`` applies.
    saturation_counts : float or None
        Pixels at or above this are flagged saturated.
    remove_hot_pixels : bool
        Replace isolated hot pixels by the background before labelling (with "auto").
    margin_px : int
        Window margin around each star for the centroid.
    psf_sigma_px : float
        Starting PSF width of the Gaussian fit.
    max_pixels : int or None
        Optional upper bound on a star's lit pixels (rejects large blobs: the Moon's limb, a
        satellite streak, a light leak); None for no bound.
    matched_filter : bool
        Detect on the frame correlated with the PSF (:mod:`starsense.detect.matched`): a pixel
        is lit when the filtered frame exceeds ``threshold_sigma`` (default 5) times *its*
        noise; single-pixel noise spikes do not become stars. ``logic.lit_pixel_counts`` is
        then not used; ``min_pixels`` and ``min_integrated_counts`` apply to the lit region.
    min_snr : float or None
        Minimum significance of a star's integrated counts: their sum over the lit pixels over
        the noise of that sum (sqrt of the summed noise variances); None for no test.
    """

    def __init__(
        self,
        logic: DetectionThresholds | None = None,
        centroid: str = "cog",
        background: str | float | Background | None = None,
        *,
        noise_counts: float = 0.0,
        threshold_sigma: float | None = None,
        saturation_counts: float | None = None,
        remove_hot_pixels: bool = True,
        margin_px: int = 2,
        psf_sigma_px: float = 1.5,
        max_pixels: int | None = None,
        matched_filter: bool = False,
        min_snr: float | None = None,
    ) -> None:
        self.logic = logic if logic is not None else DetectionThresholds()
        if centroid not in METHODS:
            raise InputError(f"centroid must be one of {', '.join(METHODS)}, got {centroid!r}")
        if threshold_sigma is not None:
            positive_float(threshold_sigma, "threshold_sigma")
        margin_px = check_int(margin_px, "margin_px", 0)
        if saturation_counts is not None and not (
            np.isfinite(saturation_counts) and saturation_counts > 0
        ):
            raise InputError(f"saturation_counts must be > 0 or None, got {saturation_counts!r}")
        psf_sigma_px = positive_float(psf_sigma_px, "psf_sigma_px")
        noise_counts = finite_float(noise_counts, "noise_counts")
        if noise_counts < 0:
            raise InputError(f"noise_counts must be >= 0, got {show(noise_counts)}")
        if max_pixels is not None:
            max_pixels = check_int(max_pixels, "max_pixels")
            if max_pixels < self.logic.min_pixels:
                raise InputError(
                    "max_pixels must be None or an integer >= min_pixels "
                    f"({self.logic.min_pixels}), got {max_pixels!r}"
                )
        if isinstance(background, str) and background not in ("auto", "quick"):
            raise InputError(
                f"background must be 'auto', 'quick', a number or None, got {background!r}"
            )
        self.centroid = centroid
        self.background = background
        self.noise_counts = float(noise_counts)
        self.threshold_sigma = threshold_sigma
        self.saturation_counts = saturation_counts
        self.remove_hot_pixels = remove_hot_pixels
        self.margin_px = int(margin_px)
        self.psf_sigma_px = float(psf_sigma_px)
        self.max_pixels = None if max_pixels is None else int(max_pixels)
        self.matched_filter = bool(matched_filter)
        self.min_snr = None if min_snr is None else positive_float(min_snr, "min_snr")

    @classmethod
    def for_sensor(cls, sensor, centroid: str = "cog", **kwargs) -> StarDetector:
        """Build a detector with the sensor's own detection logic, bias as the known background."""
        det = sensor.detector
        kwargs.setdefault("background", det.bias_counts)
        kwargs.setdefault("noise_counts", det.read_noise_e * det.gain_counts_per_e)
        kwargs.setdefault("saturation_counts", det.saturation_counts)
        kwargs.setdefault("psf_sigma_px", det.psf_sigma_px)
        return cls(sensor.detection, centroid, **kwargs)

    def frame_background(self, a: np.ndarray) -> Background:
        """Return the background and noise this detector assumes in frame ``a``."""
        if isinstance(self.background, Background):
            return self.background
        if self.background == "auto":
            # the matched filter's thresholds evaluate the noise where needed (Background.noise_at)
            box = mesh_box_px(a.shape)
            return estimate_background(a, box_px=box, full_noise_map=not self.matched_filter)
        level = 0.0 if self.background is None else float(self.background)
        return constant_background(level, self.noise_counts)

    def _subtract_and_light(self, a: np.ndarray):
        """Background, subtracted frame, hot-pixel count and :meth:`_lit`'s lit pixels."""
        if self.background == "quick":
            qb = quick_background(a)
            k = 5.0 if self.threshold_sigma is None else self.threshold_sigma
            bg = Background(0.0, qb.noise)
            if qb.declines(a.dtype):  # such frames are for the robust detector
                none = (np.empty(0, np.int64), None, None, np.empty(0, np.float32))
                return bg, scratch("quick_sub", a.shape), {"hot_pixels": 0}, none
            sub, idx, noise = quick_subtract(a, qb, k=k, floor=self.logic.lit_pixel_counts)
            return bg, sub, {"hot_pixels": 0}, (idx, None, None, noise)
        bg = self.frame_background(a)
        remove_hot = self.background == "auto" and self.remove_hot_pixels
        above = floor_threshold(bg, HOT_PIXEL_SIGMA) if remove_hot else None
        sub, candidates = subtract_level(a, bg.level, scratch("sub", a.shape), above=above)
        counts = {"hot_pixels": 0}
        if remove_hot:
            hot = hot_pixel_mask(a, bg, subtracted=sub, candidates=candidates)
            sub[hot] = 0.0
            counts["hot_pixels"] = int(np.count_nonzero(hot))
        if self.background == "auto" and self.matched_filter:
            noise = bg.noise_map if bg.noise_map is not None else bg.noise
            counts.update(remove_line_pattern(sub, noise))
        return bg, sub, counts, self._lit(sub, bg)

    def _lit(self, sub: np.ndarray, bg: Background):
        """Lit pixels (flat indices, ascending), which bound a window, filtered, their noise.

        The noise is the background's at the lit pixels (None without the matched filter).

        Without the matched filter the lit pixels bound the window (None). With it, the lit
        region (the star's light spread by the filter) is wider than the star, so the window
        is bounded by its pixels above the raw threshold where there are any. Only pixels above
        the threshold at the frame's lowest noise can pass it at their own noise: the noise
        map is evaluated at those (:meth:`Background.noise_at`), not over the whole frame.
        """
        if not self.matched_filter:
            threshold = self.logic.lit_pixel_counts
            if self.threshold_sigma is not None:
                threshold = np.maximum(
                    np.float32(threshold), bg.threshold_counts(self.threshold_sigma)
                )
            return np.flatnonzero(sub > threshold), None, None, None
        filtered = scratch("filtered", sub.shape)
        gaussian_correlate(sub, self.psf_sigma_px, out=filtered)
        grid = bg.noise_grid(NOISE_STEP)
        ratio = filtered_noise_ratio(
            filtered, grid, psf_sigma_px=self.psf_sigma_px, noise_grid=True
        )
        k = 5.0 if self.threshold_sigma is None else self.threshold_sigma
        cut = np.float32(k * ratio)
        idx = pixels_above(filtered, cut * np.float32(bg.noise_floor()))
        noise = bg.noise_at(idx)  # evaluated once, pixel by pixel: the same values for a subset
        local = local_noise_ratio(filtered, grid, ratio=ratio)
        patterned = bool((local > np.float32(ratio)).any())
        if bg.varies or patterned:
            here = np.float32(k) * ratio_at(local, idx, sub.shape[1]) if patterned else cut
            passed = filtered.ravel()[idx] > here * noise
            idx = idx[passed]
            noise = noise[passed] if np.ndim(noise) else noise
        core_at = sub.ravel()[idx] > np.float32(k) * np.float32(noise)
        return idx, core_at, filtered, noise

    def _sharp(self, sub, filtered, idx, lab, n, a) -> np.ndarray:
        """Whether each region 0..n is point-like (matched filter; module docstring).

        The peak of the PSF-filtered frame over a box filter of side 2 ceil(3 sigma)+1 at that
        peak (over the region's lit pixels ``idx``, labels ``lab``): w^2 / (4 pi sigma^2) for a
        point source (3.9 at sigma = 1 px), ~2 for a 20-pixel streak, 1 for a plateau or a
        step wider than the box (JPEG's flattened 8 x 8 blocks, a gradient cut by
        compression). Regions holding the frame's largest value (saturated stars, flat-topped)
        are kept.
        """
        half = int(np.ceil(3.0 * self.psf_sigma_px))
        peak_f, peak_b, top = (np.full(n + 1, -np.inf) for _ in range(3))
        if idx.size:
            where, peak_f_at, box_at = box_mean_at_peaks(sub, filtered, idx=idx, lab=lab, half=half)
            peak_f[where], peak_b[where] = peak_f_at, box_at
        np.maximum.at(top, lab, a.ravel()[idx])
        with np.errstate(invalid="ignore"):
            return (peak_f >= MIN_SHARPNESS * peak_b) | (top >= a.max())

    def _gauss(self, sub, boxes, xs, ys, fits) -> None:
        """Replace the CoGs by Gaussian fits over the same windows, in place (``fits`` too).

        Where a fit fails it keeps the CoG, flagged in ``fits``; where the window's CoG failed
        too, it keeps the fallback of :func:`~starsense.detect.regions.region_centroids`.
        """
        rows, cols = sub.shape
        m = self.margin_px
        for i, (r0, r1, c0, c1) in enumerate(boxes):
            wr0, wc0 = max(r0 - m, 0), max(c0 - m, 0)
            window = sub[wr0 : min(r1 + m, rows), wc0 : min(c1 + m, cols)]
            x, y, _, fit_ok = gauss_fit(window, wr0, wc0, sigma0=self.psf_sigma_px)
            if np.isfinite(x):
                xs[i], ys[i] = x, y
            fits[i] = fit_ok

    def __call__(self, image) -> Detections:
        """Detect and centroid the stars of one image.

        Parameters
        ----------
        image : array_like, shape (rows, columns)
            Frame, counts (real numbers, finite).

        Returns
        -------
        Detections
            Brightest first.
        """
        t0 = time.perf_counter()
        a = _check_image(image)
        bg, sub, counts, (idx, core, filtered, lit_noise) = self._subtract_and_light(a)
        counts["pixels_above_threshold"] = int(idx.size)
        lab, n = label_pixels(idx, a.shape, 4 if self.logic.connectivity == 4 else 8)
        empty = Detections(
            np.empty(0),
            np.empty(0),
            np.empty(0),
            np.empty(0, int),
            np.empty(0),
            np.empty(0, bool),
            np.empty((0, 4), int),
            np.empty(0, bool),
            int(n),
            float(bg.noise),
            0.0,
            self.centroid,
            counts={**counts, "candidates": int(n), "detections": 0},
        )
        if n == 0:
            return _timed(empty, t0)
        sizes = np.bincount(lab, minlength=n + 1)
        sums = np.bincount(lab, weights=sub.ravel()[idx], minlength=n + 1)
        sized = sizes >= self.logic.min_pixels
        if self.max_pixels is not None:
            sized &= sizes <= self.max_pixels
        ok = sums >= self.logic.min_integrated_counts
        if bg.step is not None:
            # quantised data: a star rises at least two steps above the background somewhere
            # (a plateau one step up, JPEG's flattened 8 x 8 blocks, is not a star)
            peak = np.full(n + 1, -np.inf)
            np.maximum.at(peak, lab, sub.ravel()[idx])
            ok &= peak >= np.float32(MIN_PEAK_STEPS * bg.step)
        if self.min_snr is not None:
            noise = bg.noise_at(idx) if lit_noise is None else lit_noise
            var = np.bincount(lab, weights=np.broadcast_to(noise, idx.shape) ** 2, minlength=n + 1)
            with np.errstate(invalid="ignore", divide="ignore"):
                ok &= sums >= self.min_snr * np.sqrt(var)
        sized[0] = False
        faint = sized & ~ok
        ok &= sized
        if filtered is not None:
            ok &= self._sharp(sub, filtered, idx, lab, n, a)
        keep = np.flatnonzero(ok)
        counts.update(
            candidates=int(n),
            rejected_size=int(n - sized.sum()),
            rejected_faint=int(faint.sum()),
            rejected_shape=int(sized.sum() - faint.sum() - keep.size),
            saturated=0,
            detections=int(keep.size),
        )
        if keep.size == 0:
            return _timed(replace(empty, counts=counts), t0)
        keep = keep[np.argsort(-sums[keep], kind="stable")]
        power = 2 if self.centroid == "iwcog" else 1
        xs, ys, peak_arr, boxes, fits = region_centroids(
            sub, a, idx=idx, lab=lab, keep=keep, core=core, margin=self.margin_px, power=power
        )
        if self.centroid == "gauss":
            self._gauss(sub, boxes, xs, ys, fits)
        sat = (
            peak_arr >= self.saturation_counts
            if self.saturation_counts is not None
            else np.zeros(len(keep), bool)
        )
        det = Detections(
            x=xs,
            y=ys,
            integrated_counts=sums[keep].astype(float),
            n_pixels=sizes[keep].astype(int),
            peak_counts=peak_arr,
            saturated=sat,
            bbox=boxes,
            fit_ok=fits,
            n_candidates=int(n),
            noise_counts=float(bg.noise),
            method=self.centroid,
            counts={**counts, "saturated": int(sat.sum())},
        )
        return _timed(det, t0)


def _timed(det: Detections, t0: float) -> Detections:
    return replace(det, time_ms=(time.perf_counter() - t0) * 1e3)


def detect_stars(image, logic: DetectionThresholds | None = None, **kwargs) -> Detections:
    """Detect stars in one image: the function form of :class:`StarDetector`.

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        Frame, counts.
    logic : DetectionThresholds, optional
        Detection logic (default: the ST-16's).
    **kwargs
        ``centroid`` and the keyword arguments of :class:`StarDetector`.

    Returns
    -------
    Detections
    """
    centroid = kwargs.pop("centroid", "cog")
    return StarDetector(logic, centroid, **kwargs)(image)
