"""Background and noise of a frame: a smooth sky-glow map for real images.

:func:`estimate_background` follows the mesh approach of photutils' ``Background2D`` (and
SExtractor before it), with NumPy/SciPy only:

1. the frame is cut into a mesh of boxes of about ``box_px`` pixels (equal sizes, to within a
   pixel); boxes of 32 pixels or more are sampled at every second pixel each way (the median's
   error, 1.25 sigma / sqrt(n), is still ~2.5 % of the noise for 64-pixel boxes, n = 1,024);
2. in every box the samples are sigma-clipped about their median, with the robust scale
   1.4826 MAD (median absolute deviation), until nothing more is clipped; the box's level is the
   median of what remains. All boxes are clipped at once (no loop over boxes);
3. the mesh is median-filtered over ``filter_px`` x ``filter_px`` boxes, which removes boxes
   spoilt by a bright star. The filter acts on the mesh minus its least-squares quadratic trend
   (added back afterwards), padded by point reflection about its edge boxes, so that a smooth
   glow passes the filter unchanged, at the edges and corners too (a plain median filter
   flattens the peak of a curved glow, and padding by repetition biases the corner boxes by
   about one box's worth of gradient);
4. the mesh, whose nodes are the centres of the sampled pixels of each box, is interpolated back
   to every pixel with a separable natural bicubic spline (default) or bilinear interpolant and
   **extrapolated linearly** beyond the outer box centres: a vignetted frame falls off fastest
   at its corners, and a flat extrapolation there overestimates the background by up to ~2.5
   noise sigma on the ESA frames (shared/data/images/esa), raising the effective detection
   threshold in the corners;
5. the noise is 1.4826 MAD of the clipped samples *minus the interpolated level*, per box,
   filtered and interpolated the same way. Subtracting the smooth map first matters for data
   quantised in coarse steps (the ESA frames are 12-bit data stored as 16-bit, steps of 16
   counts): the MAD of the raw quantised values itself moves in steps of 16 counts (24 counts of
   sigma, ~20 %), that of the residual does not.

Simulated frames with a known bias use :func:`constant_background` instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from starsense._validate import check_scalar, finite_float
from starsense._workspace import scratch
from starsense.detect.clip import MAD_TO_SIGMA as MAD_TO_SIGMA  # re-exported
from starsense.detect.clip import robust_sigma, sigma_clip_boxes
from starsense.detect.mesh import (
    MeshSampler,
    fill_from_nearest,
    interpolate_mesh,
    median_filter_mesh,
)
from starsense.detect.quantised import (
    STEP_SAMPLES_EVERY,
    clip_floor,
    clipped_box_stats,
    frame_quantisation_step,
    quantised_box_stats,
)
from starsense.detect.surface import NoiseSurface
from starsense.errors import InputError

try:
    import starsense.detect._clipc as _clipc
except ImportError:  # built without a C compiler: the NumPy form of the noise mesh
    _clipc = None

# Boxes of at least this size are sampled at every second pixel each way.
_SUBSAMPLE_MIN_BOX_PX = 32
# A box keeping fewer valid samples than this fraction (masked, clipped) takes its value from the
# nearest box that kept enough.
_MIN_VALID_FRACTION = 0.1


@dataclass(frozen=True, eq=False)
class Background:
    """A frame's background level and noise, counts.

    Attributes
    ----------
    level : float or ndarray, shape (rows, columns)
        Background level, counts: one value for the frame or a map (float32).
    noise : float
        Typical background noise, counts rms (for an estimated background: the median over the
        mesh boxes of the noise map).
    noise_map : ndarray, shape (rows, columns), or None
        Background noise per pixel, counts rms (float32); None for a constant background. Sky
        glow adds shot noise, so on real frames the noise follows the level (on the ESA frames
        it varies by ~20 % across a frame).
    level_mesh : ndarray, shape (mesh_rows, mesh_columns), or None
        The filtered box levels the map was interpolated from (counts).
    box_px : int or None
        Nominal box size of the mesh, pixels.
    step : float or None
        Quantisation step of a coarsely quantised frame (noise below 3 steps: 8-bit, low bias,
        JPEG), counts; None otherwise (:mod:`starsense.detect.quantised`).
    surface : NoiseSurface or None
        The noise map's interpolant, when the map itself was not built
        (``estimate_background(noise_map=False)``): :meth:`noise_at` evaluates it per pixel.
    """

    level: float | np.ndarray
    noise: float
    noise_map: np.ndarray | None = None
    level_mesh: np.ndarray | None = None
    box_px: int | None = None
    step: float | None = None
    surface: NoiseSurface | None = None

    def threshold_counts(self, sigma: float) -> float | np.ndarray:
        """``sigma`` times the noise: per pixel when there is a noise map, else one number."""
        if self.noise_map is None and self.surface is not None:
            return np.float32(sigma) * self.surface.grid(1)
        if self.noise_map is not None:
            return np.float32(sigma) * self.noise_map
        return sigma * self.noise

    @property
    def varies(self) -> bool:
        """Whether the noise varies across the frame (a map or a surface)."""
        return self.noise_map is not None or self.surface is not None

    def noise_at(self, flat_idx: np.ndarray) -> np.ndarray | float:
        """Noise at the pixels of flat indices ``flat_idx``, counts rms (one number if flat)."""
        if self.noise_map is not None:
            return self.noise_map.ravel()[flat_idx]
        if self.surface is not None:
            return self.surface.at(flat_idx)
        return self.noise

    def noise_floor(self) -> float | np.float32:
        """Return the lowest noise anywhere in the frame, counts rms."""
        if self.noise_map is not None:
            return np.min(self.noise_map)
        if self.surface is not None:
            return self.surface.floor()
        return self.noise

    def noise_grid(self, step: int) -> np.ndarray | float:
        """Noise at every ``step``-th pixel each way (one number if flat)."""
        if self.noise_map is not None:
            return self.noise_map[::step, ::step]
        if self.surface is not None:
            return self.surface.grid(step)
        return self.noise


def constant_background(level_counts: float, noise_counts: float) -> Background:
    """Return a known, flat background (simulated frames: the bias, the read noise times the gain).

    Parameters
    ----------
    level_counts : float
        Background level subtracted from every pixel, counts.
    noise_counts : float
        Background noise, counts rms, >= 0.
    """
    level = finite_float(level_counts, "level_counts")
    noise = check_scalar(noise_counts, "noise_counts", 0.0)
    return Background(level, noise)


def _is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _kept(cells: np.ndarray, low: np.ndarray, high: np.ndarray, ok, name: str) -> np.ndarray:
    """Which samples lie within their box's clipping bounds (and are valid: ``ok``)."""
    keep = scratch(name, cells.shape, bool)
    with np.errstate(invalid="ignore"):
        np.greater_equal(cells, low[..., None], out=keep)
        keep &= np.less_equal(cells, high[..., None], out=scratch(name + "_le", cells.shape, bool))
    if ok is not True:
        keep &= ok
    return keep


