"""The background mesh: box samples, the median filter over boxes, interpolation to pixels.

The geometry of :func:`starsense.detect.background.estimate_background`'s mesh (which pixels
each box samples, the box centres and the interpolation weights) depends only on the frame's
shape and is computed once per shape (:func:`_mesh_plan`, :func:`_axis_weights`); the filtered
mesh is interpolated back to every pixel by two small matrix products (:func:`interpolate_mesh`),
or, along an axis too long for a dense weight matrix, by the spline's local form
(:mod:`.axis_weights`), so memory grows with the pixels, not their square.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import ndimage

from starsense._workspace import scratch
from starsense.detect.axis_weights import (
    AxisWeights,
    apply_weights,
    interpolation_matrix,
    weight_matrix,
)
from starsense.detect.axis_weights import natural_spline_weights as natural_spline_weights
from starsense.detect.surface import matmul_single_thread

_interpolation_matrix = interpolation_matrix  # the dense form, under its former name


#: the detector's mesh box, px (:func:`mesh_box_px`), and the least one on a small frame
DETECT_BOX_PX = 64
MIN_DETECT_BOX_PX = 16
#: boxes across a small frame's shorter side, at least (a gradient needs a few to be followed)
MIN_BOXES_ACROSS = 4


def mesh_box_px(shape) -> int:
    """Return the detector's background mesh box for a frame of ``shape`` (rows, columns), px.

    :data:`DETECT_BOX_PX` (much larger than a star, smaller than a glow's scale on a frame of
    hundreds of pixels), but on a frame whose shorter side holds fewer than
    :data:`MIN_BOXES_ACROSS` such boxes a quarter of that side, at least
    :data:`MIN_DETECT_BOX_PX`: a 106 x 142 frame (a wide imager summed on board to 0.3 deg a
    pixel) would otherwise be cut into 2 x 2 boxes, a flat level under a stray-light gradient
    that rises by 50 noise sigmas across it. A frame too thin for that many boxes of the least
    size (a strip) keeps :data:`DETECT_BOX_PX`: its boxes then hold the frame's whole width,
    and smaller ones would hold too few pixels for a clipped noise estimate (16 on a strip one
    pixel high, whose noise passes as stars where a box's estimate falls low).
    """
    short = min(int(shape[0]), int(shape[1]))
    if short < MIN_BOXES_ACROSS * MIN_DETECT_BOX_PX:
        return DETECT_BOX_PX
    return int(min(DETECT_BOX_PX, short // MIN_BOXES_ACROSS))


def _mesh_axis(n: int, box_px: int, step: int):
    """Sample indices (boxes, samples), their validity and the boxes' sample centres, one axis."""
    n_boxes = max(1, round(n / box_px))
    edges = np.linspace(0, n, n_boxes + 1).round().astype(np.intp)
    per_box = -(-int(np.diff(edges).max()) // step)
    index = edges[:-1, None] + step * np.arange(per_box)[None, :]
    valid = index < edges[1:, None]
    index = np.minimum(index, n - 1)
    centres = np.where(valid, index, 0).sum(axis=1) / valid.sum(axis=1)
    return index, valid, centres


def fill_from_nearest(mesh: np.ndarray) -> np.ndarray:
    """Return the mesh with each non-finite box replaced by its nearest finite one.

    Parameters
    ----------
    mesh : ndarray, shape (rows, columns)
        Box values; NaN where a box kept too few samples.

    Returns
    -------
    ndarray, shape (rows, columns)
        The same array when every box is finite.
    """
    bad = ~np.isfinite(mesh)
    if not bad.any():
        return mesh
    idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    return mesh[tuple(idx)]


@functools.lru_cache(maxsize=16)
def _quadratic_design(ny: int, nx: int) -> tuple[np.ndarray, np.ndarray]:
    """Design matrix of the mesh's quadratic trend and its pseudo-inverse (once per shape)."""
    y, x = np.mgrid[0:ny, 0:nx].astype(np.float64)
    y = (y - (ny - 1) / 2) / max(ny - 1, 1)
    x = (x - (nx - 1) / 2) / max(nx - 1, 1)
    terms = [np.ones_like(x)]
    if ny > 1:
        terms.append(y)
    if nx > 1:
        terms.append(x)
    if ny > 2:
        terms.append(y * y)
    if nx > 2:
        terms.append(x * x)
    if ny > 2 and nx > 2:
        terms.append(x * y)
    design = np.stack([t.ravel() for t in terms], axis=1)
    pinv = np.linalg.pinv(design)
    design.flags.writeable = pinv.flags.writeable = False
    return design, pinv


def _quadratic_trend(mesh: np.ndarray) -> np.ndarray:
    """Least-squares quadratic surface through the mesh (linear or constant if it is small)."""
    design, pinv = _quadratic_design(*mesh.shape)
    return (design @ (pinv @ mesh.ravel())).reshape(mesh.shape)


def median_filter_mesh(mesh: np.ndarray, size: int) -> np.ndarray:
    """Median filter over ``size`` x ``size`` boxes that leaves smooth trends alone.

    A median filter flattens the peak of a curved glow (by ~0.25 noise sigma at the centre of
    the ESA frames), so it is applied to the mesh minus its least-squares quadratic trend, which
    is then added back: a quadratic passes unchanged, a box spoilt by a bright star is still
    replaced by its neighbours. The residual is padded by point reflection ("odd"), which also
    continues a linear trend across the edges.

    Parameters
    ----------
    mesh : ndarray, shape (rows, columns)
        Box values (finite).
    size : int
        Filter width, boxes (1 or less: no filter).

    Returns
    -------
    ndarray, shape (rows, columns)
    """
    if size <= 1:
        return mesh
    trend = _quadratic_trend(mesh)
    resid = mesh - trend
    pad_y, pad_x = min(size // 2, mesh.shape[0] - 1), min(size // 2, mesh.shape[1] - 1)
    padded = np.pad(resid, ((pad_y, pad_y), (pad_x, pad_x)), mode="reflect", reflect_type="odd")
    filtered = ndimage.median_filter(padded, size=size, mode="nearest")
    return trend + filtered[pad_y : pad_y + mesh.shape[0], pad_x : pad_x + mesh.shape[1]]


def interpolate_mesh(wy: np.ndarray, mesh: np.ndarray, wx: np.ndarray) -> np.ndarray:
    """Return ``wy @ mesh @ wx.T`` as float32 (rows, columns), in row blocks of small products.

    The product is a bicubic (or bilinear) interpolation of a small mesh to every pixel.
    ``wy @ mesh`` (rows x mesh columns) is formed in float64; its product with ``wx.T``, the
    whole-frame one, in float32 (SGEMM, twice the speed of DGEMM, no float64 frame), in blocks
    of rows each small enough for a single-threaded GEMM. Each pixel is a sum of a few terms
    (4 bilinear, one per mesh column for the cubic spline), so it is exact to within a few
    float32 ulps of the mesh's largest term.

    Parameters
    ----------
    wy : AxisWeights or ndarray, shape (rows, mesh rows)
        Interpolation weights along the rows.
    mesh : ndarray, shape (mesh rows, mesh columns)
        Box values.
    wx : AxisWeights or ndarray, shape (columns, mesh columns)
        Interpolation weights along the columns.

    Returns
    -------
    ndarray of float32, shape (rows, columns)
    """
    # the mesh's mean is taken out and added back: a flat mesh (a constant frame) then gives
    # exactly its value, not one float32 rounding away from it (which would light every pixel
    # of a frame whose noise is zero), and the products round on the deviations only
    centre = float(np.mean(mesh))
    mat_y, mat_x = weight_matrix(wy), weight_matrix(wx)
    if mat_y is None or mat_x is None:
        return _interpolate_local(wy, mesh - centre, wx, centre)
    left = (mat_y @ (mesh - centre)).astype(np.float32)  # (rows, mesh columns): small
    right = np.ascontiguousarray(mat_x.T, dtype=np.float32)
    out = np.empty((mat_y.shape[0], mat_x.shape[0]), dtype=np.float32)
    matmul_single_thread(left, right, out)
    out += np.float32(centre)
    return out


def _interpolate_local(wy, deviations: np.ndarray, wx, centre: float) -> np.ndarray:
    """:func:`interpolate_mesh` when an axis's weights are in local form (a very long axis).

    Along the rows first (rows x mesh columns, float64), then along each block of rows, with
    temporaries of ~1 M numbers: memory and time grow with the pixels.
    """
    left = apply_weights(wy, deviations)
    rows, cols = left.shape[0], wx.shape[0]
    out = np.empty((rows, cols), dtype=np.float32)
    block = max(1, 2**20 // max(cols, 1))
    for r0 in range(0, rows, block):
        out[r0 : r0 + block] = apply_weights(wx, left[r0 : r0 + block].T).T
    out += np.float32(centre)
    return out


def _is_regular(index: np.ndarray, step: int) -> bool:
    """Whether the mesh samples of one axis are every ``step``-th pixel from 0, box by box."""
    return bool(np.array_equal(index.ravel(), step * np.arange(index.size)))


@functools.lru_cache(maxsize=16)
def _mesh_plan(n: int, box_px: int, step: int):
    """One axis's mesh samples, computed once per frame geometry.

    Returns ``(index, valid, centres)`` of :func:`_mesh_axis` (read-only arrays: a camera's
    frames all share them).
    """
    plan = _mesh_axis(n, box_px, step)
    for arr in plan:
        arr.flags.writeable = False
    return plan


@functools.lru_cache(maxsize=16)
def _axis_weights(n: int, box_px: int, step: int, interpolation: str) -> AxisWeights:
    """One axis's interpolation weights (:class:`AxisWeights`), once per frame geometry."""
    return AxisWeights(_mesh_plan(n, box_px, step)[2], n, interpolation)


class MeshSampler:
    """The mesh of one frame shape: its samples per box, validity and interpolation weights.

    Parameters
    ----------
    shape : (rows, columns)
    box_px : int
        Nominal box size, pixels.
    every : int
        Sample every ``every``-th pixel each way.
    interpolation : {"linear", "cubic"}
    """

    def __init__(self, shape: tuple[int, int], *, box_px: int, every: int, interpolation: str):
        rows, cols = shape
        self.ri, self.rvalid, self.rc = _mesh_plan(rows, box_px, every)
        self.ci, self.cvalid, self.cc = _mesh_plan(cols, box_px, every)
        self.every = every
        self._geometry = (rows, cols, box_px, every, interpolation)
        # equal boxes that tile the frame: the samples are a strided view, gathered by one copy
        self.regular = _is_regular(self.ri, every) and _is_regular(self.ci, every)

    @property
    def wy(self) -> AxisWeights:
        """Interpolation weights along the rows (built on first use)."""
        rows, _, box_px, every, kind = self._geometry
        return _axis_weights(rows, box_px, every, kind)

    @property
    def wx(self) -> AxisWeights:
        """Interpolation weights along the columns (built on first use)."""
        _, cols, box_px, every, kind = self._geometry
        return _axis_weights(cols, box_px, every, kind)

    @property
    def boxes(self) -> tuple[int, int]:
        """Mesh shape (box rows, box columns)."""
        return len(self.rc), len(self.cc)

    def valid(self) -> np.ndarray:
        """Which samples of each box lie inside it, shape (ny, nx, samples) (a new array)."""
        ny, nx = self.boxes
        return (self.rvalid[:, None, :, None] & self.cvalid[None, :, None, :]).reshape(ny, nx, -1)

    def gather(self, values: np.ndarray, dtype=None, name: str | None = None) -> np.ndarray:
        """(ny, nx, samples) array of ``values`` at the mesh samples (a work buffer if named)."""
        ny, nx = self.boxes
        ri, ci, every = self.ri, self.ci, self.every
        if not self.regular:
            g = values[ri[:, :, None, None], ci[None, None, :, :]]  # (ny, my, nx, mx)
            g = g.transpose(0, 2, 1, 3).reshape(ny, nx, -1)
            return g if dtype is None else g.astype(dtype)
        my, mx = ri.shape[1], ci.shape[1]
        view = values[: ny * my * every : every, : nx * mx * every : every]
        shape, dtype = (ny, nx, my * mx), values.dtype if dtype is None else dtype
        out = np.empty(shape, dtype) if name is None else scratch(name, shape, dtype)
        out.reshape(ny, nx, my, mx)[...] = view.reshape(ny, my, nx, mx).transpose(0, 2, 1, 3)
        return out
