"""A background noise map that is evaluated only where it is needed.

The noise of a real frame varies smoothly across it (sky glow adds shot noise): it is a small
mesh of box values interpolated to every pixel (:mod:`.background`). The detector compares
pixels with a multiple of it, but only pixels already above that multiple of the *lowest* noise
of the frame can pass: a few thousand of a million. :class:`NoiseSurface` keeps the mesh
half-interpolated (``wy @ mesh``, one row per frame row) and evaluates the noise at given
pixels, on a subsampled grid, or over the whole frame, with the same interpolant and the same
clamp to the mesh's range as the whole-frame map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense.detect.axis_weights import AxisWeights

__all__ = ["NoiseSurface", "matmul_single_thread"]

# Largest m * n * k of one matrix product: OpenBLAS runs a GEMM single-threaded up to 65536 x 4
# (its GEMM_MULTITHREAD_THRESHOLD); a threaded GEMM on a busy machine waits for its second
# thread (~15 ms median instead of ~1 ms for a 768 x 1024 frame), and its threads then spin.
_GEMM_SINGLE_THREAD = 65536 * 4
#: numbers gathered at once by NoiseSurface.at (8 MB of float64 per operand)
_AT_BLOCK_NUMBERS = 1 << 20


def matmul_single_thread(left: np.ndarray, right: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out[...] = left @ right`` in blocks of rows, each small enough for a one-thread GEMM.

    Parameters
    ----------
    left : ndarray, shape (m, k)
    right : ndarray, shape (k, n), C-contiguous
    out : ndarray, shape (m, n), of the operands' dtype

    Returns
    -------
    ndarray
        ``out``.
    """
    block = max(1, _GEMM_SINGLE_THREAD // max(1, right.size))
    for r0 in range(0, out.shape[0], block):
        np.matmul(left[r0 : r0 + block], right, out=out[r0 : r0 + block])
    return out


@dataclass(frozen=True, eq=False)
class NoiseSurface:
    """Noise interpolated from a mesh: ``clip(centre + rows_w[r] . cols_w[c], low, high)``.

    Attributes
    ----------
    rows_w : ndarray, shape (rows, mesh_columns), float64
        ``wy @ (mesh - centre)``: the mesh interpolated along the rows.
    cols_w : ndarray, shape (columns, mesh_columns), float64, or AxisWeights
        The column interpolation weights ``wx`` (an :class:`AxisWeights` in local form for
        a very long axis).
    centre : float
        The mesh's mean, counts rms.
    low, high : float
        The mesh's range, counts rms (the interpolant's overshoot is clamped to it).
    """

    rows_w: np.ndarray
    cols_w: np.ndarray | AxisWeights
    centre: float
    low: float
    high: float

    @classmethod
    def from_mesh(cls, wy, mesh: np.ndarray, wx) -> NoiseSurface:
        """Return the surface of ``mesh`` (ny, nx) for the weights ``wy`` (rows, ny), ``wx``.

        The weights are ndarrays or :class:`AxisWeights`; dense ones are kept as matrices.
        """
        centre = float(np.mean(mesh))
        rows_w = wy.apply(mesh - centre) if isinstance(wy, AxisWeights) else wy @ (mesh - centre)
        if isinstance(wx, AxisWeights) and wx.dense:
            wx = wx.matrix
        return cls(rows_w, wx, centre, float(mesh.min()), float(mesh.max()))

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape (rows, columns)."""
        return self.rows_w.shape[0], self.cols_w.shape[0]

    def _clamp(self, values: np.ndarray) -> np.ndarray:
        out = np.asarray(values + self.centre, dtype=np.float32)
        np.maximum(out, np.float32(self.low), out=out)
        np.minimum(out, np.float32(self.high), out=out)
        return out

    def at(self, flat_idx: np.ndarray) -> np.ndarray:
        """Noise at the pixels of flat indices ``flat_idx``, counts rms (float32)."""
        r, c = np.divmod(np.asarray(flat_idx, dtype=np.intp).ravel(), self.shape[1])
        if isinstance(self.cols_w, AxisWeights):
            return self._clamp(self.cols_w.pairs(self.rows_w.T, c, r))
        # in blocks: a gather of (pixels, mesh columns) for every pixel of a bright frame at
        # once would take pixels x columns x 16 bytes (GBs); each pixel's sum is the same
        out = np.empty(r.size)
        block = max(1, _AT_BLOCK_NUMBERS // max(1, self.rows_w.shape[1]))
        for i in range(0, r.size, block):
            rr, cc = r[i : i + block], c[i : i + block]
            out[i : i + block] = np.einsum("ij,ij->i", self.rows_w[rr], self.cols_w[cc])
        return self._clamp(out)

    def grid(self, step: int) -> np.ndarray:
        """Noise at every ``step``-th pixel each way (``map[::step, ::step]``), float32."""
        if isinstance(self.cols_w, AxisWeights):
            cols = np.arange(0, self.shape[1], step)
            return self._clamp(self.cols_w.apply(self.rows_w[::step].T, cols).T)
        left, right = self.rows_w[::step], np.ascontiguousarray(self.cols_w[::step].T)
        return self._clamp(
            matmul_single_thread(left, right, np.empty((left.shape[0], right.shape[1])))
        )

    def floor(self) -> np.float32:
        """Return the lowest noise anywhere in the frame, counts rms."""
        return np.float32(self.low)