def _residual_noise(cells, level, mesh: MeshSampler, low, high, keep) -> np.ndarray:
    """Robust noise of each box: 1.4826 MAD of its kept samples minus the level map.

    ``keep`` is the kept samples, or None on a regular mesh without missing samples, where the
    compiled kernel (``_clipc.mad_resid``) tests the bounds and subtracts the map's values
    sample by sample: the same float32 comparisons and subtractions, the same MAD.
    """
    if keep is None:
        (ny, nx), my, mx = mesh.boxes, mesh.ri.shape[1], mesh.ci.shape[1]
        level = np.ascontiguousarray(level, dtype=np.float32)
        out = np.empty((ny, nx), np.float64)
        geometry = (level.shape[1], ny, nx, my, mx, mesh.every)
        _clipc.mad_resid(np.ascontiguousarray(cells), level, *geometry, low, high, out)
        return MAD_TO_SIGMA * out
    resid = mesh.gather(level, None, "bg_resid")
    return robust_sigma(np.subtract(cells, resid, out=resid), keep)


def _masked_std(cells: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Return the std of the samples ``keep`` of every box (NaN where fewer than 2)."""
    n = keep.sum(axis=-1)
    x = np.where(keep, cells, 0.0).astype(np.float64)
    mean = x.sum(-1) / np.maximum(n, 1)
    var = np.where(keep, (x - mean[..., None]) ** 2, 0.0).sum(-1) / np.maximum(n - 1, 1)
    return np.where(n >= 2, np.sqrt(var), np.nan)


def _mesh_samples(a: np.ndarray, mesh: MeshSampler, bad: np.ndarray | None):
    """Return the mesh's samples: float32 (NaN where missing), as integers, valid, per box.

    ``counts`` is the same samples as 8/16-bit integers (or None): gathered once as such
    (:func:`~starsense.detect.clip.sigma_clip_boxes` sorts them as integers) and converted,
    exactly, by one contiguous copy. ``ok`` is True where every sample is inside its box and
    unmasked, else a bool array of the samples' shape.
    """
    counts = None
    if mesh.regular and bad is None and a.dtype.kind in "iu" and a.dtype.itemsize <= 2:
        ny, nx = mesh.boxes
        my, mx = mesh.ri.shape[1], mesh.ci.shape[1]
        counts = scratch("bg_counts", (ny, nx, my * mx), a.dtype)
        cells = scratch("bg_cells", counts.shape)
        if _clipc is not None and a.dtype.isnative:  # one pass, the same samples and floats
            geometry = (a.shape[1], ny, nx, my, mx, mesh.every)
            _clipc.gather(np.ascontiguousarray(a), a.dtype.char, *geometry, counts, cells)
        else:
            np.copyto(cells, mesh.gather(a, None, "bg_counts"))  # the same buffer as counts
    else:
        cells = mesh.gather(a, np.float32, "bg_cells")
    if mesh.regular and bad is None:  # every sample is inside its box and unmasked
        return cells, counts, True, np.full(mesh.boxes, cells.shape[-1])
    ok = mesh.valid()
    if bad is not None:
        ok &= ~mesh.gather(bad)
    if not ok.all():
        cells[~ok] = np.nan
    return cells, counts, ok, ok.sum(axis=-1)


def estimate_background(
    image: ArrayLike,
    *,
    box_px: int = 64,
    filter_px: int = 3,
    sigma_clip: float = 3.0,
    mask: ArrayLike | None = None,
    interpolation: str = "cubic",
    full_noise_map: bool = True,
) -> Background:
    """Smooth background map and robust noise map of a real frame.

    Sigma-clipped median per box, median filter over the mesh, interpolation back to full
    resolution (see the module docstring).

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        Frame, counts (any real dtype).
    box_px : int
        Mesh box size, pixels, >= 4: much larger than a star, smaller than the scale on which
        the glow varies. The frame is cut into ``round(rows / box_px)`` x
        ``round(columns / box_px)`` boxes of equal size (to within a pixel).
    filter_px : int
        Size of the median filter over the mesh, **in boxes** (odd, >= 1; 1 = no filter).
    sigma_clip : float
        Clipping of stars and hot pixels inside each box, in robust sigmas (> 0).
    mask : array_like of bool, shape (rows, columns), optional
        True for pixels to ignore (known bright stars, a vignetted border).
    interpolation : {"linear", "cubic"}
        Bilinear, or natural bicubic spline, between box centres.
    full_noise_map : bool
        Build the noise map over the whole frame (default); False leaves ``noise_map`` None and
        gives its interpolant instead (``surface``, evaluated per pixel by
        :meth:`Background.noise_at`), for a detector that needs the noise only where a pixel
        is already above its threshold at the frame's lowest noise.

    Returns
    -------
    Background
        ``level`` and ``noise_map`` are float32 maps of the image's shape; ``noise`` is the
        median of the noise map.
    """
    a = np.asarray(image)
    if a.ndim != 2:
        raise InputError(f"image must be 2-D, got shape {a.shape}")
    if a.size == 0:
        raise InputError("image is empty")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InputError(f"image must be real numbers, got dtype {a.dtype}")
    if not _is_int(box_px) or box_px < 4:
        raise InputError(f"box_px = {box_px!r} is out of range; must be an integer >= 4")
    if not _is_int(filter_px) or filter_px < 1 or filter_px % 2 == 0:
        raise InputError(f"filter_px = {filter_px!r} is out of range; must be an odd integer >= 1")
    if not (isinstance(sigma_clip, (int, float, np.number)) and 0 < sigma_clip < np.inf):
        raise InputError(f"sigma_clip = {sigma_clip!r} is out of range; must be > 0")
    if interpolation not in ("linear", "cubic"):
        raise InputError(f"interpolation must be 'linear' or 'cubic', got {interpolation!r}")
    bad = None
    if mask is not None:
        bad = np.asarray(mask)
        if bad.shape != a.shape or bad.dtype != bool:
            raise InputError(
                f"mask must be a bool array of the image's shape {a.shape}, "
                f"got {bad.dtype} {bad.shape}"
            )
    box_px, filter_px = int(box_px), int(filter_px)
    mesh = MeshSampler(
        a.shape,
        box_px=box_px,
        every=2 if box_px >= _SUBSAMPLE_MIN_BOX_PX else 1,
        interpolation=interpolation,
    )
    wy, wx, gather = mesh.wy, mesh.wx, mesh.gather
    cells, counts, ok, n_samples = _mesh_samples(a, mesh, bad)
    med, low, high, kept = sigma_clip_boxes(cells, float(sigma_clip), counts=counts)
    sampled = cells[:, :, ::STEP_SAMPLES_EVERY]
    keep = None  # the kept samples: needed whole only without the fused noise kernel
    if _clipc is not None and ok is True and cells.dtype == np.float32:
        # the step from the integer samples if any (the same values, no float pass)
        step = frame_quantisation_step(
            sampled, _kept(sampled, low, high, ok, "bg_keep_step"), counts
        )
    else:
        keep = _kept(cells, low, high, ok, "bg_keep")
        step = frame_quantisation_step(sampled, keep[:, :, ::STEP_SAMPLES_EVERY])
    floor = clip_floor(sampled) if step is None else None
    if step is not None:  # 8-bit-like data: box means and standard deviations (quantised.py)
        med, _, keep = quantised_box_stats(cells, med, step)
        kept = keep.sum(-1)
    elif floor is not None:  # clipped at a floor, not coarsely quantised: the same (quantised.py)
        med, _, keep = clipped_box_stats(cells, med, floor)
        kept = keep.sum(-1)
    trusted = kept >= np.maximum(1, _MIN_VALID_FRACTION * n_samples.max())
    if not trusted.any():
        raise InputError("no box of the image has enough unmasked pixels for a background")
    med[~trusted] = np.nan
    level_mesh = median_filter_mesh(fill_from_nearest(med), filter_px)

    level = interpolate_mesh(wy, level_mesh, wx)

    # noise: MAD of the clipped samples about the smooth map (not quantised like the raw MAD);
    # for coarsely quantised data their standard deviation, at least the quantisation noise
    if step is not None:
        noise_mesh = np.maximum(_masked_std(cells - gather(level), keep), step / np.sqrt(12.0))
    elif floor is not None:
        noise_mesh = _masked_std(cells - gather(level), keep)
    else:
        noise_mesh = _residual_noise(cells, level, mesh, low, high, keep)
    noise_mesh[~trusted] = np.nan
    noise_mesh = median_filter_mesh(fill_from_nearest(noise_mesh), filter_px)
    noise_map, surface = None, None
    if full_noise_map:
        noise_map = interpolate_mesh(wy, noise_mesh, wx)
        # extrapolation and spline overshoot must not leave the range that was measured
        np.maximum(noise_map, np.float32(noise_mesh.min()), out=noise_map)
        np.minimum(noise_map, np.float32(noise_mesh.max()), out=noise_map)
    else:
        surface = NoiseSurface.from_mesh(wy, noise_mesh, wx)
    return Background(
        level=level,
        noise=float(np.median(noise_mesh)),
        noise_map=noise_map,
        level_mesh=level_mesh,
        box_px=box_px,
        step=step,
        surface=surface,
    )
