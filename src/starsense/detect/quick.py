"""Quick extraction: a coarse background and one pass that subtracts it and finds lit pixels.

The robust detector (:class:`~starsense.detect.threshold.StarDetector` with
``background="auto"``) estimates the background with sigma-clipped medians and MADs, filters
the frame with the PSF and judges each region's shape: about ten passes over the frame. A
frame of a camera with known optics usually has enough bright stars that a plain threshold
finds them, and the solver's identification says whether they sufficed. This is that plain
threshold, two passes in all:

1. the frame is cut into the mesh of boxes of
   :class:`~starsense.detect.mesh.MeshSampler` (``box_px`` = 64), sampled at every
   ``every``-th pixel each way (4: 256 samples per 64-pixel box). In each box the mean and the
   standard deviation of the samples are clipped at ``sigma_clip`` (3) standard deviations
   about the mean until nothing more is clipped (at most :data:`MAX_CLIP_ITERATIONS` times;
   SExtractor's clipping, with the mean for the median: no sort). The standard deviation of a
   Gaussian clipped at +-3 sigma is 0.98658 sigma; it is divided by that. The mean of 256
   samples is within 1/16 of the noise of the level (1 sigma). Both meshes pass the median
   filter over 3 x 3 boxes of :func:`~starsense.detect.mesh.median_filter_mesh`;
2. one pass over the frame interpolates both meshes bilinearly between the box centres
   (extrapolated linearly beyond the outer ones; the noise kept within the range of its mesh),
   subtracts the level (float32, as the robust detector's subtraction) and keeps the pixels
   above ``k`` times their noise, and above a floor.

The NumPy forms below are the reference; the compiled kernel (``_quickc``, built by
setup.py) does the same arithmetic in the same order: the same clipped statistics to within
the summation order of float64 sums (NumPy sums pairwise; a sample exactly at a clipping
bound may fall either side), the same subtracted frame and lit pixels bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense._workspace import scratch
from starsense.detect.mesh import MeshSampler, fill_from_nearest, median_filter_mesh
from starsense.detect.quantised import QUANTISED_BELOW_STEPS

try:
    import starsense.detect._quickc as _quickc
except ImportError:  # built without a C compiler: the NumPy forms below
    _quickc = None

__all__ = ["TRUNCATED_SD_3SIGMA", "QuickBackground", "quick_background", "quick_subtract"]

#: the standard deviation of a unit Gaussian clipped at +-3: sqrt(1 - 6 phi(3) / (2 Phi(3) - 1))
TRUNCATED_SD_3SIGMA = 0.98657839
#: a frame with more than this fraction of its background samples at their lowest value is
#: declined (noise clipped at a floor; Gaussian noise puts a few in a million there)
QUICK_FLOOR_FRACTION = 0.01
#: clipping iterations at most (a box converges in 2-4)
MAX_CLIP_ITERATIONS = 10
#: sample types the kernel reads (NumPy's type characters)
_KINDS = frozenset("BHhfd")


@dataclass(frozen=True, eq=False)
class QuickBackground:
    """The coarse background of :func:`quick_background`, counts.

    Attributes
    ----------
    level_mesh, noise_mesh : ndarray of float64, shape (mesh rows, mesh columns)
        Filtered box means and noise (clipped standard deviations over 0.98658), counts.
    row_centres, col_centres : ndarray of float64
        Pixel coordinates of the box centres along the rows and the columns.
    noise : float
        Median of the noise mesh, counts rms.
    floor_fraction : float
        Fraction of the samples at the lowest value of them all: a few in a million for
        Gaussian noise, a large fraction for noise clipped at a floor (an ADC's zero) or
        quantised in steps as large as the noise.
    """

    level_mesh: np.ndarray
    noise_mesh: np.ndarray
    row_centres: np.ndarray
    col_centres: np.ndarray
    noise: float
    floor_fraction: float = 0.0

    def declines(self, dtype) -> bool:
        """Whether a plain threshold is wrong for this frame (of sample type ``dtype``).

        Noise clipped at a floor (more than :data:`QUICK_FLOOR_FRACTION` of the samples at
        their lowest value), or 8-bit noise under 3 counts (JPEG's blocks stand out of it): a
        plain threshold lights the noise's clipped tail, plateaus and blocks.
        """
        low_8bit = np.dtype(dtype).itemsize == 1 and not self.noise >= QUANTISED_BELOW_STEPS
        return bool(low_8bit or self.floor_fraction > QUICK_FLOOR_FRACTION)


def _clipped_stats(cells: np.ndarray, ok, sigma_clip: float):
    """Clipped mean, standard deviation and count of the samples of each box (NumPy form)."""
    keep = np.broadcast_to(ok, cells.shape)
    mean = sd = n = None
    for _ in range(MAX_CLIP_ITERATIONS):
        n = keep.sum(axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(keep, cells, 0.0).sum(axis=-1) / n
            dev = np.where(keep, cells - mean[..., None], 0.0)
            sd = np.sqrt((dev * dev).sum(axis=-1) / (n - 1))
            new = (np.abs(cells - mean[..., None]) <= sigma_clip * sd[..., None]) & ok
        if np.array_equal(new, keep):
            break
        keep = new
    return mean, sd, n


def quick_background(
    a: np.ndarray, *, box_px: int = 64, every: int = 4, sigma_clip: float = 3.0
) -> QuickBackground:
    """Clipped box means and standard deviations of a frame, median-filtered (module docstring).

    Parameters
    ----------
    a : ndarray, shape (rows, columns)
        Frame, counts (finite real numbers).
    box_px : int
        Nominal box size, pixels.
    every : int
        Sample every ``every``-th pixel of a box each way.
    sigma_clip : float
        Clipping bound, standard deviations.

    Returns
    -------
    QuickBackground
    """
    mesh = MeshSampler(a.shape, box_px=box_px, every=every, interpolation="linear")
    ny, nx = mesh.boxes
    n_valid = mesh.rvalid.sum(axis=1)[:, None] * mesh.cvalid.sum(axis=1)[None, :]
    if _quickc is not None and a.dtype.char in _KINDS and a.dtype.isnative:
        mean, sd, n = np.empty((ny, nx)), np.empty((ny, nx)), np.empty((ny, nx), np.int64)
        ri, ci = (np.ascontiguousarray(i, np.int64) for i in (mesh.ri, mesh.ci))
        rv, cv = (np.ascontiguousarray(v, np.uint8) for v in (mesh.rvalid, mesh.cvalid))
        lowest, at_lowest = _quickc.box_stats(
            np.ascontiguousarray(a), a.dtype.char, *a.shape, ri, rv, ci, cv, ny, nx,
            *ri.shape[1:], *ci.shape[1:], sigma_clip, MAX_CLIP_ITERATIONS, mean, sd, n,
        )  # fmt: skip
    else:
        ok = True if mesh.regular else mesh.valid()
        cells = mesh.gather(a, np.float64)
        mean, sd, n = _clipped_stats(cells, ok, sigma_clip)
        lowest = float(np.min(cells, where=ok, initial=np.inf))
        at_lowest = int(np.count_nonzero((cells == lowest) & ok))
    floor_fraction = at_lowest / int(n_valid.sum())
    bad = n < np.maximum(2, 0.1 * n_valid)  # a box mostly clipped
    mean, sd = np.where(bad, np.nan, mean), np.where(bad, np.nan, sd / TRUNCATED_SD_3SIGMA)
    if np.isnan(mean).all():
        mean = sd = np.zeros((ny, nx))
    level = median_filter_mesh(fill_from_nearest(mean), 3)
    noise = median_filter_mesh(fill_from_nearest(sd), 3)
    return QuickBackground(level, noise, mesh.rc, mesh.cc, float(np.median(noise)), floor_fraction)


def _axis_weights(centres: np.ndarray, n: int):
    """Return each pixel's segment and weights between the box centres, one axis (linear)."""
    m = centres.size
    pix = np.arange(n, dtype=np.float64)
    if m == 1:
        return np.zeros(n, np.int64), np.ones(n), np.zeros(n)
    seg = np.clip(np.searchsorted(centres, pix, side="right") - 1, 0, m - 2)
    t = (pix - centres[seg]) / (centres[seg + 1] - centres[seg])
    return seg.astype(np.int64), 1.0 - t, t


def _interpolated(mesh: np.ndarray, ry, rx, dtype=np.float64) -> np.ndarray:
    """Return the mesh interpolated to every pixel (NumPy form of the kernel's arithmetic).

    Between the box rows in float64, then along the rows in ``dtype``.
    """
    (sy, wy0, wy1), (sx, wx0, wx1) = ry, rx
    sy1, sx1 = np.minimum(sy + 1, mesh.shape[0] - 1), np.minimum(sx + 1, mesh.shape[1] - 1)
    rows = (wy0[:, None] * mesh[sy] + wy1[:, None] * mesh[sy1]).astype(dtype)
    wx0, wx1 = wx0.astype(dtype), wx1.astype(dtype)
    return wx0[None, :] * rows[:, sx] + wx1[None, :] * rows[:, sx1]


def quick_subtract(a: np.ndarray, bg: QuickBackground, *, k: float, floor: float):
    """Return the frame minus its level, and its pixels above ``k`` noise sigmas and ``floor``.

    Parameters
    ----------
    a : ndarray, shape (rows, columns)
        Frame, counts.
    bg : QuickBackground
        Its background.
    k : float
        Threshold, in noise sigmas.
    floor : float
        Threshold's floor, counts (the detection logic's lit-pixel level).

    Returns
    -------
    sub : ndarray of float32, shape (rows, columns)
        ``a`` minus the interpolated level (a work buffer, valid until the next call).
    idx : ndarray of int64, shape (P,)
        Flat indices of the lit pixels, ascending.
    noise : ndarray of float32, shape (P,)
        The interpolated noise at them, counts rms.
    """
    rows, cols = a.shape
    ry, rx = _axis_weights(bg.row_centres, rows), _axis_weights(bg.col_centres, cols)
    lo, hi = float(np.min(bg.noise_mesh)), float(np.max(bg.noise_mesh))
    sub = scratch("quick_sub", a.shape)
    if _quickc is not None and a.dtype.char in _KINDS and a.dtype.isnative:
        cap = max(1 << 16, a.size // 16)
        idx, noise = np.empty(cap, np.int64), np.empty(cap, np.float32)
        level, nmesh = (np.ascontiguousarray(m, np.float64) for m in (bg.level_mesh, bg.noise_mesh))
        count = _quickc.subtract_above(
            np.ascontiguousarray(a), a.dtype.char, rows, cols, level, nmesh, *bg.level_mesh.shape,
            *ry, *rx, lo, hi, float(k), float(floor), sub, idx, noise, cap,
        )  # fmt: skip
        if count <= cap:
            return sub, idx[:count].copy(), noise[:count].copy()
    level = _interpolated(bg.level_mesh, ry, rx, np.float32)
    noise_map = np.clip(_interpolated(bg.noise_mesh, ry, rx), lo, hi)
    np.subtract(a.astype(np.float32), level, out=sub)
    thr = np.maximum(k * noise_map, floor).astype(np.float32)
    idx = np.flatnonzero(sub > thr)
    return sub, idx, noise_map.ravel()[idx].astype(np.float32)
