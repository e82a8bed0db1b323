"""Interpolation weights of the background mesh along one axis, dense or compact.

The background mesh (:mod:`.mesh`) is interpolated to every pixel by a separable natural cubic
spline (or a linear interpolant) between the box centres. Along one axis the interpolant is a
matrix W (pixels, boxes): the pixel values are ``W @ v`` for the box values v. A natural
cubic spline's W is dense (every box value reaches every pixel through the spline's second
derivatives), so it holds n * m = n^2 / box_px numbers: 1.2 GB for an axis of 100,000 pixels
and 64-pixel boxes. :class:`AxisWeights` keeps that matrix only while it is small
(:data:`DENSE_LIMIT`), and otherwise the spline's local form: each pixel's segment, the four
coefficients of its value from the two knot values and the two knot second derivatives, and
the tridiagonal system that gives the second derivatives from the values (solved per call, in
O(boxes) per column of values). Memory and time then grow with the pixels, not their square.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded

__all__ = [
    "DENSE_LIMIT",
    "AxisWeights",
    "apply_weights",
    "interpolation_matrix",
    "natural_spline_weights",
    "weight_matrix",
]

#: largest pixels x boxes of one axis kept as a dense matrix (16 MB of float64; the dense
#: build's temporaries are ~5 such matrices). Every frame up to 8,192 pixels wide with the
#: default 64-pixel boxes (1.0 M numbers) stays dense, as before.
DENSE_LIMIT = 2**21


def interpolation_matrix(centres: np.ndarray, n: int, kind: str) -> np.ndarray:
    """W (n, m) with values at pixels 0..n-1 = W @ values at the m box centres (one axis).

    Linear (or natural cubic) between the centres, linear extrapolation beyond them; both
    reproduce a linear function exactly.
    """
    m = centres.size
    if m == 1:
        return np.ones((n, 1))
    pix = np.arange(n, dtype=np.float64)
    seg = np.clip(np.searchsorted(centres, pix, side="right") - 1, 0, m - 2)
    t = (pix - centres[seg]) / (centres[seg + 1] - centres[seg])
    w = np.zeros((n, m))
    w[np.arange(n), seg] = 1.0 - t
    w[np.arange(n), seg + 1] += t
    if kind == "cubic" and m >= 3:
        inside = (pix >= centres[0]) & (pix <= centres[-1])
        w[inside] = natural_spline_weights(centres, pix[inside])
    return w


def natural_spline_weights(knots: np.ndarray, x: np.ndarray) -> np.ndarray:
    """W (n, m): the natural cubic spline through values v at ``knots``, at ``x``, is ``W @ v``.

    The spline of ``scipy.interpolate.CubicSpline(knots, v, bc_type="natural")`` (zero second
    derivative at both ends), written out in NumPy: its second derivatives at the knots solve
    the (m - 2)-square tridiagonal system of continuity of the first derivative, here for every
    unit vector v at once (scipy.interpolate costs ~0.1 s to import, more than a frame's solve).

    Parameters
    ----------
    knots : ndarray, shape (m,)
        Strictly ascending, m >= 3.
    x : ndarray, shape (n,)
        Where to evaluate, within ``[knots[0], knots[-1]]``.

    Returns
    -------
    ndarray, shape (n, m)
    """
    m = knots.size
    h = np.diff(knots)
    a = np.zeros((m - 2, m - 2))
    i = np.arange(m - 2)
    a[i, i] = 2.0 * (h[:-1] + h[1:])
    a[i[1:], i[:-1]] = h[1:-1]
    a[i[:-1], i[1:]] = h[1:-1]
    b = np.zeros((m - 2, m))  # 6 x the change of slope at each inner knot, per unit value
    b[i, i] = 6.0 / h[:-1]
    b[i, i + 1] = -6.0 / h[:-1] - 6.0 / h[1:]
    b[i, i + 2] = 6.0 / h[1:]
    second = np.zeros((m, m))  # second derivatives at the knots, zero at the ends (natural)
    second[1:-1] = np.linalg.solve(a, b)
    seg = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, m - 2)
    hs = h[seg]
    t1 = x - knots[seg]  # from the segment's left knot
    t0 = knots[seg + 1] - x  # to its right knot
    rows = np.arange(x.size)
    w = np.zeros((x.size, m))
    w[rows, seg] = t0 / hs
    w[rows, seg + 1] += t1 / hs
    c0 = ((t0**3 / hs - hs * t0) / 6.0)[:, None]
    c1 = ((t1**3 / hs - hs * t1) / 6.0)[:, None]
    return w + c0 * second[seg] + c1 * second[seg + 1]


class AxisWeights:
    """One axis's interpolation weights W (n, m): ``W @ v`` without forming W when it is big.

    Parameters
    ----------
    centres : ndarray, shape (m,)
        Box centres, pixels, strictly ascending.
    n : int
        Pixels along the axis.
    kind : {"linear", "cubic"}
    dense_limit : int, optional
        Largest n * m kept as the dense matrix (:func:`interpolation_matrix`, the same numbers
        as before; default :data:`DENSE_LIMIT`); above it the local form is used (equal to
        within ~1e-15 of the values).
    """

    def __init__(self, centres: np.ndarray, n: int, kind: str, *, dense_limit: int | None = None):
        centres = np.asarray(centres, dtype=np.float64)
        dense_limit = DENSE_LIMIT if dense_limit is None else dense_limit
        self.shape = (int(n), centres.size)
        self.matrix = None
        if n * centres.size <= dense_limit:
            self.matrix = interpolation_matrix(centres, n, kind)
            self.matrix.flags.writeable = False
            return
        m = centres.size
        self._cubic = kind == "cubic" and m >= 3
        pix = np.arange(n, dtype=np.float64)
        if m == 1:
            self.seg, self.coef = np.zeros(n, np.intp), np.zeros((n, 4))
            self.coef[:, 0] = 1.0
            return
        seg = np.clip(np.searchsorted(centres, pix, side="right") - 1, 0, m - 2)
        h = np.diff(centres)
        t = (pix - centres[seg]) / h[seg]
        coef = np.zeros((n, 4))  # x v[seg], v[seg + 1], second[seg], second[seg + 1]
        coef[:, 0], coef[:, 1] = 1.0 - t, t
        if self._cubic:
            inside = (pix >= centres[0]) & (pix <= centres[-1])
            hs = h[seg[inside]]
            t1 = pix[inside] - centres[seg[inside]]
            t0 = centres[seg[inside] + 1] - pix[inside]
            coef[inside, 0], coef[inside, 1] = t0 / hs, t1 / hs
            coef[inside, 2] = (t0**3 / hs - hs * t0) / 6.0
            coef[inside, 3] = (t1**3 / hs - hs * t1) / 6.0
            self._h = h
        self.seg, self.coef = seg, coef

    @property
    def dense(self) -> bool:
        """Whether W is held as a matrix."""
        return self.matrix is not None

    def _second(self, v: np.ndarray) -> np.ndarray:
        """Second derivatives (m, k) at the knots of the natural splines through ``v`` (m, k).

        The tridiagonal system of :func:`natural_spline_weights`, solved in O(m k) by LAPACK's
        tridiagonal solver (``scipy.linalg``, already loaded by ``scipy.ndimage``).
        """
        h = self._h
        rhs = 6.0 * (np.diff(v[1:], axis=0) / h[1:, None] - np.diff(v[:-1], axis=0) / h[:-1, None])
        bands = np.zeros((3, h.size - 1))
        bands[0, 1:] = bands[2, :-1] = h[1:-1]
        bands[1] = 2.0 * (h[:-1] + h[1:])
        second = np.zeros((h.size + 1, *v.shape[1:]))
        second[1:-1] = solve_banded((1, 1), bands, rhs, check_finite=False)
        return second

    def apply(self, v: np.ndarray, pixels: np.ndarray | None = None) -> np.ndarray:
        """Return ``W @ v`` (n, k) for box values ``v`` (m, k), or its rows ``pixels`` only."""
        v = np.asarray(v, dtype=np.float64)
        if self.matrix is not None:
            return (self.matrix if pixels is None else self.matrix[pixels]) @ v
        seg, coef = self.seg, self.coef
        if pixels is not None:
            seg, coef = seg[pixels], coef[pixels]
        m = self.shape[1]
        if m == 1:
            return np.broadcast_to(v[0], (seg.size, *v.shape[1:])) * coef[:, :1]
        out = coef[:, 0:1] * v[seg] + coef[:, 1:2] * v[seg + 1]
        if self._cubic:
            second = self._second(v)
            out += coef[:, 2:3] * second[seg] + coef[:, 3:4] * second[seg + 1]
        return out

    def pairs(self, v: np.ndarray, pixels: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """Return ``(W @ v)[pixels[i], columns[i]]`` for every i (v of shape (m, k))."""
        if self.matrix is not None:
            return np.einsum("ij,ji->i", self.matrix[pixels], v[:, columns])
        uniq, inverse = np.unique(columns, return_inverse=True)
        sub = np.asarray(v[:, uniq], dtype=np.float64)
        seg, coef = self.seg[pixels], self.coef[pixels]
        if self.shape[1] == 1:
            return coef[:, 0] * sub[0, inverse]
        out = coef[:, 0] * sub[seg, inverse] + coef[:, 1] * sub[seg + 1, inverse]
        if self._cubic:
            second = self._second(sub)
            out += coef[:, 2] * second[seg, inverse] + coef[:, 3] * second[seg + 1, inverse]
        return out


def weight_matrix(w) -> np.ndarray | None:
    """Return the dense matrix of weights ``w`` (an ndarray or :class:`AxisWeights`), or None."""
    return w.matrix if isinstance(w, AxisWeights) else np.asarray(w)


def apply_weights(w, v: np.ndarray) -> np.ndarray:
    """``W @ v`` for weights ``w`` (an ndarray or :class:`AxisWeights`) and box values ``v``."""
    return w.apply(v) if isinstance(w, AxisWeights) else np.asarray(w) @ v
