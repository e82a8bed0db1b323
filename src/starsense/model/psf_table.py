"""A tabulated pixel-integrated PSF and its cubic B-spline: values and gradients, fast on grids.

The table holds the pixel integral of a profile on nodes ``1 / TABLE_OVERSAMPLING`` px apart
(:mod:`.psf`). Between them a cubic B-spline interpolates it (Unser 1999, "Splines: a perfect fit
for signal and image processing": coefficients by the recursive prefilter, here
:func:`scipy.ndimage.spline_filter`; its error is fourth order in the node spacing, as any cubic
spline's). The table's edge is tapered to zero and padded with zero nodes, so the spline falls
to zero with its first two derivatives at the edge.

Every caller asks for the PSF on a grid of whole pixels around a star or a time node: offsets
``x0 + j`` along the columns and ``y0 + i`` along the rows. A pixel is a whole number of nodes,
so every pixel of such a grid sits at the same phase between nodes: the spline's four weights
per axis are computed once per grid (:meth:`SplineTable.grid`; a compiled kernel where the
package was built with one, the NumPy form otherwise, equal to within rounding).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

try:
    import starsense.model._modelc as _modelc
except ImportError:  # no C compiler when the package was installed: the NumPy form
    _modelc = None

__all__ = ["SplineTable"]

#: zero nodes around the table (the spline's support reaches two nodes past its last one)
PAD = 4
#: numbers gathered at once by the NumPy form (16 per pixel; 64 MB of float64)
_GATHER_NUMBERS = 1 << 23


def _weights(t: np.ndarray):
    """Return the cubic B-spline's four weights at phase ``t`` in [0, 1), and their d/dt."""
    s = 1.0 - t
    t2, t3 = t * t, t * t * t
    w = np.stack([s * s * s, 4.0 - 6.0 * t2 + 3.0 * t3, 1.0 + 3.0 * (t + t2 - t3), t3], -1) / 6.0
    dw = np.stack([-0.5 * s * s, -2.0 * t + 1.5 * t2, 0.5 + t - 1.5 * t2, 0.5 * t2], -1)
    return w, dw


