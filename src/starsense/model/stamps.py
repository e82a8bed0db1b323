"""One source's light on the pixels of its box, and its derivatives: the model's stamps.

A star's template is the pixel-integrated PSF (:mod:`starsense.model.psf`) summed over its
time nodes (:mod:`starsense.model.tracks`) with their quadrature weights, on the rows and
columns of its box; its derivatives with respect to the geometric parameters follow the
nodes' (``-dP/ddx dx_k/dp - dP/ddy dy_k/dp``). Each node lights the pixels within the reach
``half_px`` of it, the padding of a star's box at rest (a streak's box is mostly pixels far
from any one node). A Gaussian is separable: each node's stamp is the outer product of its
pixel fractions along the rows and the columns of its reach, summed over the nodes as matrix
products where its box is a few dozen stamps at most; a longer track's stamps, and another
profile's, are added into the box node by node.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.psf import PixelPSF, gaussian_pixel_1d
from starsense.model.tracks import NodePositions

__all__ = ["SEPARABLE_BOX_STAMPS", "STAMP_CHUNK", "source_stamps", "stamp_side"]

#: most stamp pixels (sources x time nodes x stamp area) drawn at once: ~10 arrays of 16 MB
STAMP_CHUNK = 2_000_000
#: a Gaussian's track is summed as matrix products over its box while the box holds at most
#: this many node stamps; past it node by node: a box pixel costs each node 3-8 ns in the
#: products, a node's stamp pixel 130-230 ns drawn and added (measured over PSF sigmas of
#: 0.5-2.5 px and streaks of 2-266 px), and the two cost the same at 20-50 stamps a box. A long
#: streak's box is mostly pixels far from every node (a 266 px streak of a 0.5 px PSF: 960
#: stamps a box, 33 times faster node by node); the light drawn is the same to round-off
SEPARABLE_BOX_STAMPS = 40


def _gaussian_width_1d(d, sigma):
    """Return d/dsigma of a 1-D Gaussian's pixel fractions at offsets ``d``.

    ``-(a phi(a) - b phi(b)) / sigma`` with ``a, b = (d +- 1/2) / sigma``.
    """
    a, b = (d + 0.5) / sigma, (d - 0.5) / sigma
    return -(a * np.exp(-0.5 * a * a) - b * np.exp(-0.5 * b * b)) * _INV_SQRT2PI / sigma


_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)


def _static_gaussian(sigma, nodes: NodePositions, idx, rows, cols, gradient, width):
    """:func:`source_stamps` of Gaussian stars at rest (one time node)."""
    px, dpx = gaussian_pixel_1d(cols - nodes.x[idx, :1], sigma)  # (S, w)
    py, dpy = gaussian_pixel_1d(rows - nodes.y[idx, :1], sigma)  # (S, h)
    t = py[:, :, None] * px[:, None, :]
    if not gradient:
        return t, None
    ax, ay = nodes.dx[idx, 0], nodes.dy[idx, 0]  # (S, P)
    gx = py[:, :, None] * dpx[:, None, :]  # d t / d(dx)
    gy = dpy[:, :, None] * px[:, None, :]
    d = -(ax[:, :, None, None] * gx[:, None] + ay[:, :, None, None] * gy[:, None])
    if width:
        dw = _gaussian_width_1d(rows - nodes.y[idx, :1], sigma)[:, :, None] * px[:, None, :]
        dw += py[:, :, None] * _gaussian_width_1d(cols - nodes.x[idx, :1], sigma)[:, None, :]
        d = np.concatenate([d, dw[:, None]], axis=1)
    return t, d


def stamp_side(half_px: float) -> int:
    """Return the side of a time node's stamp: every pixel centre within ``half_px`` of it."""
    return math.floor(2.0 * half_px) + 2