class SplineTable:
    """A table of pixel fractions on nodes ``-radius .. radius`` px, ``per_px`` nodes a pixel.

    Parameters
    ----------
    box : ndarray, shape (n, n)
        The pixel fractions at the nodes (rows: y, columns: x), zero at the edge.
    radius : float
        The offset of the last node, px; beyond it (either axis) the PSF is zero.
    per_px : int
        Nodes per pixel.
    """

    def __init__(self, box: np.ndarray, radius: float, per_px: int) -> None:
        padded = np.pad(np.asarray(box, dtype=np.float64), PAD)
        self.coef = np.ascontiguousarray(ndimage.spline_filter(padded, order=3, mode="mirror"))
        self.radius = float(radius)
        self.per_px = int(per_px)

    def _phase(self, d: np.ndarray):
        """Node index of the spline's first weight, phase and inside mask of offsets ``d``."""
        inside = np.abs(d) < self.radius
        u = np.where(inside, (d + self.radius) * self.per_px + PAD, PAD)  # outside: any node
        i = np.floor(u)
        return i.astype(np.intp) - 1, u - i, inside

    def points(self, dx: np.ndarray, dy: np.ndarray, *, gradient: bool):
        """Values (and d/ddx, d/ddy) at offsets ``dx``, ``dy`` of one shape."""
        flat_x, flat_y = dx.ravel(), dy.ravel()
        outs = [np.zeros(flat_x.size) for _ in range(3 if gradient else 1)]
        step = _GATHER_NUMBERS // 16
        for a in range(0, flat_x.size, step):
            parts = self._points(flat_x[a : a + step], flat_y[a : a + step], gradient)
            for out, part in zip(outs, parts, strict=True):
                out[a : a + step] = part
        outs = [o.reshape(dx.shape) for o in outs]
        return tuple(outs) if gradient else outs[0]

    def _points(self, dx, dy, gradient):
        ix, tx, in_x = self._phase(dx)
        iy, ty, in_y = self._phase(dy)
        wx, dwx = _weights(tx)
        wy, dwy = _weights(ty)
        k = np.arange(4)
        g = self.coef[(iy[:, None] + k)[:, :, None], (ix[:, None] + k)[:, None, :]]  # (N,4,4)
        inside = in_x & in_y
        hx = np.einsum("npq,nq->np", g, wx)
        v = np.where(inside, np.maximum(np.einsum("np,np->n", hx, wy), 0.0), 0.0)
        if not gradient:
            return (v,)
        gx = np.where(inside, np.einsum("npq,nq,np->n", g, dwx, wy), 0.0) * self.per_px
        gy = np.where(inside, np.einsum("np,np->n", hx, dwy), 0.0) * self.per_px
        return v, gx, gy

    def grid(self, x0, y0, shape: tuple[int, int], *, gradient: bool):
        """Return :meth:`starsense.model.psf.PixelPSF.grid` of this table (its form and shapes)."""
        x0 = np.ascontiguousarray(x0, dtype=np.float64).ravel()
        y0 = np.ascontiguousarray(y0, dtype=np.float64).ravel()
        ny, nx = int(shape[0]), int(shape[1])
        outs = [np.zeros((x0.size, ny, nx)) for _ in range(3 if gradient else 1)]
        if x0.size and ny and nx:
            if _modelc is not None:
                gx_, gy_ = (outs[1], outs[2]) if gradient else (outs[0], outs[0])
                _modelc.table_grid(
                    self.coef, self.coef.shape[0], self.radius, self.per_px, PAD, x0, y0,
                    x0.size, ny, nx, int(gradient), outs[0], gx_, gy_,
                )  # fmt: skip
            else:
                self._grid_numpy(x0, y0, outs, gradient)
        return tuple(outs) if gradient else outs[0]

    def _grid_numpy(self, x0, y0, outs, gradient) -> None:
        """Fill ``outs`` as :meth:`grid` does, in NumPy (the compiled kernel's reference)."""
        ny, nx = outs[0].shape[1:]
        k = np.arange(4)
        step = max(1, _GATHER_NUMBERS // (16 * ny * nx))
        last = self.coef.shape[0] - 4
        for a in range(0, x0.size, step):
            sl = slice(a, a + step)
            in_x = np.abs(x0[sl, None] + np.arange(nx)) < self.radius  # (n, nx)
            in_y = np.abs(y0[sl, None] + np.arange(ny)) < self.radius
            # one phase per grid (a pixel is whole nodes), its first column's and row's: node
            # index and weights agree for every pixel whatever the rounding of x0 + j
            ux = (x0[sl] + self.radius) * self.per_px + PAD
            uy = (y0[sl] + self.radius) * self.per_px + PAD
            # a grid at a position not a number, or far beyond any index, lies outside (masked
            # below): its phase is not cast
            ux, uy = (np.where(np.abs(u) < 1e12, u, 0.0) for u in (ux, uy))
            wx, dwx = _weights(ux - np.floor(ux))
            wy, dwy = _weights(uy - np.floor(uy))
            ix = np.floor(ux).astype(np.intp)[:, None] - 1 + self.per_px * np.arange(nx)
            iy = np.floor(uy).astype(np.intp)[:, None] - 1 + self.per_px * np.arange(ny)
            ix, iy = np.clip(ix, 0, last), np.clip(iy, 0, last)  # outside: masked below
            g = self.coef[
                (iy[:, :, None] + k)[:, :, :, None, None], (ix[:, :, None] + k)[:, None, None, :, :]
            ]  # (n, ny, 4, nx, 4)
            inside = in_y[:, :, None] & in_x[:, None, :]
            hx = np.einsum("napbq,nq->napb", g, wx)
            v = np.einsum("napb,np->nab", hx, wy)
            outs[0][sl] = np.where(inside, np.maximum(v, 0.0), 0.0)
            if gradient:
                gx = np.einsum("napbq,nq,np->nab", g, dwx, wy) * self.per_px
                gy = np.einsum("napb,np->nab", hx, dwy) * self.per_px
                outs[1][sl] = np.where(inside, gx, 0.0)
                outs[2][sl] = np.where(inside, gy, 0.0)