def source_stamps(
    psf: PixelPSF,
    nodes: NodePositions,
    idx,
    *,
    rows,
    cols,
    half_px,
    origin=None,
    gradient=True,
    width=False,
):
    """Return templates (S, h, w) of sources ``idx`` and their derivatives (S, P, h, w).

    Over consecutive pixel rows (S, h) and columns (S, w) of the detector (each source's box).
    With ``width`` (a Gaussian), the derivative with respect to the PSF's sigma is appended (P +
    1 columns). Each time node lights the pixels of a stamp of :func:`stamp_side` pixels a side
    around it (the reach ``half_px`` of a star's box at rest), whose first row and column are
    ``origin`` (S, K, 2) (default: where the nodes are now).
    """
    wk = nodes.weights
    xk, yk = nodes.x[idx], nodes.y[idx]  # (S, K)
    if psf.spec.is_gaussian and len(wk) == 1:  # at rest: outer products, no sums over time
        return _static_gaussian(psf.sigma_px, nodes, idx, rows, cols, gradient, width)
    if origin is None:
        origin = np.stack([np.floor(yk - half_px + 0.5), np.floor(xk - half_px + 0.5)], -1)
    track = len(wk) > 1
    if track:  # a box cut from a long track (a group's, the detector's edge) meets few nodes
        nodes, origin = _meeting(nodes, origin, rows, cols, stamp_side(half_px))
    box = rows.shape[1] * cols.shape[1]
    if psf.spec.is_gaussian and box <= SEPARABLE_BOX_STAMPS * stamp_side(half_px) ** 2:
        # separable: each node's reach a band of rows times one of columns
        return _separable_track(psf.sigma_px, nodes, idx, (rows, cols, origin), half_px, gradient,
                                width)  # fmt: skip
    if track:  # node by node
        # in chunks of sources whose stamps hold at most STAMP_CHUNK pixels (bounded memory)
        step = max(1, STAMP_CHUNK // (len(nodes.weights) * stamp_side(half_px) ** 2))
        parts = [
            _node_stamps(
                psf, nodes, idx[a : a + step], (rows[a : a + step], cols[a : a + step],
                origin[a : a + step]), half_px, gradient, width,
            )
            for a in range(0, len(idx), step)
        ]  # fmt: skip
        t = np.concatenate([p[0] for p in parts])
        return t, (np.concatenate([p[1] for p in parts]) if gradient else None)
    # each box a grid of whole pixels: its first column's and row's offsets from each node
    shape = (rows.shape[1], cols.shape[1])
    x0 = cols[:, :1] - xk  # (S, K)
    y0 = rows[:, :1] - yk
    if not gradient:
        v = psf.grid(x0, y0, shape, gradient=False).reshape(*xk.shape, *shape)
        return np.einsum("k,skrc->src", wk, v), None
    v, gx, gy = (a.reshape(*xk.shape, *shape) for a in psf.grid(x0, y0, shape))
    t = np.einsum("k,skrc->src", wk, v)
    d = -(
        np.einsum("skrc,skp->sprc", gx, wk[None, :, None] * nodes.dx[idx])
        + np.einsum("skrc,skp->sprc", gy, wk[None, :, None] * nodes.dy[idx])
    )
    return t, d


def _meeting(nodes: NodePositions, origin, rows, cols, n: int):
    """Return ``nodes`` and ``origin`` (S, K, 2) cut to the nodes whose stamp meets a box.

    A node whose stamp of ``n`` px a side lies off every box (rows (S, h), columns (S, w))
    adds nothing to it; at least one node is kept (its light then falls off the box too).
    """
    oy, ox = origin[..., 0], origin[..., 1]  # (S, K)
    meets = (oy <= rows[:, -1:]) & (oy + n > rows[:, :1])
    meets &= (ox <= cols[:, -1:]) & (ox + n > cols[:, :1])
    need = meets.any(axis=0)
    if need.all():
        return nodes, origin
    need[int(np.argmax(need))] = True
    k = np.flatnonzero(need)
    cut = NodePositions(
        nodes.x[:, k], nodes.y[:, k], nodes.weights[k], nodes.dx[:, k], nodes.dy[:, k]
    )
    return cut, origin[:, k]


def _separable_track(sigma, nodes: NodePositions, idx, grid, half_px, gradient, width):
    """:func:`source_stamps` of a Gaussian's track, summed over its nodes as matrix products.

    Per node, its pixel fractions along the rows and along the columns of its reach (zero
    outside): their outer product is the node's stamp.
    """
    rows, cols, origin = grid
    wk, n = nodes.weights, stamp_side(half_px)
    xk, yk = nodes.x[idx], nodes.y[idx]  # (S, K)
    dyp, dxp = rows[:, None, :] - yk[:, :, None], cols[:, None, :] - xk[:, :, None]
    oy, ox = origin[..., 0, None], origin[..., 1, None]  # (S, K, 1)
    my = (rows[:, None, :] >= oy) & (rows[:, None, :] < oy + n)  # (S, K, h)
    mx = (cols[:, None, :] >= ox) & (cols[:, None, :] < ox + n)  # (S, K, w)
    py, dpy = (a * my for a in gaussian_pixel_1d(dyp, sigma))
    px, dpx = (a * mx for a in gaussian_pixel_1d(dxp, sigma))
    # (S, h, K), laid out as such: a product of swapped axes is no BLAS operand (40 times slower)
    pyt = np.ascontiguousarray(np.swapaxes(py, 1, 2))
    t = np.matmul(pyt * wk, px)
    if not gradient:
        return t, None
    ax = wk[None, :, None] * nodes.dx[idx]  # (S, K, P)
    ay = wk[None, :, None] * nodes.dy[idx]
    dpyt = np.ascontiguousarray(np.swapaxes(dpy, 1, 2))
    d = [
        -(np.matmul(pyt * ax[:, None, :, p], dpx) + np.matmul(dpyt * ay[:, None, :, p], px))
        for p in range(ax.shape[-1])
    ]
    if width:
        sx, sy = _gaussian_width_1d(dxp, sigma) * mx, _gaussian_width_1d(dyp, sigma) * my
        syt = np.ascontiguousarray(np.swapaxes(sy, 1, 2))
        d.append(np.matmul(syt * wk, px) + np.matmul(pyt * wk, sx))
    return t, np.stack(d, axis=1)


def _node_stamps(psf: PixelPSF, nodes: NodePositions, idx, grid, half_px, gradient, width):
    """:func:`source_stamps` drawn node by node: each node's stamp added into its source's box.

    ``grid``: the boxes' rows (S, h) and columns (S, w), and the stamps' origins (S, K, 2).
    """
    rows, cols, origin = grid
    wk = nodes.weights
    xk, yk = nodes.x[idx], nodes.y[idx]  # (S, K)
    n_src, (h, w), n = len(xk), (rows.shape[1], cols.shape[1]), stamp_side(half_px)
    origin = np.asarray(origin).astype(np.int64)
    r = origin[:, :, 0, None] + np.arange(n)  # (S, K, n)
    c = origin[:, :, 1, None] + np.arange(n)
    dy, dx = r - yk[:, :, None], c - xk[:, :, None]
    if psf.spec.is_gaussian:
        px, dpx = gaussian_pixel_1d(dx, psf.sigma_px)
        py, dpy = gaussian_pixel_1d(dy, psf.sigma_px)
        v = py[..., :, None] * px[..., None, :]  # (S, K, n, n)
        gx, gy = py[..., :, None] * dpx[..., None, :], dpy[..., :, None] * px[..., None, :]
    elif gradient:  # each node's stamp a grid of whole pixels from its first row and column
        v, gx, gy = (a.reshape(*dx.shape, n) for a in psf.grid(dx[..., 0], dy[..., 0], (n, n)))
    else:
        v = psf.grid(dx[..., 0], dy[..., 0], (n, n), gradient=False).reshape(*dx.shape, n)
    lr, lc = r - rows[:, :1, None], c - cols[:, :1, None]  # in the source's box
    inside = ((lr >= 0) & (lr < h))[..., :, None] & ((lc >= 0) & (lc < w))[..., None, :]
    at = ((np.arange(n_src)[:, None, None] * h + lr)[..., :, None] * w + lc[..., None, :])[inside]
    t = np.bincount(at, (wk[None, :, None, None] * v)[inside], n_src * h * w)
    t = t.reshape(n_src, h, w)
    if not gradient:
        return t, None
    ax = wk[None, :, None] * nodes.dx[idx]  # (S, K, P)
    ay = wk[None, :, None] * nodes.dy[idx]
    parts = [
        -(gx * ax[:, :, p, None, None] + gy * ay[:, :, p, None, None]) for p in range(ax.shape[-1])
    ]
    if width and psf.spec.is_gaussian:
        sx, sy = _gaussian_width_1d(dx, psf.sigma_px), _gaussian_width_1d(dy, psf.sigma_px)
        dw = sy[..., :, None] * px[..., None, :] + py[..., :, None] * sx[..., None, :]
        parts.append(wk[None, :, None, None] * dw)
    d = np.stack(
        [np.bincount(at, q[inside], n_src * h * w).reshape(n_src, h, w) for q in parts], axis=1
    )
    return t, d
